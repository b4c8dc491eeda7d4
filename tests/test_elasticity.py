"""Tests of the P1 linear elasticity core (problems/fem/elasticity.py, thesis Sect. 2.1).

The stiffness matrix is checked against two independent codes on the same mesh:
scikit-fem's ``linear_elasticity`` form (matrix, ~1e-12) and NGSolve's C++ assembly
(matrix and the solution of a clamped body under body force, <= 1e-10).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.fem.elasticity import (
    barycentric_gradients, body_force_vector, boundary_facets, dirichlet_split,
    lame_parameters, lumped_surface_mass, rigid_body_modes, stiffness_matrix,
    strain_stress, traction_vector, von_mises,
)

E, NU = 2.5, 0.3


# --------------------------------------------------------------------------- meshes
def _jiggled(mesh, seed: int, amount: float = 0.2):
    """Points/cells of a skfem mesh with interior nodes moved (an unstructured patch)."""
    pts, cells = mesh.p.T.copy(), mesh.t.T.copy()
    interior = np.setdiff1d(np.arange(len(pts)), np.unique(boundary_facets(cells)))
    h = 1.0 / round(len(pts) ** (1.0 / pts.shape[1]))
    rng = np.random.default_rng(seed)
    pts[interior] += amount * h * rng.uniform(-1, 1, (interior.size, pts.shape[1]))
    return pts, cells


@pytest.fixture(scope="module")
def mesh2d():
    from skfem import MeshTri
    return _jiggled(MeshTri().refined(3), seed=1)


@pytest.fixture(scope="module")
def mesh3d():
    from skfem import MeshTet
    return _jiggled(MeshTet().refined(2), seed=2)


@pytest.fixture(params=["2d", "3d"])
def mesh(request, mesh2d, mesh3d):
    return mesh2d if request.param == "2d" else mesh3d


def _ngsolve_mesh(dim: int):
    import ngsolve  # a broken install must fail the test, not skip it
    from netgen.occ import unit_cube, unit_square
    geo = unit_square if dim == 2 else unit_cube
    return ngsolve.Mesh(geo.GenerateMesh(maxh=0.2 if dim == 3 else 0.1))


# --------------------------------------------------------------------------- material
def test_lame_parameters_match_223_and_plane_stress():
    lam, mu = lame_parameters(E, NU)
    assert lam == pytest.approx(E * NU / ((1 + NU) * (1 - 2 * NU)), rel=1e-15)
    assert mu == pytest.approx(E / (2 * (1 + NU)), rel=1e-15)
    lam_ps, mu_ps = lame_parameters(E, NU, plane_strain=False)
    assert lam_ps == pytest.approx(E * NU / (1 - NU ** 2), rel=1e-14)
    assert mu_ps == mu
    lam_a, mu_a = lame_parameters(np.array([1.0, 2.0]), np.array([0.2, 0.3]))
    assert lam_a.shape == mu_a.shape == (2,)


# --------------------------------------------------------------------------- stiffness
def test_stiffness_exactly_symmetric_with_rigid_body_kernel(mesh):
    pts, cells = mesh
    d = pts.shape[1]
    rng = np.random.default_rng(3)
    E_cell = rng.uniform(1.0, 100.0, len(cells))          # strongly varying material
    nu_cell = rng.uniform(0.0, 0.45, len(cells))
    K = stiffness_matrix(pts, cells, E_cell, nu_cell)
    assert K.shape == (len(pts) * d,) * 2
    assert (K != K.T).nnz == 0                              # exact, not approximate
    R = rigid_body_modes(pts)
    assert R.shape == (len(pts) * d, 3 if d == 2 else 6)
    rel = np.abs(K @ R).max() / (abs(K).max() * np.abs(R).max())
    assert rel < 1e-12
    # and K is positive definite on the complement: only rigid modes are in the kernel
    ev = np.linalg.eigvalsh(K.toarray())
    assert np.sum(ev < 1e-10 * ev[-1]) == R.shape[1]


def test_patch_test_linear_field_reproduced(mesh):
    pts, cells = mesh
    d = pts.shape[1]
    rng = np.random.default_rng(4)
    M, c = rng.normal(size=(d, d)), rng.normal(size=d)    # general affine field, incl. rotation
    u_exact = (pts @ M.T + c).ravel()
    K = stiffness_matrix(pts, cells, E, NU)
    bnodes = np.unique(boundary_facets(cells))
    fixed = (bnodes[:, None] * d + np.arange(d)).ravel()
    free, u_fix = dirichlet_split(len(pts) * d, fixed, u_exact[fixed])
    assert free.size > 0
    rhs = -(K @ u_fix)[free]
    u = u_fix.copy()
    u[free] = spla.spsolve(K[free][:, free].tocsc(), rhs)
    assert np.abs(u - u_exact).max() <= 1e-12 * np.abs(u_exact).max()
    eps, sigma = strain_stress(pts, cells, u, E, NU)
    lam, mu = lame_parameters(E, NU)
    sym = 0.5 * (M + M.T)
    assert np.allclose(eps, sym, rtol=0, atol=1e-12)
    assert np.allclose(sigma, lam * np.trace(sym) * np.eye(d) + 2 * mu * sym, rtol=0, atol=1e-11)


def test_two_bodies_give_block_diagonal_matrix(mesh2d):
    pts, cells = mesh2d
    shifted = pts + np.array([2.0, 0.0])
    both_pts = np.vstack([pts, shifted])
    both_cells = np.vstack([cells, cells + len(pts)])
    E_cell = np.r_[np.full(len(cells), 1.0), np.full(len(cells), 210.0)]
    nu_cell = np.r_[np.full(len(cells), 0.3), np.full(len(cells), 0.25)]
    K = stiffness_matrix(both_pts, both_cells, E_cell, nu_cell)
    K1 = stiffness_matrix(pts, cells, 1.0, 0.3)
    K2 = stiffness_matrix(shifted, cells, 210.0, 0.25)
    diff = K - sp.block_diag([K1, K2], format="csr")
    assert abs(diff).max() <= 1e-14 * abs(K).max()


@pytest.mark.parametrize("dim", [2, 3])
def test_matches_scikit_fem_linear_elasticity(dim, mesh2d, mesh3d):
    from skfem import Basis, ElementTetP1, ElementTriP1, ElementVector, MeshTet, MeshTri, asm
    from skfem.models.elasticity import linear_elasticity
    pts, cells = mesh2d if dim == 2 else mesh3d
    skmesh = (MeshTri if dim == 2 else MeshTet)(pts.T.copy(), cells.T.copy())
    basis = Basis(skmesh, ElementVector(ElementTriP1() if dim == 2 else ElementTetP1()))
    lam, mu = lame_parameters(E, NU)
    K_sk = asm(linear_elasticity(lam, mu), basis).tocsr()
    # skfem's nodal_dofs[c, node] is its DOF of (node, component c): map to node * d + c
    ours_to_sk = basis.nodal_dofs.T.ravel()
    K_sk = K_sk[ours_to_sk][:, ours_to_sk]
    K = stiffness_matrix(pts, cells, E, NU)
    assert abs(K - K_sk).max() <= 1e-12 * abs(K).max()


@pytest.mark.parametrize("dim", [2, 3])
def test_matches_ngsolve_on_netgen_mesh(dim):
    """THE cross-check: same mesh, same bilinear form, solve both, compare (<= 1e-10)."""
    import ngsolve as ng
    mesh = _ngsolve_mesh(dim)
    pts = np.array([v.point for v in mesh.vertices], dtype=float)
    cells = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)])
    assert pts.shape == (mesh.nv, dim) and cells.shape == (mesh.ne, dim + 1)
    lam, mu = lame_parameters(E, NU)                        # plane strain in 2D
    force = np.array([0.3, -1.0, 0.2][:dim])

    # NGSolve: VectorH1 order 1 (component-major blocks), clamped on the face x = 0
    # (netgen.occ names it "left" on unit_square but "back" on unit_cube)
    fes = ng.VectorH1(mesh, order=1, dirichlet="left" if dim == 2 else "back")
    u, v = fes.TnT()
    eps = lambda w: ng.Sym(ng.Grad(w))
    a = ng.BilinearForm(fes)
    a += (2 * mu * ng.InnerProduct(eps(u), eps(v)) + lam * ng.div(u) * ng.div(v)) * ng.dx
    a.Assemble()
    f = ng.LinearForm(fes)
    f += ng.InnerProduct(ng.CoefficientFunction(tuple(force)), v) * ng.dx
    f.Assemble()
    gfu = ng.GridFunction(fes)
    gfu.vec.data = a.mat.Inverse(fes.FreeDofs(), inverse="sparsecholesky") * f.vec
    # ng_dof[node * d + c]: NGSolve's DOF of (vertex node, component c)
    ng_dof = np.array([fes.GetDofNrs(ng.NodeId(ng.VERTEX, k)) for k in range(mesh.nv)]).ravel()
    assert np.array_equal(np.sort(ng_dof), np.arange(fes.ndof))
    ng_free = np.array(list(fes.FreeDofs()), dtype=bool)[ng_dof]
    u_ng = gfu.vec.FV().NumPy()[ng_dof]
    vals, cols, indptr = a.mat.CSR()
    K_ng = sp.csr_matrix((np.array(vals), np.array(cols), np.array(indptr)),
                         shape=(fes.ndof, fes.ndof))[ng_dof][:, ng_dof]

    # ours, on the same points and cells
    K = stiffness_matrix(pts, cells, E, NU)
    F = body_force_vector(pts, cells, force)
    clamped = np.flatnonzero(np.isclose(pts[:, 0], 0.0))
    free, u_fix = dirichlet_split(K.shape[0], (clamped[:, None] * dim + np.arange(dim)).ravel())
    assert np.array_equal(free, np.flatnonzero(ng_free))   # same Dirichlet face
    u_ours = u_fix.copy()
    u_ours[free] = spla.spsolve(K[free][:, free].tocsc(), F[free])

    assert abs(K - K_ng).max() <= 1e-12 * abs(K).max()
    assert np.abs(F - f.vec.FV().NumPy()[ng_dof]).max() <= 1e-13 * np.abs(F).max()
    rel = np.linalg.norm(u_ours - u_ng) / np.linalg.norm(u_ng)
    print(f"NGSolve {dim}D: {mesh.nv} nodes, |K-K_ng|/|K| = {abs(K - K_ng).max() / abs(K).max():.2e}, "
          f"|u-u_ng|/|u_ng| = {rel:.2e}")
    assert rel <= 1e-10, rel


# --------------------------------------------------------------------------- loads, surfaces
def test_boundary_facets_and_surface_measures(mesh):
    pts, cells = mesh
    d = pts.shape[1]
    facets = boundary_facets(cells, pts)
    n_per_side = 8 if d == 2 else 4                         # refined(3) square, refined(2) cube
    assert facets.shape == ((4 * n_per_side, 2) if d == 2 else (6 * 2 * n_per_side ** 2, 3))
    assert np.array_equal(np.sort(boundary_facets(cells), axis=1), np.sort(facets, axis=1))
    # outward orientation on the convex unit square/cube
    e1 = pts[facets[:, 1]] - pts[facets[:, 0]]
    normal = (np.stack([e1[:, 1], -e1[:, 0]], 1) if d == 2
              else np.cross(e1, pts[facets[:, 2]] - pts[facets[:, 0]]))
    centre = pts[facets].mean(axis=1) - 0.5
    assert np.all(np.einsum("ij,ij->i", normal, centre) > 0)
    mass = lumped_surface_mass(pts, facets)
    assert mass.shape == (len(pts),)
    assert mass.sum() == pytest.approx(4.0 if d == 2 else 6.0, rel=1e-14)
    assert np.all(mass[np.setdiff1d(np.arange(len(pts)), facets)] == 0)
    assert lumped_surface_mass(pts, facets, n_nodes=len(pts) + 5).shape == (len(pts) + 5,)
    traction = np.arange(1.0, d + 1)
    T = traction_vector(pts, facets, traction).reshape(-1, d)
    assert np.allclose(T.sum(axis=0), mass.sum() * traction, rtol=1e-14)
    assert np.allclose(T, mass[:, None] * traction, rtol=1e-14)   # same lumping


def test_body_force_total_and_per_cell(mesh):
    pts, cells = mesh
    d = pts.shape[1]
    force = -np.arange(1.0, d + 1)
    F = body_force_vector(pts, cells, force).reshape(-1, d)
    assert np.allclose(F.sum(axis=0), force * 1.0, rtol=1e-13)    # unit square / cube
    _, vol = barycentric_gradients(pts, cells)
    per_cell = np.outer(np.arange(len(cells)) % 2, force)
    F2 = body_force_vector(pts, cells, per_cell).reshape(-1, d)
    assert np.allclose(F2.sum(axis=0), vol[1::2].sum() * force, rtol=1e-13)


# --------------------------------------------------------------------------- post-processing
def test_von_mises_known_states(mesh):
    pts, cells = mesh
    d = pts.shape[1]
    lam, mu = lame_parameters(E, NU)
    s = 0.01
    if d == 3:   # uniaxial stress: sigma = diag(s, 0, 0) -> von Mises = s
        strain = np.diag([s / E, -NU * s / E, -NU * s / E])
        expected = s
    else:        # plane strain, u = (a x, 0): sigma_xx = (lam+2mu) a, sigma_yy = sigma_zz = lam a
        strain = np.diag([s, 0.0])
        expected = 2 * mu * s
    u = pts @ strain.T
    vm = von_mises(pts, cells, u, E, NU)
    assert vm.shape == (len(cells),)
    assert np.allclose(vm, expected, rtol=1e-12)
    assert np.allclose(von_mises(pts, cells, u.ravel() + 1.0, E, NU), expected, rtol=1e-12)


def test_dirichlet_split_semantics():
    free, u_fix = dirichlet_split(6, [4, 1, 4], [2.0, -1.0, 2.0])
    assert np.array_equal(free, [0, 2, 3, 5])
    assert np.array_equal(u_fix, [0, -1.0, 0, 0, 2.0, 0])
    free, u_fix = dirichlet_split(3, np.array([], dtype=int), 0.0)
    assert np.array_equal(free, [0, 1, 2]) and not u_fix.any()


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("call, name", [
    (lambda m: lame_parameters(0.0, 0.3), "'E'"),
    (lambda m: lame_parameters(1.0, 0.5), "'nu'"),
    (lambda m: lame_parameters(1.0, -1.0), "'nu'"),
    (lambda m: stiffness_matrix(m[0], m[1], np.ones(3), 0.3), "'E'"),
    (lambda m: stiffness_matrix(m[0], m[1], 1.0, np.full(len(m[1]), 0.7)), "'nu'"),
    (lambda m: stiffness_matrix(m[0][:, :1], m[1], 1.0, 0.3), "'points'"),
    (lambda m: stiffness_matrix(m[0], m[1][:, :2], 1.0, 0.3), "'cells'"),
    (lambda m: stiffness_matrix(m[0], m[1] + len(m[0]), 1.0, 0.3), "'cells'"),
    (lambda m: stiffness_matrix(m[0], m[1].astype(float), 1.0, 0.3), "'cells'"),
    (lambda m: stiffness_matrix(m[0], np.array([[0, 1, 1]]), 1.0, 0.3), "'cells'"),
    (lambda m: body_force_vector(m[0], m[1], [1.0, 2.0, 3.0]), "'force'"),
    (lambda m: traction_vector(m[0], boundary_facets(m[1]), np.ones((2, 2))), "'traction'"),
    (lambda m: lumped_surface_mass(m[0], m[1], None), "'facets'"),
    (lambda m: lumped_surface_mass(m[0], boundary_facets(m[1]), 0), "'n_nodes'"),
    (lambda m: boundary_facets(np.zeros((3, 5), dtype=int)), "'cells'"),
    (lambda m: strain_stress(m[0], m[1], np.zeros(5), 1.0, 0.3), "'u'"),
    (lambda m: dirichlet_split(0, [0]), "'n_dofs'"),
    (lambda m: dirichlet_split(4, [4]), "'fixed_dofs'"),
    (lambda m: dirichlet_split(4, [1, 2], [1.0]), "'fixed_values'"),
    (lambda m: dirichlet_split(4, [1, 1], [1.0, 2.0]), "'fixed_values'"),
])
def test_bad_input_names_the_parameter(call, name, mesh2d):
    with pytest.raises(ValueError, match=name):
        call(mesh2d)


def test_a_half_disk_hierarchy_keeps_its_chord_and_puts_its_arc_on_the_circle():
    """The shared half-disk mesher (problems.fem.mesh): every level's boundary nodes lie on
    the arc or on the chord, the chord's new nodes stay on it, and each level's first nodes
    are the coarser level's (nested, up to rounding)."""
    from problems.fem.mesh import half_disk_hierarchy

    center, radius = np.array([0.0, 1.0]), 0.5
    h = half_disk_hierarchy(center, radius, 2, 0.15, side="upper")
    for k, (points, cells) in enumerate(zip(h.points, h.cells)):
        assert points[:, 1].min() >= center[1] - 1e-12            # the upper half
        boundary = np.unique(boundary_facets(cells))
        x = points[boundary]
        on_arc = np.isclose(np.linalg.norm(x - center, axis=1), radius, rtol=1e-12)
        on_chord = np.isclose(x[:, 1], center[1], atol=1e-12)
        assert (on_arc | on_chord).all(), k
        if k:
            np.testing.assert_allclose(points[:len(h.points[k - 1])], h.points[k - 1], rtol=0,
                                       atol=1e-14)     # the arc's old nodes projected again
    with pytest.raises(ValueError, match="parameter 'side': 'left' is not allowed"):
        half_disk_hierarchy(center, radius, 0, 0.15, side="left")


def test_a_scene_narrows_the_couplings_it_offers():
    from problems.fem.stabilised import COUPLINGS, coupling_parameters

    coupling = coupling_parameters(("nodal", "two_pass"))[0]
    assert coupling.choices == ("nodal", "two_pass") and coupling_parameters()[0].choices == COUPLINGS
    with pytest.raises(ValueError, match="parameter 'choices'"):
        coupling_parameters(("nodal", "glued"))
