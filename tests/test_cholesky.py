"""The sparse Cholesky backends (solvers/kernels/cholesky.py) and the exact reference built on
them: PDAS through the dual problem on the contact rows against PDAS with a KKT LU per
step, on scenes."""
import platform

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems import circle_square, cube_sphere
from solvers.kernels import cholesky
from solvers.kernels.cholesky import FactorizationError, available_backends, factorize
from solvers.interface import solve
from solvers.reference import reference_solve

BACKENDS = available_backends()


@pytest.fixture(scope="module")
def scene_qp():
    return circle_square.PROBLEM.make(1)


def test_mkl_is_installed_where_its_wheels_exist():
    # a missing install step would otherwise silently fall back to the slow backend
    if platform.machine() in ("x86_64", "AMD64"):
        assert "pardiso" in BACKENDS
    assert "splu" in BACKENDS


@pytest.mark.parametrize("backend", BACKENDS)
def test_solves_agree_with_scipy(scene_qp, backend):
    A = scene_qp.A
    chol = factorize(A, backend)
    assert chol.backend == backend and chol.n == A.shape[0] and chol.fill >= A.nnz // 2
    rng = np.random.default_rng(0)
    b = rng.standard_normal(A.shape[0])
    x = chol.solve(b)
    assert x.shape == b.shape
    assert np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b) * 1e3
    np.testing.assert_allclose(x, spla.spsolve(A.tocsc(), b), rtol=1e-9, atol=1e-12)
    # a block wider than BLOCK, dense and sparse
    Bm = rng.standard_normal((A.shape[0], cholesky.BLOCK + 7))
    X = chol.solve(Bm)
    assert X.shape == Bm.shape
    y = chol.solve(Bm[:, -1])
    np.testing.assert_allclose(X[:, -1], y, rtol=1e-12, atol=1e-13 * np.abs(y).max())
    S = scene_qp.B.T.tocsc()
    np.testing.assert_allclose(chol.solve(S), chol.solve(S.toarray()), rtol=0, atol=0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_partial_solves_give_the_schur_complement(scene_qp, backend):
    qp = scene_qp
    chol = factorize(qp.A, backend, components=qp.B.indices)
    Bt = qp.B.T.tocsc()
    S_partial = qp.B @ chol.solve(Bt, partial=True)
    S_full = qp.B @ spla.spsolve(qp.A.tocsc(), Bt.toarray())
    np.testing.assert_allclose(S_partial, S_full, rtol=0, atol=1e-11 * np.abs(S_full).max())
    # a full solve after partial ones still works on the same factorisation
    x = chol.solve(qp.f)
    assert np.linalg.norm(qp.A @ x - qp.f) <= 1e-10 * np.linalg.norm(qp.f)
    with pytest.raises(ValueError, match="components"):
        factorize(qp.A, backend).solve(qp.f, partial=True)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_block_solve_holds_at_most_three_blocks(scene_qp, backend):
    """A block of BLOCK sparse columns (the Schur complement's unit of work) is solved
    with at most three n x BLOCK arrays in memory: the right-hand side, made column-major
    as the backends take it (no copy on the way in), the answer and its row-major copy
    (the callers' dense products depend on the layout, so it is kept)."""
    import tracemalloc

    qp = scene_qp
    chol = factorize(qp.A, backend, components=qp.B.indices)
    cols = sp.random(qp.n, cholesky.BLOCK, density=1e-3, format="csc", random_state=1)
    block = qp.n * cholesky.BLOCK * 8
    tracemalloc.start()
    try:
        x = chol.solve(cols)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert x.shape == (qp.n, cholesky.BLOCK)
    assert block <= peak <= 3.5 * block
    np.testing.assert_array_equal(x, chol.solve(np.ascontiguousarray(cols.toarray())))


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="MKL not installed (non-x86)")
def test_pardiso_refuses_an_indefinite_matrix():
    A = sp.diags([1.0, -1.0, 2.0]).tocsr()
    with pytest.raises(FactorizationError, match="positive definite"):
        factorize(A, "pardiso")


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="MKL not installed (non-x86)")
def test_same_pattern_refactorisation_keeps_the_analysis(scene_qp):
    """``SamePatternCholesky``: matrices of one pattern (explicit zeros included) analysed
    once, each new one's values factorised numerically, and solved as a fresh
    factorisation solves them; another pattern analysed anew; a matrix that is not
    positive definite refused without spoiling the next."""
    A = sp.csr_matrix(scene_qp.A)
    A.sort_indices()
    n = A.shape[0]
    rng = np.random.default_rng(3)
    b = rng.standard_normal(n)
    same = cholesky.SamePatternCholesky()

    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    diag = np.flatnonzero(A.indices == rows)
    ij = np.flatnonzero(A.indices != rows)[0]
    i, j = rows[ij], A.indices[ij]
    ji = np.flatnonzero((rows == j) & (A.indices == i))[0]

    def with_values(scale, zero):      # one pattern; the coupling (i, j) an explicit zero
        M = A.copy()                   # or not, its diagonals raised to keep M SPD
        M.data = A.data * scale
        M.data[diag[[i, j]]] += abs(A.data[ij]) * scale
        if zero:
            M.data[[ij, ji]] = 0.0
        return M
    mats = [with_values(1.0 + 0.5 * k, zero=k != 1) for k in range(3)]
    assert mats[0].nnz == A.nnz and mats[0][i, j] == 0.0 and mats[1][i, j] != 0.0
    for M in mats:
        x = same.factorize(M).solve(b)
        assert np.linalg.norm(M @ x - b) <= 1e-11 * np.linalg.norm(b)
        np.testing.assert_allclose(x, factorize(M, "pardiso").solve(b), rtol=0, atol=1e-12
                                   * np.abs(x).max())
    assert same.analyses == 1
    indefinite = mats[0].copy()
    indefinite.data[indefinite.indices == np.repeat(np.arange(n), np.diff(indefinite.indptr))] \
        *= -1.0
    with pytest.raises(FactorizationError, match="positive definite"):
        same.factorize(indefinite)
    x = same.factorize(mats[1]).solve(b)
    assert np.linalg.norm(mats[1] @ x - b) <= 1e-11 * np.linalg.norm(b)
    assert same.analyses == 1
    other = sp.csr_matrix(A[:100, :100])
    x = same.factorize(other).solve(b[:100])
    assert np.linalg.norm(other @ x - b[:100]) <= 1e-11 * np.linalg.norm(b[:100])
    assert same.analyses == 2


