"""Paired datasets: sequence files of input and ground-truth streams, cut into voxel windows."""
