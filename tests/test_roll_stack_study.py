"""The roll-stack study (thesis Sect. 9.3) end to end at level 0, its report,
its configuration, and the exact treatment of the floating work roll.

The work roll is held only by the contact and weak springs (~1e-9 of the elastic
stiffness): ``A`` is nearly singular in its vertical translation. The dual route of the
exact PDAS keeps that translation as an unknown of each active-set step
(:class:`solvers.kernels.cholesky.FloatingCholesky`, FETI-style), so no intermediate result is of
the size ``1/spring``; tested here against the KKT-LU PDAS, which never inverts ``A``.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.sparse as sp

from problems.floating import floating_modes
from problems.kkt import kkt_residuals
from problems.roll_stack import PROBLEM
from report import roll_stack as report
from solvers.kernels.cholesky import FloatingCholesky
from solvers.interface import solve
from workflows.studies.roll_stack import run as study
from workflows.studies import ConfigError, all_targets, check_config, load_config, schema_file
from workflows.studies.roll_stack import roll_args

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def level0():
    return PROBLEM.build(0, PROBLEM.options())


def test_floating_modes_are_the_work_rolls_free_translations(level0):
    """Quarter model: only the vertical translation floats; half model: also the
    translation in y and the spin about the roll's axis (three modes)."""
    R = floating_modes(level0)
    assert R.shape == (level0.n, 1)
    body = level0.multilevel.body_of_dof
    assert np.all(R[body == 1] == 0)                         # the backup roll is held
    # an eigenvector of A: the vertical translation, mixed with the held modes only through
    # the springs (~1e-5)
    z = level0.free_dofs % 3 == 2
    uz = R[z & (body == 0), 0]
    assert np.ptp(uz) < 1e-4 * np.abs(uz).max()
    assert np.abs(R[~z, 0]).max() < 1e-4 * np.abs(uz).max()
    half = PROBLEM.build(0, PROBLEM.options(model="half"))
    assert floating_modes(half).shape[1] == 3


@pytest.mark.parametrize("name, params", [("circle_square", {}), ("cube_sphere", {}),
                                          ("circle_square", {"E2": 1e4}),
                                          ("cube_sphere", {"E2": 1e4})])
def test_held_bodies_have_no_floating_modes(name, params):
    """Bodies held by Dirichlet conditions (also at a stiffness contrast of 1e4: each
    body is judged against its own diagonal) keep the plain factorisation."""
    from problems.spec import problems

    spec = problems()[name]
    assert floating_modes(spec.build(0, spec.options(**params))).shape[1] == 0


def test_floating_cholesky_solves_a_nearly_singular_system():
    """A free chain held at one end by a spring of 1e-4 of its stiffness: the same answer as
    a dense solve, the rigid part ``sum(b) / k`` exactly (the spring carries the load)."""
    n = 200
    L = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tolil()
    L[0, 0] = L[n - 1, n - 1] = 1.0
    k = 1e-4
    A = (L + sp.diags(np.r_[k, np.zeros(n - 1)])).tocsr()
    b = np.sin(np.arange(n))
    for backend in ("splu", "auto"):
        F = FloatingCholesky(A, np.ones((n, 1)) / np.sqrt(n), backend=backend)
        x = F.solve(b)
        assert abs(x[0] / (b.sum() / k) - 1) < 1e-12
        np.testing.assert_allclose(x, np.linalg.solve(A.toarray(), b), rtol=1e-9)
        X = F.solve(np.column_stack([b, 2 * b]))
        np.testing.assert_allclose(X[:, 1], 2 * x, rtol=1e-12)


def test_dual_route_is_exact_on_the_floating_work_roll(level0):
    """The dual PDAS (A factorised without the floating mode) is verified to KKT 1e-12 and
    agrees with the KKT-LU PDAS; before, it stalled at KKT ~4e-5 ('inaccurate')."""
    fast = solve(level0, "pdas", tol=1e-12, method="schur")
    slow = solve(level0, "pdas", tol=1e-12, method="kkt")
    assert fast.status == slow.status == "converged", fast.message
    assert fast.kkt.max < 1e-12 and fast.gap.certified
    assert np.abs(fast.p - slow.p).max() < 1e-9 * slow.p.max()
    assert kkt_residuals(level0, fast.u, fast.p).primal < 1e-14


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("roll")
    study.main(["--problem", "roll_stack", "--level", "0", "--forces", "15e6", "30e6",
                "--crowns", "150e-6", "0", "--solver-levels", "0", "--solvers", "pdas",
                "pdas_kkt", "augmented_projection", "--alg84-levels", "1",
                "--alg84-time-limit", "600", "--outdir", str(out)])
    return out


