"""Checked claims declared as data.

Every study's report module declares its claims once, at its top, as a ``CLAIMS`` dict
of :class:`Claim`: where the claim comes from (the thesis's item, a published result, or
"suite bar" with the reason the bar is what it is), a short title saying what is
measured, the conditions of the measurement (a text template), the comparison and the
bar. Its ``claims()`` function only measures and calls :meth:`Claim.row`, which puts the
title, the scene, the level and the conditions in columns of their own; the summary page
(``report/summary.py``) collects the rows, and ``tests/test_claims.py`` checks that
every row comes from a declared claim and that every title reads as one short line.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass
from typing import Any

#: The comparisons a claim can make: measured ``compare`` bar.
COMPARE = {
    "<=": operator.le, ">=": operator.ge, "<": operator.lt, ">": operator.gt,
    "|<=|": lambda x, bar: abs(x) <= bar,
    "in": lambda x, bar: bar[0] <= x <= bar[1],
}
#: Comparisons without a numeric rule: ``"-"`` reported without a bar; ``"given"`` judged
#: by the measuring code (two measured values against each other, "all runs converged"),
#: the bar a sentence.
UNJUDGED, GIVEN = "-", "given"
#: The reason shown for an unjudged row when its claim or its measuring code gives none.
NO_BAR = "a measured figure reported for reference: the thesis sets no bar for it"
NOT_REACHED = "this scale does not reach the size or resolution the bar is about"
#: The reason of a claim this run measured nothing for begins so (:meth:`Claim.absent`).
NO_RUN = "no run at this scale"
#: The columns of a claims table.
COLUMNS = ["claim", "scene", "level", "parameters", "thesis", "measured", "bar", "pass",
           "reason"]
#: The longest a claim's title may read (characters, formatted): one line of the summary.
TITLE_MAX = 100


@dataclass(frozen=True)
class Claim:
    """One checkable claim of a study.

    Attributes
    ----------
    thesis : str
        Where it comes from: the thesis's item ("Sect. 6.2", "Lemma 8.13"), a published
        result, or "suite bar" with the one-line reason the bar is what it is
        ("suite bar (TNNMG: close to one linear solve)").
    title : str
        What is measured, in at most :data:`TITLE_MAX` characters: a template formatted
        with the row's fields (``"H1 rate of the {coupling} coupling"``). The scene and
        the level have columns of their own and stay out of it.
    compare : str
        One of :data:`COMPARE`, :data:`UNJUDGED` or :data:`GIVEN`.
    bar : float, (lo, hi), str or None
        The bar: a number, an interval for ``"in"``, a sentence for ``"given"``.
    unjudged : str
        Why a claim without a bar (``compare`` ``"-"``) is reported but not judged;
        the summary shows it in place of a verdict.
    details : str
        The conditions of the measurement (a template like ``title``): the row's
        ``parameters`` column.
    level : str
        The row's ``level`` column as a template (``"{coarser} -> {level}"``); empty: the
        field ``level`` or ``levels``, if the row has one.
    """

    thesis: str
    title: str
    compare: str = UNJUDGED
    bar: Any = None
    unjudged: str = ""
    details: str = ""
    level: str = ""

    def __post_init__(self):
        allowed = (*COMPARE, UNJUDGED, GIVEN)
        if self.compare not in allowed:
            raise ValueError(f"parameter 'compare': {self.compare!r} is not allowed; allowed: "
                             f"{', '.join(allowed)}")
        if (self.compare == UNJUDGED) != (self.bar is None):
            raise ValueError("parameter 'bar': a claim without a bar has compare '-', and "
                             "only such a claim has no bar")

    def bar_text(self):
        """The bar as the claims tables show it (a plain number for ``<=``)."""
        if self.compare == UNJUDGED:
            return "-"
        if self.compare == "<=" or self.compare == GIVEN:
            return self.bar
        if self.compare == "in":
            return f"[{self.bar[0]:g}, {self.bar[1]:g}]"
        if self.compare == "|<=|":
            return f"|.| <= {self.bar:g}"
        return f"{self.compare} {self.bar:g}"

    def row(self, measured, judged: bool = True, passed: bool | None = None,
            reason: str = "", **fields) -> dict:
        """The claims-table row (:data:`COLUMNS`): the title, the scene (the field
        ``scene``, if given), the level, the conditions, the source, measured, bar, pass,
        reason.

        ``judged=False``: this scale does not reach what the bar is about (pass empty);
        ``reason`` says what it lacks (:data:`NOT_REACHED` if not given). ``passed``: the
        verdict of a ``"given"`` claim (its measuring code decides). ``reason`` is empty
        for a judged row.
        """
        if self.compare == GIVEN:
            if judged and passed is None:
                raise ValueError(f"claim {self.title!r}: a 'given' claim needs 'passed'")
            verdict = bool(passed) if judged else None
        elif self.compare == UNJUDGED or not judged:
            verdict = None
        else:
            x = float(measured)
            verdict = bool(math.isfinite(x) and COMPARE[self.compare](x, self.bar))
        if verdict is not None:
            why = ""
        elif self.compare == UNJUDGED:
            why = self.unjudged or NO_BAR
        else:
            why = reason.format(**fields) if reason else NOT_REACHED
        return {"claim": self.title.format(**fields), "scene": str(fields.get("scene", "")),
                "level": self.level_text(fields),
                "parameters": self.details.format(**fields), "thesis": self.thesis,
                "measured": measured, "bar": self.bar_text(), "pass": verdict, "reason": why}

    def absent(self, reason: str, **fields) -> dict:
        """The one row of a claim this run measured nothing for: its title (formatted with
        ``fields``), the scene, no level, conditions or value, not judged, ``reason`` (why
        nothing was measured, prefixed by :data:`NO_RUN`)."""
        return {"claim": self.title.format(**fields), "scene": str(fields.get("scene", "")),
                "level": "", "parameters": "", "thesis": self.thesis, "measured": math.nan,
                "bar": self.bar_text(), "pass": None, "reason": f"{NO_RUN}: {reason}"}

    def level_text(self, fields: dict) -> str:
        """The row's ``level`` column: :attr:`level` formatted, else the field ``level``
        or ``levels``, else empty."""
        if self.level:
            return self.level.format(**fields)
        return str(fields.get("level", fields.get("levels", "")))
