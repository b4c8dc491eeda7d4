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
leaves out has none of its problems). The
families are also the workflow's scenes (:func:`workflows.studies.scenes_with_families`),
so a hard case or a scene variant is typed once. Loading checks every name,
problem, parameter and level (:class:`TestSetError` names the key and what is
allowed); nothing here builds a problem.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from problems.spec import contact_scene_error, problems

#: Where the sets live, and the one ``contactbench export`` uses by default.
SETS_DIR = Path(__file__).resolve().parent / "config" / "test_sets"
CURRENT = "contact-qp-4"
#: Size classes, smallest first.
CLASSES = ("small", "medium", "large")


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
    """

    name: str
    family: str
    problem: str
    params: dict
    level: int
    size_class: str

    def build(self):
        """The :class:`problems.qp.ContactQP` (the registered problem's ``build``)."""
        spec = problems()[self.problem]
        return spec.build(self.level, spec.options(**self.params))


@dataclass(frozen=True)
class TestSet:
    """A loaded test set (see the module docstring)."""

    __test__ = False

    name: str
    version: int
    description: str
    classes: dict = field(repr=False)
    families: dict = field(repr=False)

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
            for cls in CLASSES if size_class is None else (size_class,):
                for level in self.levels(fam, cls):
                    out.append(SetProblem(f"{fam}_L{level}", fam, entry["problem"],
                                          dict(entry.get("params") or {}), int(level), cls))
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


def load(name: str = CURRENT) -> TestSet:
    """The test set ``name`` (a file stem under :data:`SETS_DIR`), checked.

    Raises
    ------
    TestSetError
        An unknown set name, or a definition that names an unknown problem,
        parameter, level or class.
    """
    names = available()
    if name not in names:
        raise TestSetError(f"test set {name!r} is not allowed; allowed: {', '.join(names)}")
    with open(SETS_DIR / f"{name}.yaml", encoding="utf-8") as fh:
        raw = yaml.safe_load(fh)
    ts = TestSet(name=str(raw["name"]), version=int(raw["version"]),
                 description=" ".join(str(raw.get("description", "")).split()),
                 classes=dict(raw.get("classes") or {}), families=dict(raw["families"]))
    if ts.id != name:
        raise TestSetError(f"test set file {name}.yaml declares name-version {ts.id!r}; "
                           f"allowed: {name!r}")
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
        unknown = sorted(set(entry) - {"problem", "params", "levels"})
        if unknown:
            raise TestSetError(f"test set {ts.id} 'families.{fam}': keys {unknown} are not "
                               "allowed; allowed: problem, params, levels")
        wrong = contact_scene_error(entry.get("problem"), entry.get("params"))
        if wrong is not None:
            raise TestSetError(f"test set {ts.id} 'families.{fam}.{wrong[0]}': {wrong[1]}")
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