def test_same_pattern_refactorisation_needs_mkl(monkeypatch):
    monkeypatch.setattr(cholesky, "_mkl", lambda: None)
    with pytest.raises(ValueError, match="needs Intel MKL.*backend='splu'"):
        cholesky.SamePatternCholesky()


def test_the_cholesky_factor_is_sparse_and_exact(scene_qp):
    """``cholesky_factor``: ``F'F = A`` to round-off on a scene's stiffness matrix, ``F``
    sparse (the factorisation's fill, far below a dense factor's ``n (n + 1) / 2``), and
    an indefinite matrix refused, saying why."""
    A = sp.csc_matrix(scene_qp.A)
    n = A.shape[0]
    F = cholesky.cholesky_factor(A)
    assert F.shape == (n, n) and F.nnz < 0.1 * n * (n + 1) / 2
    assert abs(F.T @ F - A).max() <= 1e-13 * abs(A).max()
    x = np.random.default_rng(0).standard_normal(n)
    assert abs(np.linalg.norm(F @ x) ** 2 - x @ (A @ x)) <= 1e-12 * x @ (A @ x)
    with pytest.raises(FactorizationError, match="1 pivots <= 0 .*not positive definite"):
        cholesky.cholesky_factor(sp.diags([1.0, -1.0, 2.0]))


def test_bad_backend_names_the_choices(scene_qp, monkeypatch):
    with pytest.raises(ValueError, match="backend='lu' is not allowed; allowed: auto, pardiso"):
        factorize(scene_qp.A, "lu")
    monkeypatch.setattr(cholesky, "_MKL", [None])      # a machine without MKL
    assert available_backends() == ("splu",)
    assert factorize(scene_qp.A).backend == "splu"
    with pytest.raises(ValueError, match="needs Intel MKL"):
        factorize(scene_qp.A, "pardiso")


# ------------------------------------------------------------- the exact reference
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("problem,level", [(circle_square, 1), (circle_square, 2),
                                           (cube_sphere, 0)])
def test_dual_route_agrees_with_kkt_lu_to_1e10(problem, level, backend):
    # the suite's bar: the fast reference agrees with the KKT-LU PDAS to 1e-10 in the multipliers
    qp = problem.PROBLEM.make(level)
    fast = solve(qp, "pdas", tol=1e-10, method="schur", factorization=backend)
    slow = solve(qp, "pdas", tol=1e-10, method="kkt")
    for r in (fast, slow):
        assert r.status == "converged" and r.kkt.max <= 1e-10, r.message
    assert fast.stats["factorization"] == backend and fast.stats["n_factorisations"] == 1
    assert np.abs(fast.p - slow.p).max() <= 1e-10 * np.abs(slow.p).max()
    e = fast.u - slow.u
    assert np.sqrt(e @ (qp.A @ e) / (slow.u @ (qp.A @ slow.u))) <= 1e-10
    assert np.array_equal(fast.p > 0, slow.p > 0)


def test_reference_solve_takes_the_dual_route(scene_qp):
    ref = reference_solve(scene_qp)
    assert ref.solver == "pdas" and ref.stats["method"] == "schur"
    assert ref.status == "converged" and ref.kkt.max <= 1e-10


def test_exact_reference_script_and_report(tmp_path, capsys):
    from report import exact_reference as report
    from workflows.io import read_csv
    from workflows.studies.exact_reference import run as exact_reference

    runs = tmp_path / "runs.csv"
    exact_reference.main(["--problem", "circle_square", "--levels", "0", "1", "--out", str(runs)])
    frame = read_csv(runs)
    assert sorted(frame.method) == ["kkt", "kkt", "schur", "schur"]
    assert (frame.status == "converged").all() and (frame.kkt_max <= 1e-10).all()
    table, claims, fig = tmp_path / "t.csv", tmp_path / "c.csv", tmp_path / "f.png"
    report.main(["--runs", str(runs), "--table", str(table), "--claims", str(claims),
                 "--figure", str(fig)])
    t, c = read_csv(table), read_csv(claims)
    assert list(t.level) == [0, 1] and (t.p_difference <= 1e-10).all()
    agree = c[c.claim.str.startswith("dual route = KKT-LU")]
    assert agree["pass"].iloc[0] == True  # noqa: E712 -- a real bool read back
    # the speedup bar is for 262k nodes: not judged at level 1
    assert c[c.claim.str.contains("faster")]["pass"].isna().all()
    assert fig.stat().st_size > 10_000
    with pytest.raises(SystemExit):
        exact_reference.main(["--problem", "circle_square", "--levels", "0", "--kkt-levels",
                              "1", "--out", str(runs)])
    assert "--kkt-levels: [1] not among --levels [0]" in capsys.readouterr().err
