"""Alg. 8.4 (augmented projection): agreement with PDAS, Theorem 8.2, (8.25), Lemma 8.13."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp

from problems.circle_square import PROBLEM
from problems.fem.surface import tensor_coarsening
from problems.kkt import energy_error
from problems.qp import ContactQP, ContactSurface, Multilevel, SurfaceHierarchy
from problems.spec import Component
from solvers.kernels import multigrid as mg
from solvers.kernels.schur import build_schur, kappa_schur_exact
from solvers.augmented_projection import (SOLVER, Alg84, augmented_projection_algorithm,
                                          face_cg_variant, make_projection, mprgp,
                                          nested_initial_guess, projected_richardson, smalbe,
                                          theorem_8_8_alpha)
from solvers.interface import solve


def synthetic_qp(n: int = 9) -> ContactQP:
    """Vector Laplacian on an n x n grid clamped at the bottom, pushed up against a
    parabolic obstacle above its top row (one constraint per top node)."""
    h = 1.0 / (n - 1)
    xy = np.array([(i * h, j * h) for j in range(n) for i in range(n)])
    lap1 = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    lap1 = sp.lil_matrix(lap1)
    lap1[0, 0] = lap1[-1, -1] = 1.0
    K = sp.kron(sp.eye(n), lap1) + sp.kron(lap1, sp.eye(n))
    A_full = sp.kron(K, sp.eye(2)).tocsr() + 1e-3 * sp.eye(2 * n * n)
    free_nodes = np.flatnonzero(xy[:, 1] > 0)
    free = np.sort(np.concatenate([2 * free_nodes, 2 * free_nodes + 1]))
    A = A_full[free][:, free]
    f = np.zeros(2 * n * n)
    f[1::2] = 0.05 * h
    top = np.flatnonzero(np.isclose(xy[:, 1], 1.0))
    pos = -np.ones(2 * n * n, dtype=int)
    pos[free] = np.arange(free.size)
    B = sp.csr_matrix((np.ones(n), (np.arange(n), pos[2 * top + 1])), shape=(n, free.size))
    g = 0.02 + 0.5 * (xy[top, 0] - 0.5) ** 2
    mass = np.full(n, h)
    mass[[0, -1]] = h / 2
    coarse_P, coarse_m, coarse_h = tensor_coarsening(xy[top, :1])
    return ContactQP(A=A, f=f[free], B=B, g=g, free_dofs=free, u_fixed=np.zeros(2 * n * n), dim=2,
                     contact=ContactSurface(nodes=top, mass=mass,
                                            direction=np.tile([0.0, 1.0], (n, 1)),
                                            facets=np.column_stack([top[:-1], top[1:]]),
                                            opposing_facets=np.zeros((0, 2), dtype=int)),
                     multilevel=Multilevel(surface=SurfaceHierarchy(coarse_P, coarse_m + [mass],
                                                                    coarse_h + [np.full(n, h)])),
                     name="synthetic")


MPRGP = Component("mprgp", {"rtol": 0.1, "max_steps": 500})
GMG = SOLVER.options(ahat="gmg").ahat.options        # the solver's declared defaults
SCHUR_STEPS = SOLVER.options().schur.options["lanczos_steps"]


def richardson(c: float = 1.0) -> Component:
    return Component("richardson", {"n_i_factor": c, "max_steps": 10_000})


def alg84(qp, Ainv, S_hat, tau, project) -> Alg84:
    return Alg84(qp.A, qp.B, qp.C, qp.f, qp.g, Ainv, S_hat, Ainv.gamma_bar, tau, project)


@pytest.fixture(scope="module")
def problems():
    qps = {"synthetic": synthetic_qp(), "cs0": PROBLEM.make(0), "cs1": PROBLEM.make(1)}
    refs = {k: solve(qp, solver="pdas", tol=1e-10) for k, qp in qps.items()}
    for r in refs.values():
        assert r.status == "converged"
    return qps, refs


COMBOS = list(itertools.product(("gmg", "sa"), ("multilevel", "inexact", "inexact_assembled",
                                                 "jacobi"), ("mprgp", "richardson")))


@pytest.mark.parametrize("name", ["synthetic", "cs0"])
@pytest.mark.parametrize("ahat,schur,projection", COMBOS)
def test_every_combination_reaches_pdas(problems, name, ahat, schur, projection):
    qps, refs = problems
    qp, ref = qps[name], refs[name]
    res = solve(qp, solver="augmented_projection", tol=1e-6, max_iter=3000, ahat=ahat,
                schur=schur, projection=projection, **{"projection.max_steps": 400})
    assert res.claimed_status == "converged", res.message
    assert energy_error(qp, res.u, ref.u) < 1e-5
    assert np.all(res.p >= 0)
    assert np.max(np.abs(res.p - ref.p)) < 1e-3 * np.max(np.abs(ref.p))
    # verified: every KKT residual and the certified energy bound <= 1e-6
    assert res.status == "converged" and res.gap.relative_energy_bound <= 1e-6, (res.status, res.kkt)


@pytest.mark.parametrize("opts", [{}, {"ahat": "sa"}, {"schur": "inexact"},
                                  {"update": "additive"}, {"projection": "richardson"},
                                  {"stop": "estimate"}, {"accelerate": "face_cg"},
                                  {"accelerate": "face_cg", "schur": "jacobi"}])
def test_level1_converges_to_pdas(problems, opts):
    qps, refs = problems
    qp, ref = qps["cs1"], refs["cs1"]
    res = solve(qp, solver="augmented_projection", tol=1e-6, max_iter=2000,
                **{"eps": 1e-7, **opts})
    assert res.claimed_status == res.status == "converged"  # never refuted by verification
    assert res.status == "converged", res.message
    assert energy_error(qp, res.u, ref.u) < 1e-5
    s = res.stats
    assert s["N"] == qp.n_nodes == 4237 and s["NC"] == qp.m == 33
    assert s["n_outer"] == res.iterations == len(res.history["kkt_max"])
    assert s["t_proj"] <= s["t_solve"]


@pytest.mark.parametrize("update", ["additive", "multiplicative"])
@pytest.mark.parametrize("schur", ["multilevel", "inexact"])
def test_transformed_functional_decreases(problems, update, schur):
    """Theorem 8.2: the functional of the transformed problem (8.20) decreases
    monotonically; the primal energy J(u^k) need not (u^k is infeasible)."""
    qp = problems[0]["cs1"]
    res = solve(qp, solver="augmented_projection", tol=1e-8, max_iter=300, update=update,
                schur=schur, stop="estimate", record_kkt=False)
    Jt = np.asarray(res.history["J_transformed"])
    assert len(Jt) > 5
    assert np.all(np.diff(Jt) <= 1e-12 * np.max(np.abs(Jt)))
    assert Jt[-1] < Jt[0]


def _transformed_norm_sq(qp, Ainv, e_u, e_p):
    """||(e_u, e_p)||^2 in the operator of (8.20)."""
    r = qp.A @ e_u + qp.B.T @ e_p
    Ar = Ainv(r)
    return float(e_u @ (qp.A @ Ar - r) + e_p @ (qp.B @ Ar - qp.B @ e_u))


@pytest.mark.parametrize("name", ["synthetic", "cs0"])
def test_estimate_8_25_bounds_true_error(problems, name):
    """Corollary 8.4 / (8.25): ||U - U^{k+1}||^2 <= 2 rho/(1 - rho) eta_k for the
    additive update, S-hat = S_in and Alg. 8.3 with n_i by (8.15) (rho_P <= e^-c)."""
    qps, refs = problems
    qp, ref = qps[name], refs[name]
    Ainv = mg.scaled_vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs, **GMG)
    S_hat = build_schur("inexact", qp, Ainv, SCHUR_STEPS)
    a_low, a_bar = theorem_8_8_alpha(Ainv.gamma_bar)
    tau, c = 1.0 / a_bar, 1.0
    project, _ = make_projection(richardson(c), S_hat)
    rho = 1.0 - 0.5 * tau * a_low * (1.0 - np.exp(-c))
    steps = []
    augmented_projection_algorithm(alg84(qp, Ainv, S_hat, tau, project), np.zeros(qp.n),
                                   np.zeros(qp.m), 1e-6, 60, "additive",
                                   lambda s: steps.append(s) or False)
    for s in steps:
        err = _transformed_norm_sq(qp, Ainv, ref.u - s.u, ref.p - s.p)
        assert s.eta >= 0 and s.corollary_8_4 >= 0
        assert err <= 2 * rho / (1 - rho) * s.corollary_8_4 * (1 + 1e-8) + 1e-14
        assert err <= 2 * rho / (1 - rho) * s.eta * (1 + 1e-8) + 1e-14
    assert len(steps) > 3


@pytest.mark.parametrize("name", ["synthetic", "cs1"])
def test_face_cg_variant_decreases_transformed_functional(problems, name):
    """The Krylov variant (beyond the thesis) keeps Theorem 8.2's monotone decay of Jt."""
    qps, refs = problems
    qp, ref = qps[name], refs[name]
    Ainv = mg.scaled_vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs, **GMG)
    S_hat = build_schur("multilevel", qp, Ainv, SCHUR_STEPS)
    project, _ = make_projection(MPRGP, S_hat)
    iterates = []
    u, p, k, reason, n_cg = face_cg_variant(
        alg84(qp, Ainv, S_hat, 1.0, project), S_hat.columns, np.zeros(qp.n), np.zeros(qp.m),
        1e-9, 300, monitor=lambda s: iterates.append((s.u.copy(), s.p.copy())) or False)
    assert reason == "converged" and n_cg > 0
    assert energy_error(qp, u, ref.u) < 1e-6
    z = Ainv(qp.f)
    Jt = [0.5 * _transformed_norm_sq(qp, Ainv, u_k, p_k)
          - ((qp.A @ u_k) @ z - qp.f @ u_k + p_k @ (qp.B @ z) - p_k @ qp.g) for u_k, p_k in iterates]
    assert np.all(np.diff(Jt) <= 1e-10 * np.max(np.abs(Jt)))


