"""The roll stack scene (thesis Sect. 9.3) at its coarsest level: geometry, equilibrium,
symmetry, unit independence and the solvers.

Tolerances are scale-free: the verification (:func:`problems.kkt.kkt_residuals`) divides
every KKT residual by the size of the terms it compares (forces by ``max(|f|, |Au|,
|B'p|)``, gaps by ``max(|Bu|, |g|)``), and the library adapters hand their solvers the
Jacobi-scaled, unit-load problem (``solvers/kernels/scaling.py``), so E ~ 2e11 Pa and
displacements ~ 1e-4 m need no special settings; the same scene in mm/N/MPa gives the
same residuals.
"""
import numpy as np
import pytest

from problems.fem.elasticity import boundary_facets
from problems.fem.fields import contact_state
from problems.fem.two_body import assemble_two_body, spring_forces
from problems.roll_stack import PROBLEM, half_disk_section, roll_meshes, scene
from problems.spec import ParameterError
from reference.roll_stack import RollStack
from solvers.interface import solve


def solved(level=0, solver="pdas", **params):
    p = PROBLEM.options(**params)
    sc = scene(level, p)
    qp = assemble_two_body(sc, 0)
    return sc, qp, solve(qp, solver, **({"method": "kkt"} if solver == "pdas" else {}))


@pytest.fixture(scope="module")
def quarter():
    return solved()


def work_roll_weight(p, quarter_model=True):
    """Weight of the meshed work roll (volume of the mesh times the weight density)."""
    (pw, cw), *_ = roll_meshes(0, p)
    x = pw[cw]
    vol = np.abs(np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]),
                           x[:, 3] - x[:, 0])).sum() / 6
    return vol * p.weight_density


def test_crown_geometry():
    """Every work-roll barrel surface node lies on r = 0.35 - 75e-6 x^2 (to round-off)."""
    p = PROBLEM.options()
    (pw, cw), (pb, cb), _, _ = roll_meshes(1, p)
    bnd = np.unique(boundary_facets(cw))
    x, r = pw[bnd, 0], np.hypot(pw[bnd, 1], pw[bnd, 2])
    on = (x < 1.0 - 1e-9) & (r > 0.349)          # the surface (inner nodes: r < 0.3485)
    assert on.sum() > 100
    np.testing.assert_allclose(r[on], 0.35 - 75e-6 * x[on] ** 2, rtol=0, atol=1e-12)
    s = RollStack()
    bnd = np.unique(boundary_facets(cb))
    x, r = pb[bnd, 0], np.hypot(pb[bnd, 1], pb[bnd, 2] - 1.1)
    on = (x < 0.95 - 1e-9) & (r > 0.749)
    np.testing.assert_allclose(r[on], 0.75 - s.relief_drop(x[on]), rtol=0, atol=1e-12)


def test_section_is_graded_and_valid():
    sec = half_disk_section(0.35, 1e-3, 0.012, 0.04)
    top = sec.points[(np.hypot(*sec.points.T) > 0.35 - 1e-12) & (sec.points[:, 1] > 0.34)]
    spacing = np.diff(np.sort(top[:, 0]))
    assert spacing[:10].max() <= 1e-3 + 1e-12           # fine at the contact line
    assert sec.node(0.0, 0.0) is not None and np.allclose(sec.points[sec.node(0.0, 0.0)], 0)


def test_equilibrium_and_springs(quarter):
    """Contact resultant = strip force - work roll weight (0.5 %); springs < 1e-4 F."""
    sc, qp, res = quarter
    assert res.status == "converged"
    p = PROBLEM.options()
    contact = 4 * contact_state(qp, res.u, res.p)["force"][2]
    expected = p.force - 4 * work_roll_weight(p)
    assert abs(contact / expected - 1) < 5e-3
    springs = 4 * spring_forces(sc, qp, res.u)
    assert np.abs(springs).max() < 1e-4 * p.force


def sag(qp, u, ell=1.0):
    """Vertical displacement of the work roll's and the backup roll's axes at x = 0."""
    d = qp.full_displacement(u)
    out = []
    for body, z in ((0, 0.0), (1, 1.1 * ell)):
        on = np.flatnonzero(qp.mesh.body_of_node == body)
        out.append(d[on[np.argmin(np.linalg.norm(qp.mesh.points[on] - [0, 0, z], axis=1))], 2])
    return np.array(out)


def test_quarter_equals_half_model(quarter):
    _, qq, rq = quarter
    _, qh, rh = solved(solver="osqp", model="half")     # verified; faster than pdas here
    assert rh.status == "converged"
    sq, sh = sag(qq, rq.u), sag(qh, rh.u)
    np.testing.assert_allclose(sq, sh, rtol=1e-2)
    assert qh.m > qq.m


def test_units_do_not_matter(quarter):
    _, qq, rq = quarter
    _, qm, rm = solved(units="mm")
    assert rm.status == "converged"
    np.testing.assert_allclose(sag(qm, rm.u, 1e3) / 1e3, sag(qq, rq.u), rtol=1e-6)


def test_bad_parameters_are_refused():
    with pytest.raises(ParameterError, match="force"):
        PROBLEM.options(force=-1.0)
    with pytest.raises(ParameterError, match="model"):
        PROBLEM.options(model="eighth")


#: status of every solver on the coarsest level. The floating work roll makes A nearly
#: singular (springs only, ~1e-9 of the elastic stiffness): a plain factorisation of A
#: returns metres of rigid motion where the answer is 0.1 mm, so pdas's dual route keeps
#: the roll's translation apart (FloatingCholesky) and is exact; the augmented
#: projection treats it by FETI's natural coarse space (the roll's equilibrium in every
#: projection, A-hat on the complement of its translation).
EXPECTED = {"pdas": "converged", "osqp": "converged", "piqp": "converged",
            "semismooth_newton": "converged", "proxsuite": "inaccurate",
            "clarabel": "inaccurate", "qpalm": "inaccurate",
            "augmented_projection": "converged"}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_solvers_on_the_coarsest_level(quarter, name):
    _, qp, ref = quarter
    opts = {"method": "kkt"} if name == "pdas" else {}
    res = solve(qp, name, **opts)
    assert res.status == EXPECTED[name], res.message
    if res.status == "skipped":
        assert "floating" in res.message and res.iterations == 0
        return
    # even the inaccurate ones agree with the reference in the contact force to 1e-4
    assert abs(res.p.sum() / ref.p.sum() - 1) < 1e-4


def test_alg84_options_without_a_coarse_space_are_refused_by_name(quarter):
    """The floating roll needs the equality in the projection (SMALBE): Alg. 8.3 and the
    face-CG phase have none, and say so naming the parameter."""
    _, qp, _ = quarter
    with pytest.raises(ParameterError, match="parameter 'projection': 'richardson'"):
        solve(qp, "augmented_projection", projection="richardson")
    with pytest.raises(ParameterError, match="parameter 'accelerate': 'face_cg'.*allowed: none"):
        solve(qp, "augmented_projection", accelerate="face_cg")


def test_pdas_schur_is_exact_on_the_floating_roll(quarter):
    """The dual route (A factorised without the work roll's floating mode) agrees with the
    KKT-LU PDAS; before the floating mode was kept apart it stalled at KKT ~4e-5."""
    _, qp, ref = quarter
    res = solve(qp, "pdas", method="schur", tol=1e-12)
    assert res.status == "converged", res.message
    np.testing.assert_allclose(res.p, ref.p, rtol=0, atol=1e-9 * ref.p.max())
