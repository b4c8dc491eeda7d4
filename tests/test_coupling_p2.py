"""The coupling study's P2 rows (``--orders 1 2``): on circle_square level 0 against P2
level 1, the rows of every coupling the scene takes at P2 with order 2, the stabilised
coupling skipped with its reason, the P1 rows as without P2; the P2 comparison against an
independent computation of the energy error; cube-sphere's dual P2 refused as a reason,
not a crash; the config's orders and P2 reference; the report's P2 claims and styles."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from report import coupling as report
from workflows.io import read_csv
from workflows.studies.coupling import run as script
from workflows.studies import ConfigError, check_config, load_config
from workflows.studies.coupling import coupling_args

ROOT = Path(__file__).resolve().parent.parent
P2_COUPLINGS = ["nodal", "mortar", "mortar_dual"]
#: The columns a P1 row has whatever the orders (its measured values; not the time).
MEASURED = ["coupling", "level", "N", "n", "NC", "status", "kkt_max", "err_energy",
            "err_force", "err_pressure", "err_pressure_dual", "a_moment", "p0_moment",
            "dev_hertz_rms"]


def _run(tmp, name, *extra):
    out = tmp / "results" / "circle_square" / f"{name}.csv"
    script.main(["--problem", "circle_square", "--levels", "0", "--reference-level", "1",
                 *extra, "--out", str(out)])
    return read_csv(out)


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    """circle_square level 0 against level 1, P1 alone and P1 with P2."""
    d = tmp_path_factory.mktemp("coupling_p2")
    return (_run(d, "p1"),
            _run(d, "both", "--orders", "1", "2", "--p2-reference-level", "1"))


def test_the_p2_rows_exist_with_order_2_and_stabilised_is_skipped(tables):
    _, t = tables
    ref = t[(t.role == "reference") & (t.order == 2)]
    assert len(ref) == 1 and ref.coupling.iloc[0] == "mortar_dual"
    assert ref.level.iloc[0] == 1 and ref.status.iloc[0] == "converged"
    p2 = t[(t.role == "compared") & (t.order == 2)].set_index("coupling")
    assert sorted(p2.index) == sorted([*P2_COUPLINGS, "stabilised"])
    assert (p2.loc[P2_COUPLINGS, "status"] == "converged").all()
    assert (p2.loc[P2_COUPLINGS, "kkt_max"] < 1e-8).all()
    # the P2 rows run on the P2 mesh: level 0 at P2 has the nodes of P1 at level 1 (the
    # P1 reference here)
    ref1 = t[(t.role == "reference") & (t.order == 1)]
    assert (p2.loc[P2_COUPLINGS, "N"] == int(ref1.N.iloc[0])).all()
    skipped = p2.loc["stabilised"]
    assert skipped.status == "skipped" and "built for P1" in skipped.reason
    assert not np.isfinite(skipped.get("err_energy", np.nan))


def test_the_p2_errors_are_measured_and_smaller_than_p1_on_the_same_mesh(tables):
    """Against a reference one level finer of its own order, P2 on level 0's mesh is
    closer than P1 (measured 0.04-0.05 against 0.11); the P2 pressure (recovered from the
    forces) is compared, its dual-norm error is P1 only."""
    _, t = tables
    c = t[t.role == "compared"].set_index(["coupling", "order"])
    for k in P2_COUPLINGS:
        e1, e2 = c.loc[(k, 1), "err_energy"], c.loc[(k, 2), "err_energy"]
        assert 0 < e2 < 0.6 * e1 < 1, (k, e1, e2)
        assert 0 < c.loc[(k, 2), "err_pressure"] < 1 and 0 <= c.loc[(k, 2), "err_force"] < 0.05
        assert np.isnan(c.loc[(k, 2), "err_pressure_dual"])
        assert np.isfinite(c.loc[(k, 1), "err_pressure_dual"])
        assert abs(c.loc[(k, 2), "a_moment"] / c.loc[(k, 2), "a_hertz"] - 1) < 0.3


def test_the_p1_rows_are_the_same_with_and_without_p2(tables):
    p1, both = tables
    a = p1[p1.role == "compared"].sort_values("coupling").reset_index(drop=True)
    b = both[(both.role == "compared") & (both.order == 1)]
    b = b.sort_values("coupling").reset_index(drop=True)
    assert (a.order == 1).all() and len(a) == 4
    pd.testing.assert_frame_equal(a[MEASURED], b[MEASURED], check_dtype=False)   # N: NaN in
    # the table with P2 (its skipped rows), so float there


def test_the_p2_energy_error_is_the_element_order_studys():
    """The P2 comparison (P2 field at the reference's P2 nodes, the reference's P2
    stiffness) against :mod:`workflows.studies.element_order.run`'s, built apart; 0 for the
    reference itself."""
    from problems.spec import problems
    from workflows.studies.element_order import run as eo
    from workflows.reference_solution import Reference

    spec = problems()["circle_square"]
    qp0, qp1 = (spec.make(level, degree=2, coupling="mortar") for level in (0, 1))
    (r0, _), (r1, _) = script.exact(qp0), script.exact(qp1)
    ref = Reference(qp1, r1.u, r1.p, {"solver": r1.solver, "status": r1.status, "t_solve": 0})
    assert ref.compare(qp1, r1.u, r1.p)["err_energy"] < 1e-12
    measured = ref.compare(qp0, r0.u, r0.p)["err_energy"]
    independent = eo.energy_error(qp0, r0.u, qp1, qp1.full_displacement(r1.u).ravel(),
                                  eo._full_stiffness(qp1))
    assert 0.01 < measured < 1 and abs(measured / independent - 1) < 1e-10


def test_cube_sphere_refuses_the_dual_p2_basis_with_its_reason():
    """In 3D the dual basis of the P2 trace does not exist: the study skips the coupling
    with the scene's reason (no solve), as it skips the P1-only stabilised one."""
    from problems.spec import problems

    spec = problems()["cube_sphere"]
    out = script.refused(spec, {}, ["nodal", "stabilised", "mortar", "mortar_dual"], 0, 2)
    assert sorted(out) == ["mortar_dual", "stabilised"]
    assert "vertex hats integrate to zero" in out["mortar_dual"]
    assert script.refused(spec, {}, ["mortar_dual", "stabilised"], 0, 1) == {}


