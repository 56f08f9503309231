"""Sequence files: the layout's one owner writes, reads and checks them."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from edeflare.errors import EventFileError, ParameterError
from edeflare.events import make_events
from edeflare.io.sequence import (
    check_paired,
    file_sha256,
    list_sequences,
    read_sequence,
    sequence_counts,
    sequence_span,
    write_sequence,
)

EV = make_events([10, 20, 30_000], [0, 1, 1], [0, 0, 1], [1, 0, 1])


def test_round_trip_span_counts_and_digest(tmp_path):
    path = tmp_path / "s.h5"
    write_sequence(
        path, {"input": EV, "gt": EV[:1]}, (2, 2), {"t_start_us": 0, "t_end_us": 40_000, "seed": 7}
    )
    inp, gt, size, start, end = read_sequence(path)
    assert np.array_equal(inp, EV) and np.array_equal(gt, EV[:1])
    assert (size, start, end) == ((2, 2), 0, 40_000)
    assert sequence_span(path) == ((2, 2), 0, 40_000)
    counts, attrs = sequence_counts(path)
    assert counts == {"input": 3, "gt": 1} and int(attrs["seed"]) == 7
    with h5py.File(path) as f:
        assert f.attrs["t_start_us"].dtype == np.int64
    assert len(file_sha256(path)) == 64
    assert list_sequences(tmp_path) == [path]


def test_layout_errors_name_what_is_wrong(tmp_path):
    with pytest.raises(ParameterError, match="'input' group"):
        write_sequence(tmp_path / "a.h5", {"gt": EV}, (2, 2), {"t_start_us": 0, "t_end_us": 1})
    with pytest.raises(ParameterError, match="t_start_us, t_end_us"):
        write_sequence(tmp_path / "a.h5", {"input": EV}, (2, 2), {})
    with pytest.raises(ParameterError, match="t_end_us > t_start_us"):
        write_sequence(tmp_path / "a.h5", {"input": EV}, (2, 2), {"t_start_us": 5, "t_end_us": 5})
    assert not list(tmp_path.iterdir())
    write_sequence(
        tmp_path / "real.h5", {"input": EV}, (2, 2), {"t_start_us": 0, "t_end_us": 40_000}
    )
    with pytest.raises(EventFileError, match="no ground truth"):
        check_paired(tmp_path / "real.h5")
    (tmp_path / "empty").mkdir()
    with pytest.raises(EventFileError, match="holds no sequence files"):
        list_sequences(tmp_path / "empty")
