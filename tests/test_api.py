"""The package face: lazy, free of import side effects, and offering the main jobs."""

from __future__ import annotations

import json
import subprocess
import sys

import edeflare
from edeflare.events import make_events


def test_import_loads_nothing_heavy_and_sets_nothing():
    code = (
        "import json, sys, edeflare; "
        "print(json.dumps({m: m in sys.modules for m in "
        "('numba', 'h5py', 'faery', 'torch', 'scipy', 'edeflare.methods')}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == dict.fromkeys(
        ("numba", "h5py", "faery", "torch", "scipy", "edeflare.methods"), False
    )


def test_every_public_name_resolves():
    for name in edeflare.__all__:
        assert getattr(edeflare, name) is not None, name
    assert set(edeflare.__all__) <= set(dir(edeflare))


def test_deflare_is_the_function_of_the_methods_package():
    import edeflare.methods

    assert edeflare.deflare is edeflare.methods.deflare
    assert not isinstance(edeflare.deflare, type(edeflare))  # a function, not a module
    ev = make_events([0, 5_000, 30_000], [1, 2, 3], [0, 0, 0], [1, 0, 1])
    assert edeflare.deflare(ev, (4, 1), "efr", frequency_hz=50)["t"].tolist() == [0, 5000]


def test_main_jobs_are_on_the_face():
    from edeflare.eval.evaluate import evaluate_events
    from edeflare.models import create_model
    from edeflare.sim.pair import simulate_pair

    assert edeflare.evaluate_events is evaluate_events
    assert edeflare.simulate_pair is simulate_pair
    assert edeflare.create_model is create_model
    from edeflare._version import __version__

    assert edeflare.__version__ == __version__