def _config(**coupling):
    config = load_config(ROOT / "workflows/config/quick.yaml")
    config["coupling"].update(coupling)
    return config


def test_the_config_orders_default_and_p2_reference():
    assert "--orders" not in coupling_args(_config(), "circle_square")   # the P1 rows
    assert script.THESIS_ORDER == 1
    config = _config(orders=[1])
    check_config(config)
    assert "--orders 1" in coupling_args(config, "circle_square")
    assert "p2-reference" not in coupling_args(config, "circle_square")
    p2 = {"circle_square": {"level": 3, "coupling": "mortar_dual"},
          "cube_sphere": {"level": 2, "coupling": "mortar"}}
    config = _config(orders=[1, 2], p2_reference=p2)
    check_config(config)
    args = coupling_args(config, "cube_sphere")
    assert "--orders 1 2 --p2-reference-level 2 --p2-reference-coupling mortar" in args


@pytest.mark.parametrize("p2, needle", [
    (None, "'coupling.p2_reference.circle_square': missing"),
    ({"circle_square": {"level": 0, "coupling": "mortar_dual"}},
     "'coupling.p2_reference.circle_square.level': 0 is not allowed; allowed: a level in 1.."),
    ({"circle_square": {"level": 3, "coupling": "mortar_dual"},
      "cube_sphere": {"level": 2, "coupling": "mortar_dual"}},
     "'coupling.p2_reference.cube_sphere.coupling': parameter 'coupling': 'mortar_dual'"),
])
def test_p2_config_errors_name_the_key(p2, needle):
    config = _config(orders=[1, 2], **({"p2_reference": p2} if p2 else {}))
    with pytest.raises(ConfigError, match=re.escape(needle)):
        check_config(config)


@pytest.mark.parametrize("argv, message", [
    (["--orders", "3"], "argument --orders: 3 is not allowed"),
    (["--orders", "1", "2"], "argument --p2-reference-level: required with --orders 2"),
    (["--p2-reference-level", "1"], "argument --p2-reference-level: not allowed without"),
    (["--orders", "2", "--p2-reference-level", "0"],
     "argument --p2-reference-level: 0 is not allowed"),
    (["--set", "degree=2"], "argument --set: 'degree' is not allowed"),
])
def test_bad_order_arguments_are_refused_naming_the_argument(argv, message, tmp_path, capsys):
    out = tmp_path / "x.csv"
    with pytest.raises(SystemExit) as err:
        script.main(["--problem", "circle_square", "--levels", "0", "--reference-level", "1",
                     *argv, "--out", str(out)])
    assert err.value.code == 2 and message in capsys.readouterr().err
    assert not out.exists()


