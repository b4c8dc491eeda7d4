"""The floor against the machine: the byte count of a V-cycle and a PCG step against counts
made by hand, the study's script and report end to end on small levels, and its bad input."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from solvers.kernels import multigrid as mg
from workflows.measure import stream_triad_gbs


def laplacian_1d(n: int) -> sp.csr_matrix:
    return sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1],
                    format="csr")


def linear_interpolation() -> sp.csr_matrix:
    """7 fine nodes from 3 coarse ones (fine 1, 3, 5 are the coarse nodes): 9 entries."""
    rows = [0, 1, 2, 2, 3, 4, 4, 5, 6]
    cols = [0, 0, 0, 1, 1, 1, 2, 2, 2]
    vals = [0.5, 1, 0.5, 0.5, 1, 0.5, 0.5, 1, 0.5]
    return sp.csr_matrix((vals, (rows, cols)), shape=(7, 3))


def test_vcycle_bytes_of_a_two_level_cycle_counted_by_hand():
    """1D Laplacian on 7 nodes (19 entries), interpolation from 3 (9 entries), V(1,1)
    symmetric Gauss-Seidel: 2 x 2 passes over A and the residual are 5 passes of A, R and
    P one each, the coarse LU once."""
    A, P = laplacian_1d(7), linear_interpolation()
    ml = mg.geometric_hierarchy(A, [P], "symmetric_gs", 1, smoothing="full")
    got = mg.vcycle_traffic(ml, "symmetric_gs", 1)
    lu = spla.splu(sp.csc_matrix(ml.levels[-1].A))
    assert ml.levels[-1].A.nnz == 7
    lu_entries = lu.L.nnz + lu.U.nnz
    assert got.values == 8 * (5 * 19 + 9 + 9 + lu_entries)
    # int32 column indices and row pointers: A (19, 8 pointers), P (9, 8), R = P' (9, 4)
    lu_index = 4 * (lu_entries + 2 * 4)
    assert got.indices == 4 * (5 * (19 + 8) + (9 + 8) + (9 + 4)) + lu_index
    # vectors of 7 and 3 entries, 8 bytes each: x = 0 (1 x 7), four Gauss-Seidel passes
    # (x read and written, b read: 3 x 7 each), A x (7 in, 7 out), b - A x (3 x 7),
    # R r (7 in, 3 out), P x_c (3 in, 7 out), x += (3 x 7); the coarse solve (3 in, 3 out)
    vectors = 7 + 4 * 21 + 14 + 21 + 10 + 10 + 21 + 6
    assert got.vectors == 8 * vectors
    assert got.total == got.values + got.indices + got.vectors


def test_cg_step_bytes_counted_by_hand():
    """SciPy's PCG step beside its preconditioner: A p once and 22 vector passes."""
    A = laplacian_1d(50)
    got = mg.cg_step_traffic(A)
    assert got.values == 8 * A.nnz and got.indices == 4 * (A.nnz + 51)
    assert got.vectors == 8 * 22 * 50


def test_vcycle_bytes_on_a_scene_hierarchy(circle_square_level_1):
    """On the floor's geometric hierarchy of a uniform scene (every level smoothed in
    full): values = 8 x (5 passes of every A_l + R_l and P_l + the coarse LU)."""
    qp = circle_square_level_1
    vc = mg.component_vcycle(qp, mg.ahat_component("gmg"))
    sweeps = mg.ahat_component("gmg").options["sweeps"]
    levels = vc.ml.levels
    assert len(levels) >= 2 and not any(hasattr(lv, "local") for lv in levels)
    got = mg.vcycle_traffic(vc.ml, mg.DEFAULT_SMOOTHER, sweeps)
    lu = spla.splu(sp.csc_matrix(levels[-1].A))
    entries = sum((4 * sweeps + 1) * lv.A.nnz + 2 * lv.P.nnz for lv in levels[:-1])
    assert got.values == 8 * (entries + lu.L.nnz + lu.U.nnz)


@pytest.fixture(scope="module")
def circle_square_level_1():
    from problems.circle_square import PROBLEM
    return PROBLEM.build(1, PROBLEM.options())


def test_stream_triad_rejects_bad_sizes():
    with pytest.raises(ValueError, match="entries and repeats must be >= 1"):
        stream_triad_gbs(entries=0)
    assert np.isfinite(stream_triad_gbs(entries=10_000, repeats=2))


def test_study_script_and_report(tmp_path):
    from report.floor_bandwidth import main as report
    from workflows.studies.floor_bandwidth.run import main as study

    runs = tmp_path / "runs.csv"
    study(["--problem", "cube_sphere", "--levels", "0", "1", "--repeats", "2",
           "--cg-steps", "3", "--stream-mb", "24", "--out", str(runs)])
    r = pd.read_csv(runs)
    assert list(r.level) == [0, 1] and list(r.mg_levels) == [1, 2]
    assert np.allclose(r.vcycle_mb, r.vcycle_values_mb + r.vcycle_indices_mb
                       + r.vcycle_vectors_mb)
    assert np.allclose(r.vcycle_gbs, r.vcycle_mb / 1e3 / r.t_vcycle)
    assert (r.cg_step_mb > r.vcycle_mb).all() and (r.stream_triad_gbs > 0).all()
    table, fig = tmp_path / "table.csv", tmp_path / "figure.png"
    report(["--runs", str(runs), "--table", str(table), "--figure", str(fig)])
    t = pd.read_csv(table)
    assert np.allclose(t.vcycle_of_triad, r.vcycle_gbs / r.stream_triad_gbs)
    # int32 indices beside float64 values: a third of a matrix's bytes at most
    assert ((0.2 < t.index_share) & (t.index_share < 1 / 3 + 0.01)).all()
    assert ((1 < t.float32_gain) & (t.float32_gain < 1.5)).all()
    assert (t.matrix_free_gain > t.float32_gain).all()
    assert fig.stat().st_size > 0


@pytest.mark.parametrize("argv, needle", [
    (["--repeats", "0"], "--repeats: 0 is not allowed; allowed: >= 1"),
    (["--cg-steps", "0"], "--cg-steps: 0 is not allowed; allowed: >= 1"),
    (["--stream-mb", "1"], "--stream-mb: 1.0 is not allowed; allowed: >= 24"),
    (["--levels", "9"], "parameter 'level': 9 is out of range"),
])
def test_study_script_rejects_bad_arguments(argv, needle, tmp_path, capsys):
    from workflows.studies.floor_bandwidth.run import main as study

    args = ["--problem", "cube_sphere", "--levels", "0", *argv, "--out", str(tmp_path / "x.csv")]
    with pytest.raises(SystemExit) as exit_:
        study(args)
    assert exit_.value.code == 2 and needle in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