def test_study_script_end_to_end(run):
    runs = pd.read_csv(run / "roll_stack_runs.csv")
    assert len(runs) == 4 and set(runs.status) == {"converged"}
    assert runs.equilibrium_error.abs().max() < 5e-3           # the suite's bar: 0.5 %
    assert runs.spring_fraction.max() < 1e-4
    assert (runs.kkt_max < 1e-10).all()
    # the crown reduces the strip crown by about 2 x 75 um x (L/2 / 1 m)^2 x 2 ... (beam: ~51 um)
    c = runs.set_index(["force", "crown"])
    for F in (15e6, 30e6):
        fe = c.loc[(F, 0.0), "strip_crown"] - c.loc[(F, 150e-6), "strip_crown"]
        beam = c.loc[(F, 0.0), "beam_strip_crown"] - c.loc[(F, 150e-6), "beam_strip_crown"]
        assert abs(fe / beam - 1) < 0.1
    assert (runs.sag_work_axis > runs.sag_backup_axis).all()    # the work roll rises more
    prof = pd.read_csv(run / "roll_stack_profiles.csv")
    assert {"fe", "beam", "strip"} == set(prof.source)
    strip = prof[(prof.source == "strip") & (prof.force == 15e6) & (prof.crown == 150e-6)]
    # the strip's load: uniform F / L over |x| <= L/2 = 0.5 m, nothing beyond
    inside = strip.x < 0.5
    # (to 1e-4: the uniform pressure acts on arcs of the crowned radius, which vary by 2e-5)
    np.testing.assert_allclose(strip.strip_line_load[inside], 15e6 / 1.0, rtol=1e-4)
    assert (strip.strip_line_load[~inside] == 0).all()
    fe = prof[(prof.source == "fe") & (prof.force == 15e6) & (prof.crown == 150e-6)]
    assert fe.x.is_unique and fe.q.notna().sum() > 3
    solvers = pd.read_csv(run / "roll_stack_solvers.csv").set_index(["solver", "level"])
    assert set(solvers.index) == {("pdas", 0), ("pdas_kkt", 0), ("augmented_projection", 0),
                                  ("augmented_projection", 1)}
    assert set(solvers.loc[["pdas", "pdas_kkt"], "status"]) == {"converged"}
    # Alg. 8.4 on the floating roll (FETI's coarse space), with its own columns, at the
    # comparison's level and alone at level 1; its V-cycle coarsens along the rolls
    # (tests/test_layered_multigrid.py): n_o 18 at levels 0-2 (29-34 with SA)
    for level in (0, 1):
        alg84 = solvers.loc[("augmented_projection", level)]
        assert alg84.status == "converged" and alg84.kkt_max <= 1e-6, alg84.message
        assert 0 < alg84.iterations <= 25 and alg84.kappa_S > 1 and alg84.ahat_degree >= 1
        assert alg84.gamma_bar < 2.5 and alg84.n_vcycles > 0
        assert alg84.ahat_kind == "layers" and alg84.kappa_vcycle < 5
    assert np.isnan(solvers.loc[("pdas", 0), "kappa_S"])
    for force in ("15", "30"):
        assert (run / f"roll_stack_F{force}MN.vtu").stat().st_size > 1000


def test_report_on_the_study_output(run, tmp_path):
    o = {k: str(tmp_path / f"{k}.{'png' if 'figure' in k else 'csv'}") for k in (
        "table", "claims", "solver-table", "pressure-figure", "mesh-figure", "stress-figure",
        "line-load-figure", "sag-figure", "strip-figure")}
    report.main(["--runs", str(run / "roll_stack_runs.csv"),
                 "--profiles", str(run / "roll_stack_profiles.csv"),
                 "--contact", str(run / "roll_stack_contact.csv"),
                 "--solvers", str(run / "roll_stack_solvers.csv"),
                 "--vtu", str(run / "roll_stack_F15MN.vtu"), str(run / "roll_stack_F30MN.vtu"),
                 *[a for k, v in o.items() for a in (f"--{k}", v)]])
    claims = pd.read_csv(o["claims"])
    assert claims.loc[claims.claim.str.startswith("equilibrium"), "pass"].iloc[0] in (True, "True")
    # level 0 resolves no contact width: Hertz is reported, not judged
    hertz = claims[claims.claim.str.contains("Hertz")]
    assert len(hertz) == 4 and hertz["pass"].isna().all()
    table = pd.read_csv(o["table"])
    assert len(table) == 4 and (table.cells_across_2b < 8).all()
    for k, v in o.items():
        assert Path(v).stat().st_size > (10_000 if k.endswith("figure") else 100), k


