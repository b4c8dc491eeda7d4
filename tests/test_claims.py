"""Claims declared as data (report/claims.py)."""
from __future__ import annotations

import importlib
import inspect
import math
import pkgutil

import pytest

import report
from report.claims import NO_BAR, NO_RUN, NOT_REACHED, TITLE_MAX, UNJUDGED, Claim


@pytest.mark.parametrize("compare, bar, measured, verdict", [
    ("<=", 0.15, 0.15, True), ("<=", 0.15, 0.16, False), ("<=", 0.15, math.nan, False),
    (">=", 3.0, 3.0, True), (">=", 3.0, 2.9, False), ("<", 1e-8, 1e-8, False),
    (">", 0.25, 0.3, True), ("|<=|", 0.05, -0.04, True), ("|<=|", 0.05, -0.06, False),
    ("in", (1.5, 2.6), 2.0, True), ("in", (1.5, 2.6), 2.7, False)])
def test_a_claim_judges_by_its_comparison(compare, bar, measured, verdict):
    row = Claim("Lemma 8.13", "ratio at level {level}", compare, bar).row(measured, level=3)
    assert row["pass"] is verdict and row["claim"] == "ratio at level 3"
    assert row["thesis"] == "Lemma 8.13" and row["measured"] is measured


def test_bars_read_as_before_and_unjudged_rows_have_no_verdict():
    assert Claim("x", "q", "<=", 0.15).bar_text() == 0.15        # a plain number, as tables had
    assert Claim("x", "q", "in", (1.5, 2.6)).bar_text() == "[1.5, 2.6]"
    assert Claim("x", "q", ">=", 0.45).bar_text() == ">= 0.45"
    assert Claim("x", "q", "|<=|", 0.05).bar_text() == "|.| <= 0.05"
    assert Claim("x", "q").row(2.0) == {"claim": "q", "scene": "", "level": "", "parameters": "",
                                        "thesis": "x", "measured": 2.0, "bar": "-",
                                        "pass": None, "reason": NO_BAR}
    assert Claim("x", "q", "<=", 1.0).row(5.0, judged=False)["pass"] is None
    given = Claim("x", "q", "given", "all")
    assert given.row("3 of 3", passed=True)["pass"] is True and given.bar_text() == "all"
    with pytest.raises(ValueError, match="needs 'passed'"):
        given.row("3 of 3")


def test_every_unjudged_row_gives_its_reason_and_a_judged_row_none():
    assert Claim("x", "q", unjudged="no published bar").row(2.0)["reason"] == "no published bar"
    coarse = Claim("x", "q at {n}", "<=", 1.0).row(0.5, judged=False, n=3,
                                                   reason="{n} cells: too coarse")
    assert coarse["pass"] is None and coarse["reason"] == "3 cells: too coarse"
    assert Claim("x", "q", "<=", 1.0).row(5.0, judged=False)["reason"] == NOT_REACHED
    assert Claim("x", "q", "<=", 1.0).row(0.5, reason="unused")["reason"] == ""
    assert Claim("x", "q", "given", "all").row("1 of 1", passed=False)["reason"] == ""


def test_every_declared_claim_without_a_bar_says_why():
    for module in _report_modules():
        for key, claim in module.CLAIMS.items():
            if claim.compare == UNJUDGED:
                assert len(claim.unjudged) > 10, f"{module.__name__}: {key}"


def _declared():
    """Every declared claim of the report modules: ``(module, key, claim)``."""
    for info in pkgutil.iter_modules(report.__path__):
        module = importlib.import_module(f"report.{info.name}")
        for table in ("CLAIMS", "BOARD_CLAIMS"):
            for key, claim in getattr(module, table, {}).items():
                if isinstance(claim, Claim):
                    yield module.__name__, key, claim