def test_kappa_S_hat_doubles_per_refinement():
    """Lemma 8.13: kappa(S) = O(h^-1), so kappa(S-hat) doubles per uniform refinement."""
    kappas = {"multilevel": [], "inexact": []}
    for level in (0, 1, 2):
        qp = PROBLEM.make(level)
        Ainv = mg.scaled_vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs,
                                 **{**GMG, "lanczos_steps": 10})
        for kind in kappas:
            kappas[kind].append(build_schur(kind, qp, Ainv, lanczos_steps=40).kappa)
    for kind, k in kappas.items():
        ratios = np.array(k[1:]) / np.array(k[:-1])
        assert np.all((ratios > 1.6) & (ratios < 2.5)), (kind, k)


def test_multilevel_S_hat_is_spectrally_close_to_S_in(problems):
    qp = problems[0]["cs1"]
    Ainv = mg.scaled_vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs, **GMG)
    sh = build_schur("multilevel", qp, Ainv, SCHUR_STEPS)
    Sd = sh.dense()
    assert np.allclose(Sd, Sd.T) and np.linalg.eigvalsh(Sd)[0] > 0
    assert np.allclose(sh.diagonal(), np.diag(Sd), rtol=1e-12)   # the known diagonal is S-hat's
    assert sh.kappa_Sin < 5.0
    # scaled so that S_in <= S-hat
    S_in = np.column_stack([qp.B @ Ainv(qp.B.T @ e) for e in np.eye(qp.m)])
    lam = np.linalg.eigvals(np.linalg.solve(Sd, 0.5 * (S_in + S_in.T))).real
    assert lam.max() <= 1.0 + 1e-6
    assert lam.max() / lam.min() < 5.0


