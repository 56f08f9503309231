"""Project exceptions.

Every error that a user can cause (a bad file, a bad array, a bad option)
raises a subclass of :class:`EdeflareError`, so that the command line can
print one line and exit non-zero instead of a traceback.
"""

from __future__ import annotations

import os

__all__ = [
    "AnnotationError",
    "DependencyError",
    "EdeflareError",
    "EventFileError",
    "EventsError",
    "ParameterError",
    "UnknownFormatError",
]


class EdeflareError(Exception):
    """Base class of every error raised on purpose by edeflare."""


class EventsError(EdeflareError, ValueError):
    """An event array is malformed: wrong dtype, unsorted, out of range, NaN..."""


class ParameterError(EdeflareError, ValueError):
    """A method or option was given an unknown name or an invalid value."""


class EventFileError(EdeflareError, ValueError):
    """A file cannot be read or written; the message names the file.

    Parameters
    ----------
    path : str or os.PathLike
        The file concerned.
    problem : str
        What is wrong with it, phrased for a user.

    Examples
    --------
    >>> str(EventFileError("rec.h5", "file is empty"))
    'rec.h5: file is empty'
    """

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        self.path = os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class UnknownFormatError(EventFileError):
    """The file's suffix names no format edeflare can read or write."""


class AnnotationError(EventFileError):
    """A light-source annotation (regions JSON) is malformed or lies off the sensor.

    Examples
    --------
    >>> str(AnnotationError("lights.json", "source 0: circle lies off the 640x480 sensor"))
    'lights.json: source 0: circle lies off the 640x480 sensor'
    """


class DependencyError(EdeflareError, ImportError):
    """An optional dependency is missing; the message names the extra that installs it."""
