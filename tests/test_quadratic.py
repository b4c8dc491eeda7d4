"""P2 elements (thesis Remark 7.11): the element, the constraints, the scenes, the solvers."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from problems import circle_square, cube_sphere, flat_blocks
from problems.fem.accuracy import interpolation_matrix
from problems.fem.elasticity import lame_parameters, rigid_body_modes
from problems.fem.fields import contact_fields, hertz_comparison
from problems.fem.mesh import structured_cube, structured_square
from problems.fem.quadratic import (body_force_vector_p2, facet_shape_functions,
                                    linear_subcells, quadratic_facets, quadratic_mesh,
                                    stiffness_matrix_p2, stiffness_matrix_p2_skfem,
                                    surface_mass_p2, traction_vector_p2)
from problems.spec import ParameterError
from solvers.interface import solve


def _meshes():
    return [quadratic_mesh(*structured_square(3)), quadratic_mesh(*structured_cube(2))]


@pytest.mark.parametrize("mesh", _meshes(), ids=["2d", "3d"])
def test_stiffness_is_exact_for_quadratic_fields_and_equals_scikit_fem(mesh):
    d = mesh.points.shape[1]
    E = np.linspace(1.0, 3.0, len(mesh.cells))          # per-cell material
    K = stiffness_matrix_p2(mesh, E, 0.3)
    np.testing.assert_allclose(K.toarray(), stiffness_matrix_p2_skfem(mesh, E, 0.3).toarray(),
                               rtol=0, atol=1e-12 * abs(K).max())
    assert abs(K - K.T).max() == 0.0
    assert abs(K @ rigid_body_modes(mesh.points)).max() < 1e-12 * abs(K).max()
    # u = (x^2, 0, ...): a(u, u) = (lam + 2 mu) int (2x)^2 = (lam + 2 mu) 4/3 on the unit box
    K1 = stiffness_matrix_p2(mesh, 1.0, 0.3)
    u = np.zeros_like(mesh.points)
    u[:, 0] = mesh.points[:, 0] ** 2
    lam, mu = lame_parameters(1.0, 0.3)
    assert u.ravel() @ K1 @ u.ravel() == pytest.approx((lam + 2 * mu) * 4 / 3, rel=1e-12)
    # loads: the totals are the force times the measure
    f = body_force_vector_p2(mesh.points, mesh.cells, np.tile(np.arange(1.0, d + 1), (len(mesh.cells), 1)))
    np.testing.assert_allclose(f.reshape(-1, d).sum(axis=0), np.arange(1.0, d + 1), rtol=1e-12)


def test_surface_loads_and_masses_integrate_the_shape_functions():
    mesh = quadratic_mesh(*structured_cube(2))
    top = mesh.cells[:, :4]
    from problems.fem.elasticity import boundary_facets
    facets = boundary_facets(top, mesh.points)
    facets = facets[np.all(np.isclose(mesh.points[facets][:, :, 2], 1.0), axis=1)]
    qf = quadratic_facets(mesh, facets)
    mass = surface_mass_p2(mesh.points, qf)
    on = np.unique(qf)
    assert np.all(mass[on] > 0) and mass.sum() == pytest.approx(1.0, rel=1e-12)   # HRZ: positive
    load = traction_vector_p2(mesh.points, qf, np.array([0.0, 0.0, -2.0])).reshape(-1, 3)
    assert load[:, 2].sum() == pytest.approx(-2.0, rel=1e-12)
    vertices = on[on < mesh.n_vertices]
    assert np.all(load[vertices] == 0.0)             # a P2 triangle's vertex function: int = 0


def test_facet_weights_reproduce_affine_functions_and_interpolate_nodes():
    rng = np.random.default_rng(0)
    for k in (2, 3, 4):
        lam = rng.dirichlet(np.ones(k), size=20)
        w = facet_shape_functions(lam)
        np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-14)
        np.testing.assert_allclose(facet_shape_functions(np.eye(k))[:, :k], np.eye(k), atol=0)
    # the linear coordinate through the nodes of a segment [0, 1]: vertices 0, 1, midpoint 1/2
    lam = rng.dirichlet(np.ones(2), size=20)
    np.testing.assert_allclose(facet_shape_functions(lam) @ np.array([0.0, 1.0, 0.5]), lam[:, 1])


def test_p2_interpolation_between_nested_meshes_is_exact_for_quadratics():
    coarse = quadratic_mesh(*structured_square(2))
    fine = quadratic_mesh(*structured_square(4))
    P = interpolation_matrix(coarse.points, coarse.cells, fine.points)
    field = lambda x: 1 + x[:, 0] - 2 * x[:, 1] + 3 * x[:, 0] * x[:, 1] - x[:, 1] ** 2
    np.testing.assert_allclose(P @ field(coarse.points), field(fine.points), atol=1e-13)
    sub = linear_subcells(fine.points, fine.cells)
    assert sub.shape == (4 * len(fine.cells), 3)


@pytest.fixture(scope="module")
def circle_p2():
    qp = circle_square.PROBLEM.make(1, degree=2)
    return qp, solve(qp, "pdas", tol=1e-10)


def test_p2_scene_has_midpoint_constraints_supports_and_a_p_multigrid_step(circle_p2):
    qp, _ = circle_p2
    p1 = circle_square.PROBLEM.make(1)
    assert qp.mesh.degree == 2 and p1.mesh.degree == 1
    assert qp.mesh.cells.shape[1] == 6
    assert qp.m == 2 * p1.m - 1                      # every P2 node of the top edge
    # the held arc: its midpoints are prescribed like its vertices (-indent in y)
    assert qp.u_fixed.reshape(-1, 2)[:, 1].min() == pytest.approx(-0.017)
    n_held = np.count_nonzero(np.isclose(qp.u_fixed.reshape(-1, 2)[:, 1], -0.017))
    n_held1 = np.count_nonzero(np.isclose(p1.u_fixed.reshape(-1, 2)[:, 1], -0.017))
    assert n_held == 2 * n_held1 - 1
    # hierarchy: P1 level 0 -> P1 level 1 -> P2 on level 1
    P = qp.multilevel.prolongations
    assert len(P) == 2 and P[-1].shape == (qp.n, p1.n)


def test_p2_circle_square_exact_reference_agrees_with_a_qp_library(circle_p2):
    qp, exact = circle_p2
    assert exact.status == "converged"
    other = solve(qp, "clarabel", tol="high")
    assert other.status == "converged"
    np.testing.assert_allclose(other.p, exact.p, atol=1e-6 * exact.p.max())
    fields = contact_fields(qp, exact.u, exact.p)
    assert fields["cells"].shape == (4 * len(qp.mesh.cells), 3)
    assert np.all(np.isfinite(fields["von_mises"]))


@pytest.fixture(scope="module")
def cube_sphere_p2():
    """``level -> (qp, exact)``: cube–sphere (P2) at ``level`` and its exact reference
    (pdas, 1e-10), each made once in this module (the library comparison and the Hertz
    moments use the same solve)."""
    @functools.cache
    def made(level):
        qp = cube_sphere.PROBLEM.make(level, degree=2)
        return qp, solve(qp, "pdas", tol=1e-10)
    return made


def test_p2_cube_sphere_two_levels_exact_against_qp_libraries(cube_sphere_p2):
    for level, library in ((0, "osqp"), (1, "clarabel")):
        qp, exact = cube_sphere_p2(level)
        assert exact.status == "converged"
        other = solve(qp, library, tol="high")
        assert other.status == "converged", other.message
        assert abs(other.p.sum() / exact.p.sum() - 1) < 1e-4


def test_p2_hertz_at_the_finest_quick_levels(cube_sphere_p2):
    """Moments of the nodal forces against Hertz, 2D level 2 and 3D level 1 (P2)."""
    qp = circle_square.PROBLEM.make(2, degree=2)
    for qp, exact in ((qp, solve(qp, "pdas", tol=1e-10)), cube_sphere_p2(1)):
        assert exact.status == "converged"
        h = hertz_comparison(qp, exact.p)
        assert abs(h["dev_a_moment"]) < 0.05 and abs(h["dev_p0_moment"]) < 0.05, h


def test_p2_pressure_recovery_is_exact_for_constant_pressure():
    """The P1-aggregated pressure of consistent P2 forces of a constant traction is that
    traction, in 2D and in 3D (where ``p / mass`` would be 0 at the vertices)."""
    for qp in (circle_square.PROBLEM.make(1, degree=2), cube_sphere.PROBLEM.make(0, degree=2)):
        d = qp.dim
        pts = qp.mesh.points
        facets = qp.contact.facets
        from problems.fem.quadratic import FACET_INTEGRALS, _simplex_measures, quadratic_mesh as qm
        quad = qm(pts[:np.max(qp.mesh.cells[:, :d + 1]) + 1], qp.mesh.cells[:, :d + 1])
        qf = quadratic_facets(quad, facets)
        force = np.bincount(qf.ravel(), weights=(_simplex_measures(pts, facets)[:, None]
                                                 * FACET_INTEGRALS[d]).ravel(),
                            minlength=len(pts))[qp.contact.nodes]
        # interior of the surface (the ends see half a patch)
        pressure = qp.contact.pressure(force)
        x = qp.constrained_points()
        inner = np.all((x[:, :d - 1] > 0.2) & (x[:, :d - 1] < 0.8), axis=1)
        np.testing.assert_allclose(pressure[inner], 1.0, rtol=1e-12)


def test_p2_patch_test_pressure_is_uniform():
    """Flat blocks on non-matching meshes: the recovered P2 pressure is uniform to 3 %
    (P1's nodal pressure varies by ~20 % on the same meshes)."""
    for side in ("coarse", "fine"):
        qp = flat_blocks.PROBLEM.make(1, degree=2, constrained=side)
        r = solve(qp, "pdas", tol=1e-10)
        pr = qp.contact.pressure(r.p)[r.p > 0]
        assert (pr.max() - pr.min()) / pr.mean() < 0.03


def test_augmented_projection_on_p2_is_level_independent():
    n_o = []
    for level in (1, 2):
        r = solve(circle_square.PROBLEM.make(level, degree=2), "augmented_projection", tol="mid")
        assert r.status == "converged"
        assert r.stats["schur_kind"] == "multilevel"
        n_o.append(r.stats["n_outer"])
    assert n_o[1] <= 1.25 * n_o[0], n_o


def test_degree_is_validated_by_name():
    with pytest.raises(ParameterError, match="degree"):
        circle_square.PROBLEM.make(0, degree=3)
    with pytest.raises(ParameterError, match="degree.*coupling"):
        flat_blocks.PROBLEM.make(0, degree=2, coupling="stabilised")


def test_element_order_study_script_and_report(tmp_path, capsys):
    """The P1/P2 study's entry points on the smallest case: P1 at levels 0, 1 and P2 at
    level 0 against the P2 reference at level 1."""
    import pandas as pd

    from report.element_order import claims, main as report_main
    from workflows.studies.element_order.run import main as script

    out = tmp_path / "eo.csv"
    script(["--problem", "circle_square", "--levels", "0", "--reference-level", "1",
            "--time-limit", "60", "--out", str(out)])
    t = pd.read_csv(out)
    cmp = t[t.role == "compared"]
    assert list(zip(cmp.degree, cmp.level)) == [(1, 0), (1, 1), (2, 0)]
    assert (cmp.status == "converged").all()
    e = dict(zip(zip(cmp.degree, cmp.level), cmp.err_energy))
    # P1 level 1 lives in the reference's space up to the curved boundary: small error;
    # P2 level 0 has P1 level 1's nodes and beats it
    assert 0 < e[(2, 0)] < e[(1, 0)] and e[(1, 1)] < e[(1, 0)]
    report_main(["--tables", str(out), "--claims", str(tmp_path / "c.csv"),
                 "--figure", str(tmp_path / "f.png")])
    c = claims(t)
    assert bool(c["pass"].iloc[0])                      # every compared solve converged
    assert (tmp_path / "f.png").stat().st_size > 10_000
    for argv, refusal in (
            (["--problem", "flat_blocks", "--set", "coupling=stabilised"],
             "allowed: degree=1, or degree=2 with coupling in"),
            (["--problem", "laplace_nonmatching"], "not a contact problem"),
            (["--problem", "circle_square", "--set", "degree=2"], "'degree' is not allowed"),
            (["--problem", "circle_square", "--levels", "1"], "above every level (1)"),
            (["--problem", "circle_square", "--time-limit", "0"], "allowed: > 0")):
        args = {"--levels": "0", "--reference-level": "1", "--time-limit": "60",
                "--out": str(out)}
        args.update({k: v for k, v in zip(argv[::2], argv[1::2]) if k != "--set"})
        extra = argv[argv.index("--set"):argv.index("--set") + 2] if "--set" in argv else []
        with pytest.raises(SystemExit) as exit_:
            script([x for kv in args.items() for x in kv] + extra)
        assert exit_.value.code == 2
        assert refusal in capsys.readouterr().err