def test_projections_solve_the_box_qp():
    rng = np.random.default_rng(0)
    M = rng.standard_normal((30, 30))
    S = M @ M.T + 30 * np.eye(30)
    d = rng.standard_normal(30) * 10
    S_hat = lambda q: S @ q
    lam = np.linalg.eigvalsh(S)
    q_m, n_m = mprgp(S_hat, d, np.zeros(30), 1.0 / lam[-1], 1e-12, 500)
    q_r, n_r = projected_richardson(S_hat, d, np.zeros(30), 1.0 / lam[-1], 3000)
    for q in (q_m, q_r):
        g = S @ q - d
        assert np.all(q >= 0)
        assert np.max(np.abs(np.where(q > 0, g, np.minimum(g, 0)))) < 1e-8
    assert n_m < n_r


def test_smalbe_projects_onto_the_balanced_set():
    """(8.24) with a floating body's equilibrium G q = e: the KKT conditions of
    min 1/2 q'Sq - d'q, q >= 0, G q = e hold for SMALBE's q and multiplier mu."""
    rng = np.random.default_rng(3)
    M = rng.standard_normal((30, 30))
    S = M @ M.T + 30 * np.eye(30)
    d = rng.standard_normal(30) * 10
    G = rng.uniform(0.5, 1.5, (1, 30))
    e = np.array([4.0])
    lam = np.linalg.eigvalsh(S)
    q, mu, n = smalbe(lambda x: S @ x, G, e, d, np.zeros(30), lam[-1], 1e-12, 500,
                      eq_rtol=1e-12)
    assert n > 0 and np.all(q >= 0)
    assert abs((G @ q - e)[0]) <= 1e-10 * e[0]
    g = S @ q - d + G.T @ mu                    # = the bounds' multipliers: >= 0, on q = 0
    free = q > 0
    assert free.any() and (~free).any()         # both kinds of component occur
    assert np.abs(g[free]).max() < 1e-8 * np.abs(d).max()
    assert g[~free].min() > -1e-8 * np.abs(d).max()


