"""The ghost prior (lights reflected through the sensor's centre) and its logit shift."""

from __future__ import annotations

import numpy as np
import pytest

from edeflare.events import make_events, merge_events
from edeflare.lights.cells import LIGHT_RATE
from edeflare.rules.ghost import ghost_cells, in_ghost_prior


def _light(x0: int, y0: int, n: int = 400, size: int = 8) -> np.ndarray:
    """``n`` events in the ``size`` x ``size`` pixels from (x0, y0), over 20 ms."""
    k = np.arange(n)
    return make_events(k * (20_000 // n), x0 + k % size, y0 + k // size % size, np.ones(n))


def test_a_corner_light_has_its_ghosts_on_the_diagonal_through_the_centre():
    # 64x64 sensor, 8x8 cells: the centre is at cell coordinate 4; the light's cell
    # centre at 0.5. Ghost at 4 + k (0.5 - 4): k = 0.6 -> 1.9 (cell 1), 0.4 -> 2.6 (2),
    # -0.5 -> 5.75 (5), -1 -> 7.5 (7), -1.5 and beyond off the sensor. The light's own
    # cell and its four neighbours are left out; (1, 1) is only a diagonal neighbour.
    cells = ghost_cells(_light(0, 0), (64, 64), 20_000, widen=0)
    assert sorted(zip(*np.nonzero(cells), strict=True)) == [(1, 1), (2, 2), (5, 5), (7, 7)]
    widened = ghost_cells(_light(0, 0), (64, 64), 20_000, widen=1)
    assert widened[6, 7] and widened[4, 5] and not widened[0, 7]


def test_the_prior_follows_the_light_and_a_light_needs_its_rate():
    # a light in cell (3, 7) at the right edge (centre 3.5, 7.5): its k = -1 ghost is at
    # 4 - (3.5 - 4) = 4.5, 4 - (7.5 - 4) = 0.5, cell (4, 0) at the left edge
    cells = ghost_cells(_light(56, 24), (64, 64), 20_000, widen=0)
    assert cells[4, 0] and not cells[3, 7]
    # 320 events in an 8x8 cell are a light in 20 ms (LIGHT_RATE 0.25 / px / ms) ...
    assert LIGHT_RATE * 64 * 20 == 320
    assert ghost_cells(_light(0, 0, n=320), (64, 64), 20_000).any()
    # ... but not in 40 ms, nor 319 of them in 20 ms
    assert not ghost_cells(_light(0, 0, n=320), (64, 64), 40_000).any()
    assert not ghost_cells(_light(0, 0, n=319), (64, 64), 20_000).any()
    empty = make_events([], [], [], [])
    assert not ghost_cells(empty, (64, 64), 20_000).any()


def test_in_ghost_prior_reads_each_events_cell():
    far = make_events([1, 2, 3], [60, 61, 58], [60, 57, 4], [1, 0, 1])
    ev = merge_events(_light(0, 0), far)
    inside = in_ghost_prior(ev, (64, 64), 20_000)
    cells = ghost_cells(ev, (64, 64), 20_000)
    np.testing.assert_array_equal(inside, cells[ev["y"] // 8, ev["x"] // 8])
    assert inside[np.isin(ev["x"], [60, 61])].all() and not inside[ev["x"] == 58].any()
    # the cells, when given, are used as they are
    np.testing.assert_array_equal(in_ghost_prior(ev, (64, 64), 20_000, cells=cells), inside)
    only = np.zeros_like(cells)
    only[7, 7] = True  # the cell of the events at (60, 60) and (61, 57)
    assert in_ghost_prior(ev, (64, 64), 20_000, cells=only).sum() == 2


def test_the_prior_covers_only_sparse_events_in_its_cells():
    # the corner light's k = -1 ghost cell is (7, 7): pixels 56-63. A lone event and a
    # line of three there are sparse (at most 4 events in each 3x3 neighbourhood: the
    # line's middle pixel sees 3); a solid 3x3 block is not (its centre sees 9, its
    # corners 4, its edges 6)
    lone = make_events([1], [62], [62], [1])
    line = make_events([2, 3, 4], [56, 57, 58], [57, 57, 57], [1, 1, 1])
    yy, xx = np.mgrid[59:62, 56:59]
    block = make_events(np.arange(5, 14), xx.ravel(), yy.ravel(), np.ones(9))
    ev = merge_events(_light(0, 0), lone, line, block)
    in_cells = in_ghost_prior(ev, (64, 64), 20_000, max_neighbours=None)
    sparse = in_ghost_prior(ev, (64, 64), 20_000)
    at = {(int(x), int(y)): bool(v) for x, y, v in zip(ev["x"], ev["y"], sparse, strict=True)}
    assert in_cells[ev["x"] >= 56].all() and np.array_equal(sparse, in_cells & sparse)
    assert at[(62, 62)] and at[(56, 57)] and at[(57, 57)] and at[(58, 57)]
    assert at[(56, 59)] and at[(58, 61)]  # the block's corners: 4 each
    assert not at[(57, 60)] and not at[(57, 59)] and not at[(56, 60)]  # centre 9, edges 6
    # a looser gate: only the block's centre (9) is left out of the 13 events there
    assert in_ghost_prior(ev, (64, 64), 20_000, max_neighbours=8)[ev["x"] >= 56].sum() == 12


@pytest.mark.parametrize("kw, what", [({"cell": 0}, "cell must be"), ({"widen": -1}, "widen")])
def test_bad_prior_settings_are_refused(kw, what):
    with pytest.raises(ValueError, match=what):
        ghost_cells(_light(0, 0), (64, 64), 20_000, **kw)
    with pytest.raises(ValueError, match="window_us"):
        ghost_cells(_light(0, 0), (64, 64), 0)


def test_light_cells_of_another_grid_are_refused():
    with pytest.raises(ValueError, match="lights has shape"):
        ghost_cells(_light(0, 0), (64, 64), 20_000, lights=np.ones((4, 4), dtype=bool))


def test_the_ghost_maps_are_computed_once_per_sensor_and_cannot_be_changed():
    from edeflare.rules.ghost import GHOST_FACTORS, _ghost_maps

    first = _ghost_maps(64, 64, 8, GHOST_FACTORS)
    assert _ghost_maps(64, 64, 8, GHOST_FACTORS)[0] is first[0]
    with pytest.raises(ValueError, match="read-only"):
        first[2][0, 0] = 5
    # factor -1 of cell (0, 0) (the point reflected through the centre): cell (7, 7)
    assert first[2][GHOST_FACTORS.index(-1.0), 0] == 7 * 8 + 7
