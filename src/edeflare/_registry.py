"""One registry shape for everything made by name: methods, models, recipes, presets, kinds.

A :class:`Registry` maps names to entries (a factory, a preset, a config). An
entry joins at its definition (``@registry.register("name")`` or
``registry.register("name", entry)``); registering a name twice is an error;
an unknown name raises :class:`~edeflare.errors.ParameterError` (a
``ValueError``) listing the valid ones. A factory may declare a frozen
parameter dataclass (``params=``): :meth:`Registry.create` then rejects
unknown parameters by name, listing the valid ones, and the command line
builds its options from the same dataclass (:func:`param_fields`).

Examples
--------
>>> from dataclasses import dataclass
>>> shapes = Registry("shape")
>>> @dataclass(frozen=True)
... class SquareParams:
...     side: float = 1.0
>>> @shapes.register("square", params=SquareParams)
... def _square(side: float = 1.0) -> float:
...     return side * side
>>> shapes.create("square", side=3.0), sorted(shapes)
(9.0, ['square'])
>>> shapes.create("square", sides=3.0)
Traceback (most recent call last):
...
edeflare.errors.ParameterError: shape 'square' has no parameter 'sides'; valid: side
>>> shapes["circle"]
Traceback (most recent call last):
...
edeflare.errors.ParameterError: unknown shape 'circle'; registered shapes: square
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable, Iterator, Mapping
from typing import Any, Generic, TypeVar

from .errors import ParameterError

__all__ = ["CliOption", "Registry", "cli_option", "param_defaults", "param_fields"]

T = TypeVar("T")


class Registry(Mapping[str, T], Generic[T]):
    """Named entries of one kind; a read-only mapping ``name -> entry``.

    Parameters
    ----------
    kind : str
        What an entry is (``"method"``, ``"model"``, ``"recipe"``...), for messages.
    plural : str, optional
        Default: ``kind + "s"``.
    loader : callable, optional
        Called once before the first look-up (imports the modules that register).
    """

    def __init__(
        self, kind: str, *, plural: str | None = None, loader: Callable[[], None] | None = None
    ) -> None:
        self.kind = kind
        self.plural = plural or f"{kind}s"
        self._entries: dict[str, T] = {}
        self._params: dict[str, type | None] = {}
        self._loader = loader

    def _load(self) -> None:
        if self._loader is not None:
            loader, self._loader = self._loader, None
            loader()

    def register(self, name: str, entry: T | None = None, *, params: type | None = None) -> Any:
        """Add ``entry`` under ``name`` (without ``entry``: a decorator).

        ``params``: the entry's frozen parameter dataclass (for :meth:`create`).
        """
        if not isinstance(name, str) or not name:
            raise ParameterError(f"a {self.kind} name must be a non-empty string, got {name!r}")
        if params is not None and not dataclasses.is_dataclass(params):
            raise ParameterError(f"params of {self.kind} {name!r} must be a dataclass")

        def add(value: T) -> T:
            if name in self._entries:
                raise ParameterError(f"{self.kind} {name!r} is already registered")
            self._entries[name] = value
            self._params[name] = params
            return value

        return add if entry is None else add(entry)

    def unregister(self, name: str) -> None:
        """Remove ``name`` (for tests and examples)."""
        self._entries.pop(name, None)
        self._params.pop(name, None)

    def __getitem__(self, name: str) -> T:
        self._load()
        try:
            return self._entries[name]
        except (KeyError, TypeError):
            raise ParameterError(
                f"unknown {self.kind} {name!r}; registered {self.plural}: {', '.join(self.names())}"
            ) from None

    def __contains__(self, name: object) -> bool:
        self._load()
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        self._load()
        return iter(self._entries)

    def __len__(self) -> int:
        self._load()
        return len(self._entries)

    def names(self) -> list[str]:
        """Registered names, sorted."""
        self._load()
        return sorted(self._entries)

    def params(self, name: str) -> type | None:
        """The parameter dataclass of ``name`` (None when it declares none)."""
        self[name]
        return self._params[name]

    def parameters(self, name: str) -> dict[str, Any]:
        """``name``'s parameters and their defaults (from its dataclass, else its signature)."""
        cls = self.params(name)
        if cls is not None:
            return param_defaults(cls)
        sig = inspect.signature(self[name])  # type: ignore[arg-type]
        return {k: p.default for k, p in sig.parameters.items()}

    def check_params(self, name: str, params: Mapping[str, Any]) -> None:
        """Raise ParameterError naming every unknown parameter and the valid ones."""
        valid = self.parameters(name)
        unknown = [k for k in params if k not in valid]
        if unknown:
            plural = "s" if len(unknown) > 1 else ""
            raise ParameterError(
                f"{self.kind} {name!r} has no parameter{plural} {', '.join(map(repr, unknown))}; "
                f"valid: {', '.join(valid) if valid else '(none)'}"
            )

    def create(self, name: str, **params: Any) -> Any:
        """Call the factory ``name`` with ``params`` (unknown parameters are an error)."""
        factory = self[name]
        self.check_params(name, params)
        return factory(**params)  # type: ignore[operator]


# ----------------------------------------------------------------------------- parameters


@dataclasses.dataclass(frozen=True)
class CliOption:
    """How a parameter appears on the command line (field metadata ``"cli"``).

    Attributes
    ----------
    flag : str
        The option, e.g. ``"--efr-merge-ms"``.
    help : str
        Help text; the default is appended as ``[value]`` unless ``default_text``
        says otherwise (``""``: nothing appended).
    metavar : str, optional
    unit : {"", "ms"}
        ``"ms"``: the option takes milliseconds, the parameter microseconds.
    kind : {"value", "flag", "bool"}
        A value, a ``store_true`` flag, or ``--x / --no-x``.
    type : callable, optional
        Parser of the value (default: the field's default's type).
    choices : tuple, optional
    default_text : str, optional
        Shown instead of the default.
    convert : callable, optional
        Makes the parameter from the parsed value (e.g. loads a file).
    """

    flag: str
    help: str
    metavar: str | None = None
    unit: str = ""
    kind: str = "value"
    type: Callable[[str], Any] | None = None
    choices: tuple[Any, ...] | None = None
    default_text: str | None = None
    convert: Callable[[Any], Any] | None = None

    def to_param(self, value: Any) -> Any:
        """The parameter value of a parsed option value."""
        if self.convert is not None:
            return self.convert(value)
        if self.unit == "ms":
            return round(value * 1000)
        return value

    def help_text(self, default: Any) -> str:
        """Help with the default (in the option's unit) appended."""
        if self.default_text is not None:
            shown = self.default_text
        elif self.kind == "flag" or default is None:
            shown = ""
        else:
            value = default / 1000 if self.unit == "ms" else default
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            shown = str(value)
        return f"{self.help} [{shown}]" if shown else self.help


def cli_option(flag: str, help: str, **options: Any) -> dict[str, CliOption]:
    """Field metadata: ``field(default=..., metadata=cli_option("--x", "what x is"))``."""
    return {"cli": CliOption(flag, help, **options)}


def param_fields(cls: type) -> list[tuple[dataclasses.Field[Any], CliOption | None]]:
    """The fields of a parameter dataclass with their command-line options (None: none)."""
    return [(f, f.metadata.get("cli")) for f in dataclasses.fields(cls)]


def param_defaults(cls: type) -> dict[str, Any]:
    """``{field: default}`` of a parameter dataclass, in declaration order."""
    out = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            out[f.name] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            out[f.name] = f.default_factory()
        else:
            out[f.name] = inspect.Parameter.empty
    return out