def test_hertz_is_judged_only_where_resolved():
    t = pd.DataFrame({"force_MN": [15.0, 30.0], "crown_um": [150.0, 150.0], "level": [3, 3],
                      "status": ["converged"] * 2, "equilibrium_error": [1e-4, -2e-4],
                      "spring_fraction": [2e-5, 2e-5], "cells_across_2b": [9.0, 7.0],
                      "dev_b0": [0.03, 0.01], "dev_p0_nodal": [-0.06, 0.0]})
    c = report.claims(t)
    hertz = c[c.claim.str.contains("Hertz")]
    assert list(hertz["pass"]) == [True, False, None, None]


def config(scale="tiny"):
    return load_config(ROOT / f"workflows/config/{scale}.yaml")


@pytest.mark.parametrize("scale", ["tiny", "quick", "full"])
def test_configs_run_the_roll_stack(scale):
    c = config(scale)
    check_config(c)
    assert "results/roll_stack/roll_stack_sag.png" in all_targets(c)
    if scale == "full":     # Alg. 8.4 at levels 1-3, with a limit of its own
        assert "--alg84-levels 1 2 3 --alg84-time-limit 1800" in roll_args(c, "roll_stack")


@pytest.mark.parametrize("change, needle", [
    (lambda c: c["roll_stack"]["scenes"].update(roll_stack=[0, 1]), "one level"),
    (lambda c: c["roll_stack"].update(forces=[1.0]), "'roll_stack.forces'"),
    (lambda c: c["roll_stack"].update(crowns=[2e-3]), "'roll_stack.crowns'"),
    (lambda c: c["roll_stack"].update(solvers=["nope"]), "'roll_stack.solvers'"),
    (lambda c: c["roll_stack"].update(solver_levels=[9]), "'roll_stack.solver_levels'"),
    (lambda c: c["roll_stack"]["scenes"].update(circle_square=[0]), "allowed: roll_stack"),
    (lambda c: c["resources"].pop("roll_stack_study"), "'resources.roll_stack_study'"),
])
def test_bad_roll_stack_config_names_the_key(change, needle):
    c = copy.deepcopy(config())
    change(c)
    with pytest.raises(ConfigError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        check_config(c)


def test_script_rejects_bad_arguments(tmp_path, capsys):
    for args, needle in ((["--forces", "1"], "--forces"), (["--solvers", "nope"], "--solvers"),
                         (["--level", "9"], "level"), (["--time-limit", "0"], "--time-limit"),
                         (["--alg84-time-limit", "-1"], "--alg84-time-limit")):
        base = ["--problem", "roll_stack", "--level", "0", "--outdir", str(tmp_path)]
        with pytest.raises(SystemExit) as err:
            study.main(base + args)
        assert err.value.code == 2 and needle in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_study_outputs_do_not_depend_on_the_units(run, tmp_path):
    """The same study in mm, N, MPa reports the same SI numbers (to round-off)."""
    study.main(["--problem", "roll_stack", "--set", "units=mm", "--level", "0", "--forces",
                "15e6", "--crowns", "150e-6", "--outdir", str(tmp_path)])
    mm = pd.read_csv(tmp_path / "roll_stack_runs.csv").iloc[0]
    m = pd.read_csv(run / "roll_stack_runs.csv").set_index(["force", "crown"]).loc[(15e6, 150e-6)]
    for col in ("contact_force", "q0", "p0_nodal", "sag_work_axis", "sag_backup_axis",
                "strip_crown", "spring_fraction", "work_roll_rise"):
        assert abs(mm[col] / m[col] - 1) < 1e-9, col


@pytest.mark.parametrize("scale", ["tiny", "quick", "full"])
def test_schema_accepts_the_configs_and_refuses_unknown_roll_stack_keys(scale):
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import validate

    with schema_file() as schema:
        c = config(scale)
        validate(copy.deepcopy(c), schema)
        c["roll_stack"]["crown"] = [0.0]                        # a typo: 'crowns'
        with pytest.raises(WorkflowError, match="crown"):
            validate(c, schema)
        c = config(scale)
        c["roll_stack"]["alg84_time_limit"] = 0
        with pytest.raises(WorkflowError, match="alg84_time_limit"):
            validate(c, schema)
