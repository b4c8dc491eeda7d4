"""The contact QP test set: named problems from the registered scenes, declared once.

A test set is a YAML file under ``workflows/config/test_sets/`` (the current one is
:data:`CURRENT`)::

    name: contact-qp
    version: 1
    classes:                  # size class -> registered problem -> levels
      small: {circle_square: [0, 1], cube_sphere: [0, 1], ...}
      medium: {...}
    families:                 # a family = a scene: a registered problem + overrides
      circle_square: {problem: circle_square}
      hard_si_units: {problem: circle_square, params: {E1: 2.1e+11, ...}}
      circle_square_p2:       # its own levels per class (P2 has 4x the nodes of P1)
        {problem: circle_square, params: {degree: 2}, levels: {small: [0], medium: [1, 2]}}

A problem is a family at one level of a class, named ``<family>_L<level>``; a family's
``levels`` (class -> levels) replace its problem's levels of ``classes`` (a class it
leaves out has none of its problems).

A frictional family (``params: {friction: tresca | coulomb, mu: .., shift: ..}``) is one
Tresca step of its scene's load path (:func:`frictional_steps`): ``step: last`` (the
default) its last tangential step, ``step: <j>`` the tangential step ``j`` (1 ..
``shift_steps``), ``step: all`` every tangential step, one problem each, named
``<family>_L<level>_s<j>`` (a load-path family: each step's warm start is the previous
step's reference solution). The
families are also the workflow's scenes (:func:`workflows.studies.scenes_with_families`),
so a hard case or a scene variant is typed once. A set's ``files`` (:data:`EXPORT_FILES`)
name what its export adds to every problem folder; a set that extends another keeps its
files and its description (its own appended). Loading checks every name,
problem, parameter, level and step (:class:`TestSetError` names the key and what is
allowed); loading builds no problem.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from workflows.yaml_io import read_yaml

from problems.spec import contact_scene_error, problems

#: Where the sets live, and the one ``contactbench export`` uses by default.
SETS_DIR = Path(__file__).resolve().parent / "config" / "test_sets"
CURRENT = "contact-qp-6"
#: Size classes, smallest first.
CLASSES = ("small", "medium", "large")
#: A family's keys.
FAMILY_KEYS = ("problem", "params", "levels", "step")
#: The files a set's export may add to every problem folder beyond the QP and cone files
#: (its ``files``): ``fclib`` the fclib global file (:func:`workflows.export.fclib_file`),
#: ``multigrid`` what a multigrid solver needs (:func:`workflows.export.multigrid_file`).
EXPORT_FILES = ("fclib", "multigrid")
#: A frictional family's ``step`` besides a step number: the last step, or every one.
STEP_CHOICES = ("last", "all")
#: Significant digits (of the vector's largest entry) kept in a frictional step's slip
#: bounds and previous state (:func:`definition_digits`).
DEFINITION_DIGITS = 8


#: The problem classes a comparison ranks apart (:func:`problem_class`): a solver is
#: ranked among the solvers that take the class, never across classes.
PROBLEM_CLASSES = {
    "frictionless": "frictionless contact QP",
    "friction_2d": "2D frictional step (QP in (u, t))",
    "friction_3d_cone": "3D frictional step (second-order cone program)",
    "friction_3d_facets": "3D faceted frictional step (QP)",
}


def problem_class(meta: dict) -> str:
    """The class of an exported problem (its ``meta.json``; :data:`PROBLEM_CLASSES`)."""
    if not meta.get("friction"):
        return "frictionless"
    if int(meta["dim"]) == 2:
        return "friction_2d"
    return "friction_3d_cone" if meta["form"] == "cone" else "friction_3d_facets"


def cold_rows(t):
    """The rows of run tables started from zero (``start`` ``cold``; a table written before
    the column existed is all cold): what every table but the warm-start comparison reads."""
    return t if "start" not in t else t[t["start"].fillna("cold") == "cold"]


def plain_rows(t):
    """The cold rows at rung 0 of each tolerance ladder (:mod:`workflows.ladder`; a table
    without the column is all rung 0): each solver's plain run at a preset's own mapping."""
    t = cold_rows(t)
    return t if "rung" not in t else t[t["rung"].fillna(0) == 0]


class TestSetError(ValueError):
    """A test set name, class or definition that is not allowed (the message says which)."""

    __test__ = False        # not a pytest test class


@dataclass(frozen=True)
class SetProblem:
    """One problem of a test set: a family (scene) at one level.

    Attributes
    ----------
    name : str
        ``<family>_L<level>``, the folder name of the export.
    family, problem : str
        The family (a scene name) and the registered problem behind it.
    params : dict
        The family's parameter overrides (the problem's defaults for the rest).
    level : int
        Refinement level.
    size_class : str
        One of :data:`CLASSES`.
    step : int or None
        A frictional family's tangential step (1 .. ``shift_steps``) of the scene's load
        path; ``None`` without friction.
    """

    name: str
    family: str
    problem: str
    params: dict
    level: int
    size_class: str
    step: int | None = None

    def build(self):
        """The :class:`problems.qp.ContactQP` (the registered problem's ``build``); a
        frictional problem's is its Tresca step (:meth:`frictional_step`)."""
        if self.step is not None:
            return self.frictional_step().qp
        spec = problems()[self.problem]
        return spec.build(self.level, spec.options(**self.params))

    def frictional_step(self) -> "FrictionStep":
        """The frictional problem's step of its load path (:func:`frictional_steps`)."""
        if self.step is None:
            raise ValueError(f"{self.name} has no friction")
        return frictional_steps(self.problem, tuple(sorted(self.params.items())),
                                self.level)[self.step]


@dataclass(frozen=True)
class TestSet:
    """A loaded test set (see the module docstring)."""

    __test__ = False

    name: str
    version: int
    description: str
    classes: dict = field(repr=False)
    families: dict = field(repr=False)
    files: tuple = ()

    @property
    def id(self) -> str:
        """``<name>-<version>``, e.g. ``contact-qp-1``."""
        return f"{self.name}-{self.version}"

    def problems(self, size_class: str | None = None,
                 families: list[str] | None = None) -> list[SetProblem]:
        """The set's problems (of one class, of some families), in declaration order:
        family by family, levels ascending."""
        if size_class is not None:
            check_class(size_class)
        chosen = list(self.families) if families is None else list(families)
        unknown = [f for f in chosen if f not in self.families]
        if unknown:
            raise TestSetError(f"families {unknown} are not in the set {self.id}; allowed: "
                               f"{', '.join(self.families)}")
        out = []
        for fam in chosen:
            entry = self.families[fam]
            params = dict(entry.get("params") or {})
            steps = family_steps(problems()[entry["problem"]].options(**params),
                                 step_choice(entry))
            for cls in CLASSES if size_class is None else (size_class,):
                for level in self.levels(fam, cls):
                    for step in steps:
                        name = f"{fam}_L{level}" + (f"_s{step}" if len(steps) > 1 else "")
                        out.append(SetProblem(name, fam, entry["problem"], dict(params),
                                              int(level), cls, step))
        return out

    def levels(self, family: str, size_class: str) -> list[int]:
        """The levels of ``family`` in ``size_class``: its own ``levels`` if it declares
        them, else its problem's in ``classes``."""
        entry = self.families[family]
        if entry.get("levels") is not None:
            return list(entry["levels"].get(size_class) or [])
        return list(self.classes.get(size_class, {}).get(entry["problem"]) or [])


def available() -> list[str]:
    """The names of the test sets under :data:`SETS_DIR`."""
    return sorted(p.stem for p in SETS_DIR.glob("*.yaml"))


def check_class(size_class: str) -> str:
    if size_class not in CLASSES:
        raise TestSetError(f"size class {size_class!r} is not allowed; allowed: "
                           f"{', '.join(CLASSES)}")
    return size_class


def set_file(name: str | Path, relative_to: Path | None = None) -> Path:
    """The file of the test set ``name``: a set of the suite (a file stem under
    :data:`SETS_DIR`, e.g. ``contact-qp-5``), or a path to a set file of your own
    (``.yaml``; relative to ``relative_to``, the file that names it, else the working
    directory)."""
    text = str(name)
    if text.endswith((".yaml", ".yml")):
        path = Path(text)
        if not path.is_absolute() and relative_to is not None:
            path = relative_to.parent / path
        if not path.is_file():
            raise TestSetError(f"test set file {text!r} does not exist; allowed: a set of the "
                               f"suite ({', '.join(available())}) or a set file")
        return path
    names = available()
    if text not in names:
        raise TestSetError(f"test set {text!r} is not allowed; allowed: {', '.join(names)} or "
                           "the path of a set file (.yaml)")
    return SETS_DIR / f"{text}.yaml"


def load(name: str | Path = CURRENT) -> TestSet:
    """The test set ``name`` (:func:`set_file`: a set of the suite or a set file of your
    own), checked. A set file may name another set as ``extends:`` (a set of the suite or
    a path relative to it): it then holds that set's classes and families, and its own
    families after them (a family of the set it extends may not be defined again).

    Raises
    ------
    TestSetError
        An unknown set name or file, or a definition that names an unknown problem,
        parameter, level or class, or a family twice.
    """
    path = set_file(name)
    with open(path, encoding="utf-8") as fh:
        raw = read_yaml(fh)
    classes, families = dict(raw.get("classes") or {}), dict(raw.get("families") or {})
    files = list(raw.get("files") or [])
    description = " ".join(str(raw.get("description", "")).split())
    wrong = [f for f in files if f not in EXPORT_FILES]
    if wrong:
        raise TestSetError(f"test set file {path.name} 'files': {wrong} are not allowed; "
                           f"allowed: {', '.join(EXPORT_FILES)}")
    if raw.get("extends"):
        base = load(set_file(raw["extends"], relative_to=path))
        files = [*base.files, *files]
        description = " ".join(filter(None, (base.description, description)))
        again = sorted(set(families) & set(base.families))
        if again:
            raise TestSetError(f"test set file {path.name} 'families': {again} are families of "
                               f"the set it extends, {base.id}; allowed: new names")
        classes = {c: {**base.classes.get(c, {}), **classes.get(c, {})}
                   for c in {*base.classes, *classes}}
        families = {**base.families, **families}
    ts = TestSet(name=str(raw["name"]), version=int(raw["version"]),
                 description=description,
                 classes=classes, families=families,
                 files=tuple(f for f in EXPORT_FILES if f in files))
    if path.parent == SETS_DIR and ts.id != path.stem:
        raise TestSetError(f"test set file {path.name} declares name-version {ts.id!r}; "
                           f"allowed: {path.stem!r}")
    check(ts)
    return ts


def check(ts: TestSet) -> None:
    """Every class, problem, family parameter and level of ``ts`` is valid."""
    registry = problems()
    for cls, levels in ts.classes.items():
        check_class(cls)
        for problem, lv in levels.items():
            if problem not in registry or registry[problem].kind != "contact":
                raise TestSetError(f"test set {ts.id} 'classes.{cls}.{problem}': not a "
                                   "registered contact problem")
            _check_levels(ts, f"classes.{cls}.{problem}", registry[problem], lv)
    for fam, entry in ts.families.items():
        unknown = sorted(set(entry) - set(FAMILY_KEYS))
        if unknown:
            raise TestSetError(f"test set {ts.id} 'families.{fam}': keys {unknown} are not "
                               f"allowed; allowed: {', '.join(FAMILY_KEYS)}")
        wrong = contact_scene_error(entry.get("problem"), entry.get("params"))
        if wrong is not None:
            raise TestSetError(f"test set {ts.id} 'families.{fam}.{wrong[0]}': {wrong[1]}")
        try:
            family_steps(registry[entry["problem"]].options(**(entry.get("params") or {})),
                         step_choice(entry))
        except ValueError as err:
            raise TestSetError(f"test set {ts.id} 'families.{fam}.step': {err}") from None
        if entry.get("levels") is not None:
            if not isinstance(entry["levels"], dict):
                raise TestSetError(f"test set {ts.id} 'families.{fam}.levels': "
                                   f"{entry['levels']!r} is not allowed; allowed: a mapping "
                                   f"size class -> levels ({', '.join(CLASSES)})")
            for cls, lv in entry["levels"].items():
                if cls not in CLASSES:
                    raise TestSetError(f"test set {ts.id} 'families.{fam}.levels': size class "
                                       f"{cls!r} is not allowed; allowed: {', '.join(CLASSES)}")
                _check_levels(ts, f"families.{fam}.levels.{cls}", registry[entry["problem"]],
                              lv)


def _check_levels(ts: TestSet, key: str, spec, levels) -> None:
    """``levels`` (at ``key`` of the set) are in the range of the problem ``spec``."""
    lo, hi = spec.levels
    bad = [x for x in levels or [] if not (isinstance(x, int) and lo <= x <= hi)]
    if bad:
        raise TestSetError(f"test set {ts.id} '{key}': levels {bad} are not allowed; "
                           f"allowed: integers {lo}..{hi}")


def step_choice(entry: dict) -> str:
    """A family's ``step`` (:data:`STEP_CHOICES`; ``last`` where its entry names none)."""
    return entry.get("step", STEP_CHOICES[0])


def family_steps(options, step) -> list:
    """The tangential steps a family's problems are (``[None]`` without friction): ``step``
    ``last`` (``[shift_steps]``), ``all`` (``1 .. shift_steps``) or one step number.

    Raises
    ------
    ValueError
        A ``step`` on a frictionless family, or one outside the allowed values.
    """
    frictional = options.get("friction", "none") != "none"
    if not frictional:
        if step != "last":
            raise ValueError(f"{step!r} is not allowed without friction; allowed: no step "
                             "(a frictionless family is one problem per level)")
        return [None]
    count = int(options["shift_steps"])
    if step == "last":
        return [count]
    if step == "all":
        return list(range(1, count + 1))
    if isinstance(step, int) and not isinstance(step, bool) and 1 <= step <= count:
        return [step]
    raise ValueError(f"{step!r} is not allowed; allowed: {', '.join(STEP_CHOICES)} or an "
                     f"integer 1..{count} (shift_steps)")


def definition_digits(v: np.ndarray, digits: int = DEFINITION_DIGITS) -> np.ndarray:
    """``v`` rounded to ``digits`` significant digits of its largest entry (one decimal
    grid for the whole vector, so round-off noise on its near-zero entries goes too).

    A frictional step's slip bounds and previous state come out of reference solves of
    the earlier steps (and of Coulomb's fixed point); their last digits depend on the
    machine (BLAS kernel, summation order). Rounded to 8 of their about 13 reliable
    digits, two machines define the same problem, unless an entry lies within the
    solves' round-off of a rounding boundary (about 1e-5 per entry)."""
    v = np.asarray(v, dtype=float)
    top = float(np.max(np.abs(v), initial=0.0))
    if top == 0.0:
        return np.zeros_like(v)
    decimals = digits - 1 - int(np.floor(np.log10(top)))
    return np.round(v, decimals) + 0.0          # + 0.0: no negative zeros


@dataclass(frozen=True)
class FrictionStep:
    """One tangential step of a frictional scene's load path as a test problem.

    Attributes
    ----------
    qp : ContactQP
        The Tresca step (``friction.law`` ``tresca`` also on a Coulomb path, ``mu`` the
        path's): the scene's data of the step, slip bounds ``s`` and previous state
        rounded by :func:`definition_digits`.
    solution : TrescaSolution
        Its exact reference (:func:`solvers.kernels.tresca.tresca_exact`).
    warm : TrescaSolution
        The previous step's reference solution (the first tangential step's: the normal
        step's), the step's recorded warm start.
    step, steps : int
        This tangential step (from 1) and the path's number of them.
    ratio : float
        ``Q / (mu P)`` of the reference solution (:func:`solvers.kernels.tresca.tangential_ratio`).
    fixed_point : dict or None
        Coulomb: the fixed point ``s = mu p`` of the step (its Tresca solves, last change
        and contraction, and ``max |mu p - s| / max s`` of the rounded bound's reference).
    """

    qp: object
    solution: object
    warm: object
    step: int
    steps: int
    ratio: float
    fixed_point: dict | None


@lru_cache(maxsize=8)
def frictional_steps(problem: str, params: tuple, level: int,
                     digits: int = DEFINITION_DIGITS,
                     perturb: float = 0.0) -> dict[int, FrictionStep]:
    """The tangential steps of a frictional scene's load path as test problems (cached).

    The path is :func:`solvers.kernels.tresca.friction_path`'s, with the exact reference (``A``
    factorised once) on the rounded definitions (its ``define``): the normal step's slip
    bounds ``s = mu p`` (Tresca; Coulomb: the fixed point ``s = mu p`` of each step,
    :func:`solvers.kernels.tresca.coulomb_step`, to 1e-12) and each step's previous state
    ``T u + offset`` of the step before are rounded by :func:`definition_digits` before
    the step is solved, so each step's problem and its warm start are exactly the
    previous exported problem's reference. ``perturb`` (tests only) multiplies every
    reference solution by ``1 + perturb`` before its quantities are rounded.

    Returns
    -------
    dict
        Tangential step (1 .. ``shift_steps``) -> :class:`FrictionStep`.
    """
    from solvers.kernels.tresca import (PathStep, dual_operators, friction_path, tangential_ratio,
                                        tresca_exact)

    spec = problems()[problem]
    qp = spec.build(level, spec.options(**dict(params)))
    fr = qp.friction
    ops = dual_operators(qp)

    def solve(step_qp):
        sol = tresca_exact(step_qp, ops)
        if sol.status != "converged":
            raise RuntimeError(f"the exact reference stopped on {qp.name}: {sol.status}")
        return replace(sol, u=sol.u * (1 + perturb), p=sol.p * (1 + perturb))

    path = friction_path(qp, solve, tol=1e-12, define=lambda v: definition_digits(v, digits))
    out = {}
    for k in range(1, len(path)):
        done, sol = path[k], path[k].solution
        # the problem is a Tresca step whatever the path's law (Coulomb's: the fixed
        # point's final step, its bound s given): no solver re-runs the fixed point on it
        step_qp = replace(done.qp, friction=replace(done.qp.friction, law="tresca"))
        fixed_point = None
        if fr.law == "coulomb":
            s = step_qp.friction.slip_bound
            fixed_point = {"tresca_solves": done.tresca_solves, "last_change": done.history[-1],
                           "contraction": done.contraction, "status": sol.status,
                           "residual": float(np.max(np.abs(fr.mu * sol.p - s), initial=0.0))
                           / max(float(np.max(s, initial=0.0)), 1e-300)}
        out[k] = FrictionStep(qp=step_qp, solution=sol, warm=path[k - 1].solution, step=k,
                              steps=len(fr.path) - 1,
                              ratio=tangential_ratio([PathStep(step_qp, sol)]),
                              fixed_point=fixed_point)
    return out
