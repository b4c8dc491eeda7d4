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

import functools
import importlib
import pkgutil
from collections.abc import Mapping
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
    kind : type, optional
        The value's type when the default's is not it.
    renamed : dict, optional
        ``{old value: new value}`` of choices that were renamed: the old spelling is
        refused with an error naming the new one.
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
    renamed: dict | None = None

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
        if self.renamed and value in self.renamed:
            raise ParameterError(
                f"parameter '{self.name}': {value!r} was renamed to {self.renamed[value]!r}; "
                f"allowed: {self.allowed()}")
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


@dataclass(frozen=True)
class ComponentParameter:
    """A component chosen by name, with its own options (pyamg's
    ``presmoother=('gauss_seidel', {'sweep': 'symmetric'})`` style).

    The resolved value is a :class:`Component` ``(kind, options)``. From Python
    give ``"kind"``, ``("kind", {...})`` or a :class:`Component`; on the command
    line ``--set name=kind`` and ``--set name.option=value``.

    Parameters
    ----------
    name : str
    default : str
        Default kind.
    kinds : dict
        ``{kind: (Parameter, ...)}``: the options each kind accepts (with
        their defaults, declared here once).
    help : str
    """

    name: str
    default: str
    kinds: dict
    help: str = ""

    @property
    def choices(self) -> tuple:
        return tuple(self.kinds)

    def allowed(self) -> str:
        return "one of " + ", ".join(self.kinds)

    def validate(self, value: Any, extra: dict | None = None) -> "Component":
        """Resolve ``value`` (plus dotted options ``extra``) into a Component.

        Raises
        ------
        ParameterError
            For an unknown kind or an option the kind does not have.
        """
        if isinstance(value, Component):
            kind, given = value.kind, dict(value.options)
        elif isinstance(value, (tuple, list)) and len(value) == 2 and isinstance(value[1], dict):
            kind, given = value[0], dict(value[1])
        else:
            kind, given = value, {}
        if kind not in self.kinds:
            raise ParameterError(f"parameter '{self.name}': {kind!r} is not allowed; "
                                 f"allowed: {self.allowed()}")
        given.update(extra or {})
        declared = self.kinds[kind]
        names = {p.name for p in declared}
        unknown = sorted(set(given) - names)
        if unknown:
            known = ", ".join(f"{self.name}.{n}" for n in names) or "(none)"
            raise ParameterError(f"parameter '{self.name}' = {kind!r} has no option "
                                 f"{', '.join(repr(self.name + '.' + u) for u in unknown)}; "
                                 f"known: {known}")
        opts = {p.name: _prefixed(p, self.name).validate(given.get(p.name, p.default))
                for p in declared}
        return Component(kind, opts)


def _prefixed(p: Parameter, owner: str) -> Parameter:
    """``p`` renamed ``owner.name`` so that its messages name the dotted option."""
    from dataclasses import replace
    return replace(p, name=f"{owner}.{p.name}")


@dataclass(frozen=True)
class Component:
    """A resolved :class:`ComponentParameter`: the chosen kind and its options."""

    kind: str
    options: dict

    def __getitem__(self, key):          # component["smoother"]
        return self.options[key]

    def __str__(self) -> str:
        inner = ", ".join(f"{k}={v}" for k, v in self.options.items())
        return f"{self.kind}({inner})" if inner else self.kind


class Options(Mapping):
    """Resolved options of a solver or problem: a read-only mapping with attribute
    access (``opts.update`` is the option ``update``, whatever its name)."""

    def __init__(self, values: dict | None = None):
        self._values = dict(values or {})

    def __getitem__(self, key):
        return self._values[key]

    def __iter__(self):
        return iter(self._values)

    def __len__(self):
        return len(self._values)

    def __getattr__(self, key):
        try:
            return self.__dict__["_values"][key]
        except KeyError:
            raise AttributeError(key) from None

    def __repr__(self):
        return f"Options({self._values!r})"

    def flat(self) -> dict:
        """``{name: value}`` with components spelled ``kind`` and ``name.option``."""
        out = {}
        for key, value in self.items():
            if isinstance(value, Component):
                out[key] = value.kind
                out.update({f"{key}.{k}": v for k, v in value.options.items()})
            else:
                out[key] = value
        return out


