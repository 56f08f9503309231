"""Classical de-flaring baselines of the paper (Appendix D), re-implemented faithfully.

- :mod:`~edeflare.baselines.efr`: EFR, the linear comb filter (Wang et al., ICRA 2022).
- :mod:`~edeflare.baselines.pfd`: PFD-A / PFD-B, polarity-focused denoising
  (Shi et al., TCSVT 2025), the event-by-event program ``PFDs``.

Both are per-event state machines compiled with numba, in float64 and in the
original programs' order of operations, so that they reproduce the originals'
outputs exactly (the test suite checks this against golden files). Their
state objects (:class:`EFRFilter`, :class:`PFDFilter`) can be fed a stream
chunk by chunk with the same result as one pass.

The one-pass functions live in their modules (``edeflare.baselines.efr.efr``,
``edeflare.baselines.pfd.pfd``; they are not re-exported here so that they do
not shadow the modules), and every method is also reachable by name through
:func:`edeflare.create_method` / :func:`edeflare.deflare`.
"""

from __future__ import annotations

from .efr import EFRFilter, efr_bias, efr_delays
from .pfd import PFDFilter, pfd_mask

__all__ = ["EFRFilter", "PFDFilter", "efr_bias", "efr_delays", "pfd_mask"]