def test_chebyshev_polynomial_maps_the_spectrum_as_theory_says():
    """A-hat^-1 = p(VA)V: lambda p(lambda) lies in [1 - e, 1 + e] on the interval, with
    e = 1/T_d(sigma) and d the smallest degree for the target; it stays positive below
    the interval, where _below_interval reads the eigenvalue back from its image."""
    lo, hi = 1e-3, 1.0
    lam = np.concatenate([[1e-4], np.geomspace(lo, hi, 120)])
    A = sp.diags(lam).tocsr()
    d = mg.chebyshev_degree(lo, hi, 2.0)
    e = 1.0 / np.cosh(d * np.arccosh((hi + lo) / (hi - lo)))
    e_less = 1.0 / np.cosh((d - 1) * np.arccosh((hi + lo) / (hi - lo)))
    assert (1 + e) / (1 - e) <= 2.0 < (1 + e_less) / (1 - e_less)
    apply = mg.chebyshev_vcycle(lambda x: A @ x, lambda r: np.array(r, dtype=float), lo, hi, d)
    P = np.column_stack([apply(c) for c in np.eye(lam.size)])
    np.testing.assert_allclose(P, P.T, atol=1e-12 * np.abs(P).max())
    image = np.diag(P) * lam                                 # lambda p(lambda)
    assert image[1:].min() >= 1 - e - 1e-9 and image[1:].max() <= 1 + e + 1e-9
    assert 0 < image[0] < 1 - e
    assert mg._below_interval(lo, hi, d, image[0]) == pytest.approx(1e-4, rel=1e-6)
    assert mg.chebyshev_degree(0.5, 1.0, 2.5) == 1           # a good V-cycle stays one


@pytest.mark.parametrize("scene", ["circle_square", pytest.param("cube_sphere", marks=pytest.mark.slow)])
def test_outer_steps_stay_bounded_towards_incompressibility(scene):
    """The V-cycle's kappa(VA) grows like (1 - 2 nu)^-0.75 (h-independent); the
    automatic Chebyshev degree keeps gamma_bar near its target, and S-hat = S_in where
    the multilevel one loses its equivalence, so n_o at nu = 0.4999 is at most twice
    n_o at nu = 0.3 (level 1)."""
    from problems.spec import problems as registry

    spec = registry()[scene]
    runs = {nu: solve(spec.make(1, nu1=nu, nu2=nu), solver="augmented_projection", tol="mid")
            for nu in (0.3, 0.4999)}
    for nu, r in runs.items():
        assert r.status == "converged", (nu, r.message)
        assert r.stats["gamma_bar"] < 3.5
    soft, hard = runs[0.3].stats, runs[0.4999].stats
    assert soft["ahat_degree"] == 1 and soft["schur_kind"] == "multilevel"
    assert hard["kappa_vcycle"] > 100 and hard["ahat_degree"] >= 8
    assert hard["schur_kind"].startswith("inexact")
    assert runs[0.4999].iterations <= 2 * runs[0.3].iterations


def test_nested_initial_guess_saves_outer_steps(problems):
    qps, refs = problems
    coarse, fine = qps["cs0"], qps["cs1"]
    rc = solve(coarse, solver="augmented_projection", tol=1e-6)
    u0, p0 = nested_initial_guess(coarse, rc, fine)
    assert np.all(p0 >= 0) and u0.shape == (fine.n,) and p0.shape == (fine.m,)
    # the pressure transfers: total force is roughly kept
    assert abs(p0.sum() / rc.p.sum() - 1) < 0.1
    cold = solve(fine, solver="augmented_projection", tol=1e-6, max_iter=500)
    warm = solve(fine, solver="augmented_projection", tol=1e-6, max_iter=500, u0=u0, p0=p0)
    assert warm.status == cold.status == "converged"
    assert warm.iterations < cold.iterations


def test_honest_status(problems):
    qp = problems[0]["cs1"]
    res = solve(qp, solver="augmented_projection", tol=1e-9, max_iter=3)
    assert res.status == "max_iter" and res.iterations == 3
    res = solve(qp, solver="augmented_projection", tol=1e-12, time_limit=1e-3, max_iter=10_000)
    assert res.status == "time_limit"


