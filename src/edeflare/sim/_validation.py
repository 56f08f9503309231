"""The simulator's error class and the package's checks (:mod:`edeflare._validation`) raising it."""

from __future__ import annotations

import functools

from .. import _validation as _v
from ..errors import EdeflareError

__all__ = [
    "SimError",
    "check_choice",
    "check_interval",
    "check_range",
    "dataclass_from_dict",
    "make_rng",
]


class SimError(EdeflareError, ValueError):
    """A simulator input or option is invalid (the message says what was received)."""


make_rng = functools.partial(_v.make_rng, error=SimError)
check_range = functools.partial(_v.check_range, error=SimError)
check_interval = functools.partial(_v.check_interval, error=SimError)
check_choice = functools.partial(_v.check_choice, error=SimError)
dataclass_from_dict = functools.partial(_v.dataclass_from_dict, error=SimError)