def resolve_parameters(declared: tuple, given: dict[str, Any], owner: str) -> Options:
    """Defaults overridden by ``given``, every value validated.

    ``given`` may set a component's options with dotted keys
    (``{"ahat": "sa", "ahat.max_coarse": 200}``).

    Raises
    ------
    ParameterError
        For an unknown name (listing the known ones) or an invalid value.
    """
    by_name = {p.name: p for p in declared}
    plain = {k: v for k, v in given.items() if "." not in k}
    dotted: dict[str, dict] = {}
    for key, value in given.items():
        if "." in key:
            head, _, tail = key.partition(".")
            dotted.setdefault(head, {})[tail] = value
    unknown = sorted(set(plain) - set(by_name))
    unknown += sorted(f"{h}.{t}" for h, opts in dotted.items() for t in opts
                      if not isinstance(by_name.get(h), ComponentParameter))
    if unknown:
        known = ", ".join(by_name) or "(none)"
        raise ParameterError(f"{owner} has no parameter {', '.join(map(repr, unknown))}; "
                             f"known parameters: {known}")
    out = {}
    for name, p in by_name.items():
        if isinstance(p, ComponentParameter):
            out[name] = p.validate(plain.get(name, p.default), dotted.get(name))
        else:
            out[name] = p.validate(plain.get(name, p.default))
    return Options(out)


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
        ``"contact"``: ``build`` returns a :class:`problems.qp.ContactQP`;
        ``"linear"``: ``build`` returns an object with ``solve()`` (no contact,
        e.g. the Laplace problem of Ch. 6) and any QP solver is meaningless.
    levels : tuple[int, int]
        Smallest and largest admissible refinement level.
    dim : int
        Spatial dimension: one uniform level multiplies the nodes by about ``2**dim``
        (the resource planner, ``workflows/planning.py``, reads it).
    parameters : tuple[Parameter, ...]
        Scene parameters (declared here once), overridable from the CLI.
    build : callable
        ``build(level, params)`` with ``params`` the resolved :class:`Options`;
        the one entry point.
    default_level : int
        Level used when the CLI gets none.
    thesis_tables : dict
        ``{study: reference table}`` this scene regenerates with the thesis's
        own parameters, e.g. ``{"augmented_projection": "table_9_1"}``
        (``reference/<table>.csv``).
    """

    name: str
    summary: str
    kind: str
    levels: tuple[int, int]
    parameters: tuple[Parameter, ...]
    build: Callable[..., Any]
    dim: int = 2
    default_level: int = 1
    thesis_tables: dict = field(default_factory=dict)

    def check_level(self, level: Any) -> int:
        lo, hi = self.levels
        return Parameter("level", lo, low=lo, high=hi, kind=int).validate(level)

    def options(self, **params: Any) -> Options:
        """The resolved parameters: defaults overridden by ``params``, validated."""
        return resolve_parameters(self.parameters, params, f"problem '{self.name}'")

    def make(self, level: int | None = None, **params: Any) -> Any:
        """Validate ``level`` and ``params`` and call :attr:`build`."""
        level = self.check_level(self.default_level if level is None else level)
        return self.build(level, self.options(**params))


def discover(package: str, attribute: str) -> dict[str, Any]:
    """Import every module of ``package`` that defines ``attribute`` (or a tuple of them,
    ``attribute + "S"``).

    Modules whose name starts with an underscore and subpackages (shared
    machinery such as ``problems.fem``) are skipped. Returns ``{name: spec}``
    sorted by name; a module's registry name is its ``spec.name``. The package's folder
    is read once per process (a registry is asked for at every solve).
    """
    return dict(_discovered(package, attribute))


@functools.lru_cache(maxsize=None)
def _discovered(package: str, attribute: str) -> dict[str, Any]:
    pkg = importlib.import_module(package)
    found = {}
    for info in pkgutil.iter_modules(pkg.__path__):
        if info.ispkg or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{package}.{info.name}")
        spec = getattr(module, attribute, None)
        # one spec per module, or a table of them (e.g. SOLVERS, one per QP library)
        for spec in ([spec] if spec is not None else getattr(module, attribute + "S", ())):
            if spec.name in found:
                raise RuntimeError(f"two {package} modules register the name {spec.name!r}")
            found[spec.name] = spec
    return dict(sorted(found.items()))


@dataclass
class Plugins:
    """What one entry-point group holds: ``specs`` ``{name: spec}`` and ``packages``
    ``{name: (distribution, version)}`` of the installed packages that register them."""

    specs: dict[str, Any]
    packages: dict[str, tuple[str, str | None]]


def load_plugins(group: str, attribute: str, spec_type: type, what: str) -> Plugins:
    """The specs other installed packages register under the entry-point ``group``: each
    entry point names a ``spec_type`` or a module defining ``attribute``. One that cannot
    be loaded, is not a ``spec_type``, or repeats another plug-in's name is left out with a
    warning that says why: a broken plug-in never breaks the suite."""
    import warnings
    from importlib.metadata import entry_points

    found, packages = {}, {}
    for ep in entry_points(group=group):
        try:
            obj = ep.load()
        except Exception as err:                 # whatever the plug-in's import raises
            warnings.warn(f"{what} plug-in {ep.name!r} ({ep.value}) is left out: it could not "
                          f"be loaded ({type(err).__name__}: {err})", RuntimeWarning,
                          stacklevel=3)
            continue
        spec = getattr(obj, attribute, obj)
        if not isinstance(spec, spec_type):
            warnings.warn(f"{what} plug-in {ep.name!r} ({ep.value}) is left out: it names a "
                          f"{type(spec).__name__}, not a {spec_type.__module__}."
                          f"{spec_type.__name__}", RuntimeWarning, stacklevel=3)
            continue
        if spec.name in found:
            warnings.warn(f"{what} plug-in {ep.name!r} ({ep.value}) is left out: another "
                          f"plug-in registers the name {spec.name!r} already", RuntimeWarning,
                          stacklevel=3)
            continue
        found[spec.name] = spec
        dist = getattr(ep, "dist", None)
        packages[spec.name] = (getattr(dist, "name", None) or ep.value.split(":")[0],
                               getattr(dist, "version", None))
    return Plugins(found, packages)


def with_plugins(built_in: dict[str, Any], plugins: dict[str, Any], what: str) -> dict[str, Any]:
    """``built_in`` and the plug-ins' specs ``plugins``, sorted by name; a built-in name
    wins a clash (the plug-in is left out with a warning)."""
    import warnings

    found = dict(built_in)
    for name, spec in plugins.items():
        if name in found:
            origin = getattr(getattr(spec, "solve", None) or getattr(spec, "build", None),
                             "__module__", "?")
            warnings.warn(f"{what} plug-in {name!r} ({origin}) is left out: a built-in {what} "
                          f"has that name", RuntimeWarning, stacklevel=3)
        else:
            found[name] = spec
    return dict(sorted(found.items()))


def lookup(registry: dict[str, Any], name: str, what: str) -> Any:
    """``registry[name]`` or a ParameterError listing the allowed names."""
    try:
        return registry[name]
    except KeyError:
        raise ParameterError(f"unknown {what} {name!r}; allowed: {', '.join(registry)}") from None


def contact_scene_error(problem: Any, params: dict | None) -> tuple[str, str] | None:
    """What is wrong with a scene entry ``{problem, params}`` that must name a registered
    contact problem with valid parameters: ``(key, message)`` (key ``problem`` or
    ``params``), or None. Configs and test sets prefix the message with where it stands."""
    registry = problems()
    if problem not in registry:
        return "problem", (f"{problem!r} is not a registered problem; allowed: "
                           f"{', '.join(registry)}")
    if registry[problem].kind != "contact":
        return "problem", f"{problem!r} is not a contact problem"
    try:
        registry[problem].options(**(params or {}))
    except ParameterError as err:
        return "params", str(err)
    return None


#: The entry-point group through which another installed package registers a scene: its
#: value names a :class:`ProblemSpec` (``"package.module:PROBLEM"``) or a module defining
#: ``PROBLEM`` (docs/guide/add-a-scene.md).
SCENE_ENTRY_POINT_GROUP = "contactbench.scenes"


@functools.lru_cache(maxsize=1)
def external_problems() -> dict[str, ProblemSpec]:
    """The scenes of other installed packages (:data:`SCENE_ENTRY_POINT_GROUP`), read once
    per process (:func:`load_plugins`)."""
    return load_plugins(SCENE_ENTRY_POINT_GROUP, "PROBLEM", ProblemSpec, "scene").specs


def problems() -> dict[str, ProblemSpec]:
    """All registered problems, ``{name: ProblemSpec}``: the modules of ``problems/`` that
    define ``PROBLEM``, and the scenes other installed packages register under
    :data:`SCENE_ENTRY_POINT_GROUP` (a built-in name wins a clash)."""
    return with_plugins(discover("problems", "PROBLEM"), external_problems(), "scene")