@pytest.mark.slow                       # dense eigenvalues of the operators
def test_spectral_estimates_match_dense_eigenvalues():
    """gamma_bar (8.18), kappa(S-hat) (Table 9.1) and kappa(S-hat^-1 S) (Sect. 8.6) from
    Lanczos, against dense generalised eigenvalues on level 0 (2194 unknowns, 17 rows)."""
    import scipy.linalg as sla
    qp = PROBLEM.make(0)
    Ainv = mg.scaled_vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs,
                            **{**GMG, "lanczos_steps": 40})
    # the V-cycle as a dense SPD matrix: A-hat^-1 = V / gamma_low
    V = np.column_stack([Ainv.raw(e) for e in np.eye(qp.n)])
    V = 0.5 * (V + V.T)
    lam = sla.eigh(qp.A.toarray(), np.linalg.inv(V), eigvals_only=True)   # lambda(V A)
    assert Ainv.ritz[0] == pytest.approx(lam[0], rel=1e-6)
    assert Ainv.ritz[1] == pytest.approx(lam[-1], rel=1e-6)
    assert lam[-1] / lam[0] * 1.05 / 0.9 == pytest.approx(Ainv.gamma_bar, rel=1e-5)
    # a symmetric V-cycle with Galerkin coarse operators never over-corrects: lambda(V A) <= 1
    assert lam[-1] <= 1.0 + 1e-10
    # (8.18) holds for the scaled operator: A-hat < A <= gamma_bar A-hat
    assert lam[0] / Ainv.gamma_low > 1 and lam[-1] / Ainv.gamma_low <= Ainv.gamma_bar
    sh = build_schur("multilevel", qp, Ainv, 40)
    S_hat = sh.dense()
    ev = np.linalg.eigvalsh(S_hat)
    assert sh.kappa == pytest.approx(ev[-1] / ev[0] * 1.05, rel=1e-6)
    S = qp.B.toarray() @ np.linalg.solve(qp.A.toarray(), qp.B.T.toarray())
    mu = sla.eigh(S, S_hat, eigvals_only=True)
    kappa, lo, hi = kappa_schur_exact(qp, Ainv, sh, steps=40)
    assert kappa == pytest.approx(mu[-1] / mu[0], rel=1e-4)
    assert kappa < 5.0                                     # spectrally equivalent, Remark 8.15
    S_in = qp.B.toarray() @ V @ qp.B.T.toarray() / Ainv.gamma_low
    mu_in = sla.eigh(0.5 * (S_in + S_in.T), S_hat, eigvals_only=True)
    assert mu_in[-1] <= 1.0 + 1e-9                          # scaled: S_in <= S-hat
    assert sh.kappa_Sin == pytest.approx(mu_in[-1] / mu_in[0], rel=1e-4)


def test_unscaled_vcycle_is_the_scaled_one_without_lanczos(problems):
    """What a linear PCG solve (the floor, the certificate) builds: the same V-cycle as
    A-hat, with no Lanczos run for a scaling it does not need."""
    qp = problems[0]["cs1"]
    o = {k: GMG[k] for k in ("smoother", "sweeps")}
    raw = mg.vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs, **o)
    scaled = mg.scaled_vcycle(qp.A, "gmg", qp.multilevel, 2, qp.free_dofs, **GMG)
    x = np.random.default_rng(1).standard_normal(qp.n)
    assert np.array_equal(raw.raw(x), scaled.raw(x))
    assert raw.gamma_low == 1.0 and raw.lanczos_time == 0.0 and np.isnan(raw.ritz).all()
    assert np.allclose(scaled(x), scaled.raw(x) / scaled.gamma_low)


def test_diagnostics_off_changes_nothing_but_the_record(problems):
    """``diagnostics=False`` drops the per-step J(u^k) and Corollary 8.4 products, not a
    step of Alg. 8.4: the iterates are the same to the last bit."""
    qp = problems[0]["cs1"]
    runs = [solve(qp, solver="augmented_projection", tol=1e-8, max_iter=40, stop="estimate",
                  record_kkt=False, diagnostics=d) for d in (True, False)]
    on, off = runs
    assert on.iterations == off.iterations > 5
    assert np.array_equal(on.u, off.u) and np.array_equal(on.p, off.p)
    assert np.array_equal(on.history["J_transformed"], off.history["J_transformed"])
    assert np.isfinite(on.history["energy"]).all() and np.isnan(off.history["energy"]).all()
    assert np.isfinite(on.history["corollary_8_4"]).all()
    assert np.isnan(off.history["corollary_8_4"]).all()
