"""Event-to-image reconstruction: a small recurrent network trained on the simulator.

Used to measure what de-flaring does downstream (the paper's E2VID-style
check): reconstruct from the input, from each method's output and from the
ground truth, and score the images against the simulator's flare-free
frames (:mod:`edeflare.eval.downstream`).

- :mod:`~edeflare.recon.network`: :class:`FireNet` (about 38 k parameters);
- :mod:`~edeflare.recon.clips`: simulated training clips with exact frames;
- :mod:`~edeflare.recon.train`: resumable CPU training;
- :mod:`~edeflare.recon.weights`: safetensors with a card; the bundled weights;
- :mod:`~edeflare.recon.infer`: :class:`Reconstructor` and ``edeflare reconstruct``.
"""