def test_the_p2_claims_report_the_rate_beside_the_optimal_and_the_skipped_reason():
    """Three P2 levels of a made-up 2D table: the fitted rate reported (not judged)
    beside the optimal -3/4; a skipped row as a claim with its reason; the converged count
    leaves the skipped rows out; the P1 mortar rate still judged."""
    N = np.array([1000.0, 4000.0, 16000.0])
    rows = [{"scene": "s", "role": "reference", "coupling": "mortar_dual", "level": 5,
             "order": o, "dim": 2, "N": 64000, "status": "converged"} for o in (1, 2)]
    for order, r in ((1, -0.5), (2, -0.6)):
        rows += [{"scene": "s", "role": "compared", "coupling": "mortar_dual", "level": lv,
                  "order": order, "dim": 2, "N": n, "status": "converged",
                  "err_energy": n ** r, "err_pressure_dual": n ** r if order == 1 else np.nan}
                 for lv, n in enumerate(N)]
    rows.append({"scene": "s", "role": "compared", "coupling": "stabilised", "level": 0,
                 "order": 2, "dim": 2, "status": "skipped", "reason": "built for P1"})
    claims = report.claims(pd.DataFrame(rows)).set_index("claim")
    assert claims.iloc[0].measured == "8 of 8" and claims.iloc[0]["pass"] is True
    p2 = claims.loc[[c for c in claims.index if "mortar_dual: P2 energy-error rate" in c][0]]
    assert math.isclose(p2.measured, -0.6, abs_tol=1e-12) and p2["pass"] is None
    assert "optimal -0.750" in p2.parameters
    skipped = claims.loc["stabilised at P2: not solved"]
    assert skipped.measured == "skipped" and skipped.reason.endswith("built for P1")
    p1 = claims.loc[[c for c in claims.index if "mortar_dual: energy-error rate" in c][0]]
    assert math.isclose(p1.measured, 0.0, abs_tol=1e-12) and p1["pass"] is True
    assert not [c for c in claims.index if "P2 multiplier error" in c]


def test_p2_lines_are_dashed_with_open_markers():
    p1, p2 = report._style("mortar", 1), report._style("mortar", 2)
    assert p1["color"] == p2["color"] and p1["fmt"][0] == p2["fmt"][0]
    assert p1["fmt"].endswith("-") and not p1["fmt"].endswith("--") and "mfc" not in p1
    assert p2["fmt"].endswith("--") and p2["mfc"] == "none"


def test_a_p2_rate_from_too_few_levels_says_so():
    rows = [{"scene": "s", "role": "compared", "coupling": "mortar", "level": lv, "order": 2,
             "dim": 3, "N": n, "status": "converged", "err_energy": 1.0 / n}
            for lv, n in enumerate((2691.0, 18360.0))]
    claims = report.claims(pd.DataFrame(rows))
    p2 = claims[claims.claim.str.contains("mortar: P2 energy-error rate")].iloc[0]
    assert np.isnan(p2.measured) and p2.reason.startswith("not fitted: needs 3 levels; this run has 2")
    assert "optimal -0.500" in p2.parameters


@pytest.mark.parametrize("name, coupling", [("cube_sphere", "mortar"), ("cube_sphere", "nodal"),
                                            ("circle_square", "mortar_dual")])
def test_the_p2_contact_force_is_the_one_the_rows_transmit(name, coupling):
    """At P2 the study's force (and Hertz's moments) take the normal forces the rows exert
    on the constrained nodes: the multipliers for nodal and dual rows; their total is the
    normal force ``B' p`` exerts on each body, whatever the coupling. The standard mortar
    multipliers in 3D (the modified basis) are no nodal forces: their sum is the force
    (``sum_i c_i m_i = int lambda``), but a vertex's consistent load is zero whatever its
    multiplier."""
    from problems.fem.fields import contact_forces
    from problems.spec import problems

    qp = problems()[name].make(0, degree=2, coupling=coupling)
    res, _ = script.exact(qp)
    full = np.zeros(qp.n_nodes * qp.dim)
    full[qp.free_dofs] = qp.B.T @ res.p
    on_body = [full.reshape(-1, qp.dim)[qp.mesh.body_of_node == b, -1].sum() for b in (0, 1)]
    forces = contact_forces(qp, res.p)
    assert res.status == "converged" and forces.sum() > 0
    for total in on_body:
        assert abs(abs(total) / forces.sum() - 1) < 1e-10, (on_body, forces.sum())
    if (name, coupling) == ("cube_sphere", "mortar"):
        assert res.p.sum() == pytest.approx(forces.sum(), rel=1e-10)
        assert np.abs(forces - res.p).max() > 0.1 * res.p.max()
    else:
        np.testing.assert_allclose(forces, res.p, rtol=0, atol=1e-14 * res.p.max())
