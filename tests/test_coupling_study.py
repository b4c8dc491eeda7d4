"""The coupling study at tiny levels: the script and the report builder end to end, the
claims table, the measured errors, the figures, and the script's argument checks."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from report import coupling as report
from workflows.io import read_csv
from workflows.scripts import coupling as script
from workflows.studies import ConfigError, check_config, load_config

ROOT = Path(__file__).resolve().parent.parent

COUPLINGS = ["nodal", "stabilised", "mortar", "mortar_dual"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """circle_square levels 0 and 1 against a mortar_dual reference at level 2, and the
    report's outputs."""
    d = tmp_path_factory.mktemp("coupling")
    table = d / "results" / "circle_square" / "coupling.csv"
    script.main(["--problem", "circle_square", "--levels", "0", "1", "--reference-level", "2",
                 "--out", str(table)])
    out = {"claims": d / "claims.csv", "figure": d / "coupling.png",
           "hertz": d / "coupling_hertz.png"}
    report.main(["--tables", str(table), "--claims", str(out["claims"]),
                 "--figure", str(out["figure"]), "--hertz-figure", str(out["hertz"])])
    return read_csv(table), out


def test_every_solve_is_exact_and_verified(run):
    t, _ = run
    ref = t[t.role == "reference"]
    assert len(ref) == 1 and ref.coupling.iloc[0] == "mortar_dual" and ref.level.iloc[0] == 2
    c = t[t.role == "compared"]
    assert sorted(zip(c.coupling, c.level)) == sorted((k, lv) for k in COUPLINGS for lv in (0, 1))
    assert (t.status == "converged").all() and (t.solver == "pdas").all()
    assert (t.kkt_max < 1e-8).all()                   # the 'high' preset's verified residuals


def test_the_errors_against_the_reference_are_measured_and_fall(run):
    t, _ = run
    c = t[t.role == "compared"].set_index(["coupling", "level"])
    for k in COUPLINGS:
        e0, e1 = c.loc[(k, 0), "err_energy"], c.loc[(k, 1), "err_energy"]
        assert 0 < e1 < e0 < 1, (k, e0, e1)
    # the dual mortar, the reference's coupling: the nested difference falls about as h
    # (measured 0.222 -> 0.113 from level 0 to 1, ratio 0.51; O(h) would give 0.5)
    e0, e1 = c.loc[("mortar_dual", 0), "err_energy"], c.loc[("mortar_dual", 1), "err_energy"]
    assert 0.3 < e1 / e0 < 0.75, (e0, e1)
    # Hertz: every coupling's half-width and peak within 30 % at these coarse levels
    for k in COUPLINGS:
        row = c.loc[(k, 1)]
        assert abs(row.a_moment / row.a_hertz - 1) < 0.3 and abs(row.p0_moment / row.p0_hertz - 1) < 0.3
        assert 0 < row.err_force < 0.05 and 0 < row.dev_hertz_rms < 0.5


def test_the_claims_table_has_every_claim_with_a_status_or_a_reason(run):
    _, out = run
    claims = read_csv(out["claims"])
    assert list(claims.columns) == ["claim", "thesis", "measured", "bar", "pass", "reason"]
    first = claims.iloc[0]
    assert "converged" in first.claim and first.measured == "9 of 9" and first["pass"] == True  # noqa: E712
    for _, row in claims.iterrows():
        judged = isinstance(row["pass"], (bool, np.bool_)) or str(row["pass"]) in ("True", "False")
        assert judged or (isinstance(row.reason, str) and len(row.reason) > 10), row.to_dict()
    # two levels: the mortar rates (three levels) are not judged here and say why
    mortar = claims[claims.claim.str.contains("mortar") & claims.claim.str.contains("rate")]
    assert len(mortar) == 2 and mortar.reason.str.contains("needs 3 levels").all()
    assert {"nodal", "stabilised"} <= {w for c in claims.claim for w in c.replace(":", " ").split()}


def test_the_mortar_rate_is_judged_against_the_optimal_rate():
    """Three levels of a made-up table: the fitted slope against the optimal -1/2 in 2D."""
    N = np.array([1000.0, 4000.0, 16000.0])
    rows = [{"scene": "s", "role": "reference", "coupling": "mortar_dual", "level": 5,
             "dim": 2, "N": 64000, "status": "converged"}]
    for k, r in (("mortar_dual", -0.55), ("mortar", -0.3), ("nodal", -0.25)):
        rows += [{"scene": "s", "role": "compared", "coupling": k, "level": lv, "dim": 2,
                  "N": n, "status": "converged", "err_energy": n ** r}
                 for lv, n in enumerate(N)]
    claims = report.claims(pd.DataFrame(rows)).set_index("claim")
    dual = claims.loc[[c for c in claims.index if "mortar_dual energy" in c][0]]
    std = claims.loc[[c for c in claims.index if "mortar energy" in c][0]]
    nodal = claims.loc[[c for c in claims.index if "nodal energy" in c][0]]
    assert math.isclose(dual.measured, -0.05, abs_tol=1e-12) and dual["pass"] is True
    assert math.isclose(std.measured, 0.2, abs_tol=1e-12) and std["pass"] is False
    assert math.isclose(nodal.measured, -0.25, abs_tol=1e-12) and nodal["pass"] is None


def test_the_figures_decode(run):
    _, out = run
    for key in ("figure", "hertz"):
        with Image.open(out[key]) as im:
            im.load()
            assert im.size[0] > 300 and im.size[1] > 200


@pytest.mark.parametrize("argv, message", [
    (["--levels", "0", "1", "--reference-level", "2", "--set", "coupling=nodal"],
     "argument --set: 'coupling' is not allowed"),
    (["--levels", "0", "1", "--reference-level", "2", "--couplings", "glued"],
     "argument --couplings: glued is not allowed"),
    (["--levels", "0", "1", "--reference-level", "1"],
     "argument --reference-level: 1 is not allowed"),
])
def test_bad_arguments_are_refused_naming_the_argument(argv, message, tmp_path, capsys):
    out = tmp_path / "x.csv"
    with pytest.raises(SystemExit) as err:
        script.main(["--problem", "circle_square", *argv, "--out", str(out)])
    assert err.value.code == 2 and message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("change, needle", [
    (lambda c: c["coupling"]["reference_level"].update(circle_square=2),
     "'coupling.reference_level.circle_square': 2 is not allowed; allowed: a level in 3.."),
    (lambda c: c["coupling"]["reference_level"].update(ghost=2),
     "'coupling.reference_level.ghost': not among coupling.scenes"),
    (lambda c: (c["scenes"].update(rolls={"problem": "roll_stack"}),
                c["coupling"]["scenes"].update(rolls=[0]),
                c["coupling"]["reference_level"].update(rolls=1)),
     "'coupling.scenes.rolls': problem 'roll_stack' does not offer the couplings"),
    (lambda c: (c["scenes"].update(cs_mortar={"problem": "circle_square",
                                              "params": {"coupling": "mortar"}}),
                c["coupling"]["scenes"].update(cs_mortar=[0]),
                c["coupling"]["reference_level"].update(cs_mortar=1)),
     "'coupling.scenes.cs_mortar': the scene sets 'coupling'"),
])
def test_config_errors_name_the_key(change, needle):
    config = load_config(ROOT / "workflows/config/quick.yaml")
    change(config)
    with pytest.raises(ConfigError, match=re.escape(needle)):
        check_config(config)
