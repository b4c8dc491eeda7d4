"""The Hertz-Mindlin scene (problems/hertz_mindlin.py): graded nested grids, matched contact
faces with the paraboloid's gap, Hertz's contact at level 0, and the frictional solvers
agreeing on its Tresca steps."""
import numpy as np
import pytest

from problems import hertz_mindlin as hm
from problems.fem.fields import in_plane
from problems.kkt import energy_error
from problems.spec import ParameterError, problems
from reference.cattaneo_mindlin import stick_zone_ratio
from reference.hertz import contact_size, moment_estimate, peak_pressure
from solvers.interface import solve
from solvers.kernels.tresca import path_for_ratio
from workflows.studies.friction.run import partial_slip

SCENE = problems()["hertz_mindlin"]


@pytest.mark.parametrize("level", [0, 1, 2])
def test_levels_are_nested_and_graded(level):
    core, cells = 0.125, 5
    coarse, fine = hm.half_axis(level, core, cells), hm.half_axis(level + 1, core, cells)
    assert np.all(np.isin(coarse, fine))                         # nested
    new = np.setdiff1d(fine, coarse)                             # every new node a midpoint
    mid = 0.5 * (coarse[:-1] + coarse[1:])
    assert np.allclose(new, mid[np.searchsorted(coarse, new) - 1])
    h = np.diff(fine)
    in_core = fine[1:] <= core + 1e-12
    assert np.allclose(h[in_core], core / cells / 2 ** (level + 1))   # uniform core
    ratio = h[1:] / h[:-1]
    assert ratio.max() <= 4 + 1e-9 and ratio.min() >= 1 - 1e-9    # graded outwards
    assert fine[-1] == pytest.approx(hm.extent(core, cells))


def test_contact_faces_match_and_the_gap_is_the_paraboloids():
    qp = SCENE.make(0, indent=0.0, radius=2.0)
    x = qp.constrained_points()
    assert np.all(np.abs(x[:, :2]) <= 0.125 + 1e-12) and np.allclose(x[:, 2], 0.0)
    assert np.allclose(qp.g, (x[:, 0] ** 2 + x[:, 1] ** 2) / (2 * 2.0), rtol=0, atol=1e-15)
    # each constrained node's opposing point is one node of the tip straight above it
    tip = qp.mesh.points[qp.mesh.body_of_node == 1]
    above = {tuple(np.round(p[:2], 12)) for p in tip if p[2] < 0.1}
    assert {tuple(np.round(p[:2], 12)) for p in x} <= above


def test_hertz_contact_at_level_0():
    qp = SCENE.make(0)
    res = solve(qp, "pdas", tol=1e-12)
    assert res.status == "converged"
    P = res.p.sum()
    _, a, p0 = moment_estimate("point", in_plane(qp), res.p)
    a_hertz = contact_size("point", P, qp.hertz.radius, qp.hertz.E_star)
    # 4.6 constrained nodes across the radius: a within 3 %, the peak within 6 %
    assert abs(a / a_hertz - 1) < 0.03
    assert abs(p0 / peak_pressure("point", P, a_hertz) - 1) < 0.06
    assert 0.1 < a < 0.125 < hm.extent(0.125, 5) / 6    # in the core, far from the sides


@pytest.fixture(scope="module")
def tresca_path():
    """The reference's Tresca path at level 0 scaled to Q/(mu P) = 0.7."""
    qp = SCENE.make(0, friction="tresca", mu=0.5, shift=0.003)
    return path_for_ratio(qp, 0.7)


def test_cattaneo_mindlin_at_level_0(tresca_path):
    fields, _ = partial_slip(tresca_path[-1], 0.7)
    assert fields["ratio_reached"] == pytest.approx(0.7, rel=1e-5)
    # unresolved (69 contact nodes), yet within 6 % of (1 - Q/(mu P))^(1/3)
    assert abs(fields["c_over_a"] / stick_zone_ratio(0.7, "point") - 1) < 0.06
    assert fields["traction_l2"] < 0.15
    # the bodies of one material: the normal step leaves the zones concentric
    assert abs(fields["stick_offset"]) < 0.02


@pytest.mark.parametrize("solver", ["tnnmg", "semismooth_newton"])
def test_frictional_solvers_agree_with_the_exact_reference(tresca_path, solver):
    step = tresca_path[-1]
    res = solve(step.qp, solver, tol="high")
    assert res.status == "converged", res.message
    assert energy_error(step.qp, res.u, step.solution.u) <= 1e-8     # the study's bar


@pytest.mark.parametrize("key,value", [("core", 0.01), ("core_cells", 0), ("radius", 0.0),
                                       ("indent", -0.01)])
def test_bad_parameters_name_the_parameter(key, value):
    with pytest.raises(ParameterError, match=f"'{key}'"):
        SCENE.make(0, **{key: value})
