"""Plug-in specifications shared by problems and solvers.

A problem module under ``problems/`` (or a solver module under ``solvers/``)
becomes part of the suite by defining one module-level object, ``PROBLEM``
(a :class:`ProblemSpec`) or ``SOLVER`` (a ``solvers.interface.SolverSpec``).
:func:`discover` finds them; adding a module touches no other file.

Parameters are declared with :class:`Parameter`, which validates values coming
from Python or from the command line (``--set key=value``) and raises a
:class:`ParameterError` that names the parameter and the allowed range.
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field
from typing import Any, Callable


class ParameterError(ValueError):
    """Bad user input: the message names the parameter and what is allowed."""


@dataclass(frozen=True)
class Parameter:
    """One named, typed, range-checked parameter of a problem or solver.

    Parameters
    ----------
    name : str
        Name used on the command line (``--set name=value``) and in Python.
    default : Any
        Default value; its type fixes the parameter's type unless ``kind`` is given.
    help : str
        One line for ``contactbench list``.
    choices : tuple, optional
        Allowed values (for strings).
    low, high : float, optional
        Closed bounds for numbers (``None`` = unbounded).
    low_open, high_open : bool
        Make the corresponding bound strict.
    """

    name: str
    default: Any
    help: str = ""
    choices: tuple | None = None
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    kind: type | None = None

    @property
    def type(self) -> type:
        return self.kind or type(self.default)

    def allowed(self) -> str:
        """Human-readable description of the allowed values."""
        if self.choices is not None:
            return "one of " + ", ".join(map(str, self.choices))
        if self.type in (int, float):
            lo = "-inf" if self.low is None else repr(self.low)
            hi = "inf" if self.high is None else repr(self.high)
            return (f"a{'n integer' if self.type is int else ' number'} in "
                    f"{'(' if self.low_open or self.low is None else '['}{lo}, "
                    f"{hi}{')' if self.high_open or self.high is None else ']'}")
        if self.type is bool:
            return "true or false"
        return f"a {self.type.__name__}"

    def validate(self, value: Any) -> Any:
        """Convert ``value`` (possibly a string from the CLI) and check it.

        Raises
        ------
        ParameterError
            If the value cannot be converted or lies outside the allowed range.
        """
        t = self.type
        try:
            if t is bool and isinstance(value, str):
                low = value.strip().lower()
                if low not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError(value)
                value = low in ("true", "1", "yes")
            elif t is int and isinstance(value, float) and value.is_integer():
                value = int(value)
            elif t is int and isinstance(value, str):
                value = int(value.strip())
            elif t is float and isinstance(value, (str, int)) and not isinstance(value, bool):
                value = float(value)
            elif t is str:
                value = str(value)
            if not isinstance(value, t) or (t is not bool and isinstance(value, bool)):
                raise ValueError(value)
        except (TypeError, ValueError):
            raise ParameterError(
                f"parameter '{self.name}': cannot use {value!r}; allowed: {self.allowed()}"
            ) from None
        if self.choices is not None and value not in self.choices:
            raise ParameterError(
                f"parameter '{self.name}': {value!r} is not allowed; allowed: {self.allowed()}")
        if t in (int, float):
            if value != value or value in (float("inf"), float("-inf")):
                raise ParameterError(
                    f"parameter '{self.name}': {value!r} is not finite; allowed: {self.allowed()}")
            bad_low = self.low is not None and (value < self.low or (self.low_open and value == self.low))
            bad_high = self.high is not None and (value > self.high or (self.high_open and value == self.high))
            if bad_low or bad_high:
                raise ParameterError(
                    f"parameter '{self.name}': {value!r} is out of range; allowed: {self.allowed()}")
        return value


def resolve_parameters(declared: tuple[Parameter, ...], given: dict[str, Any],
                       owner: str) -> dict[str, Any]:
    """Defaults overridden by ``given``, every value validated.

    Raises
    ------
    ParameterError
        For an unknown name (listing the known ones) or an invalid value.
    """
    by_name = {p.name: p for p in declared}
    unknown = sorted(set(given) - set(by_name))
    if unknown:
        known = ", ".join(by_name) or "(none)"
        raise ParameterError(f"{owner} has no parameter {', '.join(map(repr, unknown))}; "
                             f"known parameters: {known}")
    return {name: p.validate(given.get(name, p.default)) for name, p in by_name.items()}


@dataclass(frozen=True)
class ProblemSpec:
    """Entry point of one problem module.

    Attributes
    ----------
    name : str
        Registry name (the module name).
    summary : str
        One line: what the scene is, with the thesis section.
    kind : str
        ``"contact"``: ``build`` returns a ``solvers.interface.ContactQP``;
        ``"linear"``: ``build`` returns an object with ``solve()`` (no contact,
        e.g. the Laplace problem of Ch. 6) and any QP solver is meaningless.
    levels : tuple[int, int]
        Smallest and largest admissible refinement level.
    parameters : tuple[Parameter, ...]
        Scene parameters, overridable from the CLI.
    build : callable
        ``build(level, **params)``; the one entry point.
    default_level : int
        Level used when the CLI gets none.
    """

    name: str
    summary: str
    kind: str
    levels: tuple[int, int]
    parameters: tuple[Parameter, ...]
    build: Callable[..., Any]
    default_level: int = 1
    extras: dict = field(default_factory=dict)

    def check_level(self, level: Any) -> int:
        lo, hi = self.levels
        return Parameter("level", lo, low=lo, high=hi, kind=int).validate(level)

    def make(self, level: int | None = None, **params: Any) -> Any:
        """Validate ``level`` and ``params`` and call :attr:`build`."""
        level = self.check_level(self.default_level if level is None else level)
        values = resolve_parameters(self.parameters, params, f"problem '{self.name}'")
        return self.build(level, **values)


def discover(package: str, attribute: str) -> dict[str, Any]:
    """Import every module of ``package`` that defines ``attribute``.

    Modules whose name starts with an underscore and subpackages (shared
    machinery such as ``problems.fem``) are skipped. Returns ``{name: spec}``
    sorted by name; a module's registry name is its ``spec.name``.
    """
    pkg = importlib.import_module(package)
    found = {}
    for info in pkgutil.iter_modules(pkg.__path__):
        if info.ispkg or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{package}.{info.name}")
        spec = getattr(module, attribute, None)
        if spec is not None:
            if spec.name in found:
                raise RuntimeError(f"two {package} modules register the name {spec.name!r}")
            found[spec.name] = spec
    return dict(sorted(found.items()))


def lookup(registry: dict[str, Any], name: str, what: str) -> Any:
    """``registry[name]`` or a ParameterError listing the allowed names."""
    try:
        return registry[name]
    except KeyError:
        raise ParameterError(f"unknown {what} {name!r}; allowed: {', '.join(registry)}") from None


def problems() -> dict[str, ProblemSpec]:
    """All registered problems, ``{name: ProblemSpec}``."""
    return discover("problems", "PROBLEM")