def test_every_declared_title_reads_as_one_short_line():
    """A title filled with 30-character names stays within TITLE_MAX; the scene, the
    level, the size and the load ratio are the columns', never the title's."""
    import re
    declared = list(_declared())
    assert len(declared) > 60
    for name, key, claim in declared:
        filled = re.sub(r"\{\w+(:[^}]*)?\}", "x" * 30, claim.title)
        assert len(filled) <= TITLE_MAX, (name, key, filled)
        assert not re.search(r"\{(scene|level|levels|N|ratio|coarser)\b", claim.title), (name, key)


def test_a_row_puts_scene_level_and_conditions_in_columns_of_their_own():
    claim = Claim("Lemma 8.13", "ratio of {what}", "<=", 2.0, details="Q/(mu P) = {ratio:g}")
    row = claim.row(1.5, scene="circle_square", level=3, ratio=0.3, what="kappa")
    assert (row["claim"], row["scene"], row["level"], row["parameters"]) == (
        "ratio of kappa", "circle_square", "3", "Q/(mu P) = 0.3")
    growth = Claim("x", "growth", level="{coarser} -> {level}").row(1.1, level=3, coarser=2)
    assert growth["level"] == "2 -> 3" and growth["parameters"] == ""
    none = claim.absent("one level only", scene="s", what="kappa")
    assert none["pass"] is None and none["reason"] == f"{NO_RUN}: one level only"
    assert (none["level"], none["parameters"]) == ("", "") and math.isnan(none["measured"])


def test_a_claim_names_a_wrong_declaration():
    with pytest.raises(ValueError, match="parameter 'compare': '=<' is not allowed"):
        Claim("x", "q", "=<", 1.0)
    with pytest.raises(ValueError, match="parameter 'bar'"):
        Claim("x", "q", "<=")
    with pytest.raises(ValueError, match="parameter 'bar'"):
        Claim("x", "q", "-", 1.0)


def _report_modules():
    for info in pkgutil.iter_modules(report.__path__):
        module = importlib.import_module(f"report.{info.name}")
        if hasattr(module, "claims") and inspect.isfunction(module.claims):
            yield module


def test_every_study_declares_its_claims_in_one_place():
    """Each report module that measures claims declares them in ``CLAIMS`` (thesis item,
    quantity, comparison, bar) and builds its rows only through them."""
    modules = list(_report_modules())
    assert {m.__name__ for m in modules} >= {
        "report.laplace_nonmatching", "report.contact_solution", "report.augmented_projection", "report.adaptive",
        "report.exact_reference", "report.hard_cases",
        "report.roll_stack", "report.element_order", "report.test_set"}
    for module in modules:
        assert module.CLAIMS and all(isinstance(c, Claim) and c.thesis and c.title
                                     for c in module.CLAIMS.values()), module.__name__
        assert '"claim":' not in inspect.getsource(module), module.__name__


@pytest.mark.parametrize("dim, N, verdict", [(2, 65_926, True), (3, 135_102, False),
                                             (3, 18_360, None)])
def test_tnnmg_time_bars_are_judged_at_the_sizes_they_are_set_for(dim, N, verdict):
    """Alg. 8.4's study: TNNMG's time over the fastest multigrid-PCG floor at the finest
    level is judged from TNNMG_TIME_MIN_N unknowns on (2x in 2D, 2.5x in 3D), reported with
    the reason below."""
    import pandas as pd

    from report.augmented_projection import TNNMG_TIME_MIN_N, tnnmg_claims

    ratio = 1.8 if verdict is not False else 2.6
    study = pd.DataFrame([{"config": c, "level": 3, "N": N, "dim": dim, "n_to_target": 10,
                           "t_to_target": t}
                          for c, t in (("tnnmg", ratio), ("amg_pcg_gmg", 1.0))])
    row = next(r for r in tnnmg_claims(study) if "time to the energy-error target" in r["claim"])
    assert row["measured"] == pytest.approx(ratio) and row["pass"] is verdict
    assert verdict is not None or f"{TNNMG_TIME_MIN_N[dim]:,}" in row["reason"]
