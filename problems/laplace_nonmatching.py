"""The Laplace problem on a non-matching grid (thesis Ch. 6, Sects. 6.1-6.6).

Omega = (0, 1)^2 is split by the interface Gamma_C = {x = 1/2} into
Omega_1 = (0, 1/2) x (0, 1) and Omega_2 = (1/2, 1) x (0, 1), meshed
independently by structured P1 triangulations with mesh sizes in the ratio
``ratio`` (default 2:3, not a simple multiple, so the interface nodes of the two
sides match only at every second coarse node). We solve ``-Laplace(u) = f`` with
Dirichlet data from an exact solution:

* ``sin10x``: u = sin(10 x), the example of Sect. 6.6. Its flux across
  x = 1/2 is 10 cos(5) != 0, so the interface matters. (Across a horizontal
  interface, d/dy = 0 and every variant would look alike.)
* ``linear``: u = 1 + 2 x - y, f = 0: a patch test. The conforming grid
  reproduces it to round-off; the non-matching variants do not, and what they
  commit is the interface's own error.

Variants (the interface coupling):

* ``conforming``: one matching grid (both subdomains at the coarse side's mesh
  size, interface nodes shared) -- the baseline.
* ``nodal``: nodal constraints (Def. 6.11): at every interface node x_i of the
  *constrained* side, u_constrained(x_i) = u_other(x_i), the other side's trace
  evaluated by linear interpolation. No stabilisation; Theorem 6.17 proves only
  O(h^1/2) in H1.
* ``mortar``: the thesis's yardstick (Sect. 6.1, Remark 6.8): the jump is
  orthogonal to a multiplier space on the constrained (non-mortar) side,
  standard P1 multipliers modified at the Dirichlet end points.
* ``stabilised_a0.5``, ``stabilised_a1``: the nodal constraints plus the
  consistent penalty (6.18) on the jump at the *other* side's interface nodes,
  with the lumped interface mass of Sect. 6.5,
  ``sum_j [u](y_j) [v](y_j) sum_{E ∋ y_j} h_E^(-2 alpha) |E| / 2``; Theorem 6.24 /
  Remark 6.25 give the optimal O(h) in H1 for alpha = 1.

Naming: the thesis calls the side whose nodes carry the constraints the
"master" (contact mechanics would call it the slave). Here it is the
*constrained* side, chosen by the parameter ``constrained`` (``coarse`` = the
left subdomain, ``fine`` = the right one); the penalty acts on the other side.
The default, ``coarse``, is the harder and more instructive case: the finer
side's interface nodes are the "hanging" ones the stabilisation is for. The
study measures both sides.

The constraints are imposed exactly by elimination: u = P w + u_0, where w
holds the free unknowns, the constrained interface values are the interpolated
other-side values, and u_0 carries the Dirichlet data. The reduced operator
P^T A_s P is what "definite" refers to; it equals the kernel-restricted operator
of the saddle-point system of Sect. 6.5.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from skfem import Basis, ElementTriP1, Functional, LinearForm, MeshTri, asm
from skfem.models.poisson import laplace

from problems.spec import Options, Parameter, ParameterError, ProblemSpec

VARIANTS = ("conforming", "nodal", "stabilised_a0.5", "stabilised_a1", "mortar")
CASES = ("sin10x", "linear")
INTERFACE_X = 0.5


# --- exact solutions -------------------------------------------------------

def exact_solution(case: str, x: np.ndarray, y: np.ndarray):
    """Return ``(u, du/dx, du/dy, f)`` of the named case at points ``(x, y)``.

    ``f = -Laplace(u)``. Shapes follow ``x``.
    """
    if case == "sin10x":
        return (np.sin(10 * x), 10 * np.cos(10 * x), np.zeros_like(x), 100 * np.sin(10 * x))
    if case == "linear":
        return (1 + 2 * x - y, 2 + 0 * x, -1 + 0 * x, np.zeros_like(x))
    raise ParameterError(f"parameter 'case': {case!r} is not allowed; allowed: one of {', '.join(CASES)}")


# --- meshes ----------------------------------------------------------------

def parse_ratio(text: str) -> tuple[int, int]:
    """``"2:3"`` -> (2, 3): mesh cells per unit length of the coarse : fine side."""
    try:
        a, b = (int(s) for s in str(text).split(":"))
    except ValueError:
        raise ParameterError(f"parameter 'ratio': {text!r} is not allowed; allowed: 'p:q' with "
                             "integers 1 <= p <= q <= 16, e.g. '2:3'") from None
    if not (1 <= a <= b <= 16):
        raise ParameterError(f"parameter 'ratio': {text!r} is not allowed; allowed: 'p:q' with "
                             "integers 1 <= p <= q <= 16, e.g. '2:3'")
    return a, b


def subdomain_mesh(x0: float, x1: float, cells_per_unit: int) -> MeshTri:
    """Structured P1 mesh of (x0, x1) x (0, 1) with spacing 1/cells_per_unit."""
    nx = int(round((x1 - x0) * cells_per_unit))
    return MeshTri.init_tensor(np.linspace(x0, x1, nx + 1), np.linspace(0.0, 1.0, cells_per_unit + 1))


def cells_per_unit(level: int, ratio: tuple[int, int]) -> tuple[int, int]:
    """Cells per unit length of the coarse (left) and fine (right) subdomain.

    Level L has ``p * 2^(L+1)`` and ``q * 2^(L+1)`` cells per unit length; with
    the default 2:3 the fine side's h is 1/6, 1/12, ..., 1/384 at L = 0..6.
    """
    return ratio[0] * 2 ** (level + 1), ratio[1] * 2 ** (level + 1)


# --- interface coupling ----------------------------------------------------

def interface_nodes(mesh: MeshTri, x: float = INTERFACE_X, tol: float = 1e-12) -> np.ndarray:
    """Nodes of ``mesh`` on the line x = const, sorted by y."""
    nodes = np.flatnonzero(np.abs(mesh.p[0] - x) < tol)
    return nodes[np.argsort(mesh.p[1, nodes])]


def trace_interpolation(y_from: np.ndarray, y_to: np.ndarray) -> sp.csr_matrix:
    """Matrix T with ``(T v)_i = v_h(y_to[i])`` for the piecewise linear ``v_h``
    with nodal values ``v`` at the sorted points ``y_from`` (the 1D trace space of
    a P1 mesh on a straight interface, Sect. 6.4)."""
    if np.any(np.diff(y_from) <= 0):
        raise ValueError("y_from must be strictly increasing")
    k = np.clip(np.searchsorted(y_from, y_to, side="right") - 1, 0, len(y_from) - 2)
    t = (y_to - y_from[k]) / (y_from[k + 1] - y_from[k])
    if np.any(t < -1e-12) or np.any(t > 1 + 1e-12):
        raise ValueError("y_to lies outside the range of y_from")
    rows = np.repeat(np.arange(len(y_to)), 2)
    cols = np.stack([k, k + 1], axis=1).ravel()
    vals = np.stack([1 - t, t], axis=1).ravel()
    T = sp.csr_matrix((vals, (rows, cols)), shape=(len(y_to), len(y_from)))
    T.eliminate_zeros()
    return T


def lumped_interface_weights(y: np.ndarray, alpha: float) -> np.ndarray:
    """``sum_{E ∋ y_j} h_E^(-2 alpha) |E| / 2`` for the sorted interface nodes
    ``y`` (the lumped, h_E-weighted mass C-bar^{-1} of Sect. 6.5)."""
    h = np.diff(y)
    w_edge = h ** (1 - 2 * alpha) / 2
    w = np.zeros(len(y))
    w[:-1] += w_edge
    w[1:] += w_edge
    return w


def mortar_coupling(y_c: np.ndarray, y_o: np.ndarray, gauss_points: int = 3):
    """Mortar condition int_Gamma (u_c - u_o) mu ds = 0 for all multipliers mu,
    solved for the constrained (non-mortar) side's interior interface values.

    Multipliers: the constrained side's interior hat functions, the first and
    last extended by the end hats (constant on the end elements), the standard
    modification at Dirichlet end points, so the multiplier space holds the
    constants. Integrals are exact: Gauss quadrature on the merged 1D mesh.

    Returns ``(T_other, T_ends)`` with
    ``u_c[1:-1] = T_other @ u_o + T_ends @ u_c[[0, -1]]``.
    """
    breaks = np.union1d(y_c, y_o)
    xg, wg = np.polynomial.legendre.leggauss(gauss_points)
    a, b = breaks[:-1, None], breaks[1:, None]
    yq = (0.5 * (a + b) + 0.5 * (b - a) * xg).ravel()
    wq = (0.5 * (b - a) * wg).ravel()
    hats_c = trace_interpolation(y_c, yq).toarray()      # hat functions at the quadrature points
    hats_o = trace_interpolation(y_o, yq).toarray()
    mu = hats_c[:, 1:-1].copy()
    mu[:, 0] += hats_c[:, 0]
    mu[:, -1] += hats_c[:, -1]
    M_c = mu.T @ (wq[:, None] * hats_c)
    M_o = mu.T @ (wq[:, None] * hats_o)
    inner = M_c[:, 1:-1]
    T_other = np.linalg.solve(inner, M_o)
    T_ends = -np.linalg.solve(inner, M_c[:, [0, -1]])
    return sp.csr_matrix(T_other), sp.csr_matrix(T_ends)


@dataclass
class Discretisation:
    """The assembled non-matching problem before elimination.

    ``A`` and ``f`` are block-diagonal over the meshes in ``meshes`` (global
    numbering: mesh 0's nodes first). ``constraint`` maps the global vector to
    the values the constrained interface nodes must take; ``penalty`` is the
    stabilisation (6.18) as a global matrix (zero for ``nodal``).
    """

    meshes: list
    offsets: np.ndarray
    A: sp.csr_matrix
    f: np.ndarray
    penalty: sp.csr_matrix
    dirichlet: np.ndarray
    dirichlet_values: np.ndarray
    constrained: np.ndarray
    constraint: sp.csr_matrix
    h: float

    @property
    def n_nodes(self) -> int:
        return int(self.offsets[-1])


def assemble(level: int, case: str, variant: str, ratio: tuple[int, int],
             constrained_side: str) -> Discretisation:
    """Meshes, block stiffness, load, Dirichlet data, constraints and penalty."""
    n_coarse, n_fine = cells_per_unit(level, ratio)
    if variant == "conforming":
        meshes = [subdomain_mesh(0.0, INTERFACE_X, n_coarse), subdomain_mesh(INTERFACE_X, 1.0, n_coarse)]
    else:
        meshes = [subdomain_mesh(0.0, INTERFACE_X, n_coarse), subdomain_mesh(INTERFACE_X, 1.0, n_fine)]
    sizes = [m.p.shape[1] for m in meshes]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    blocks, loads, dirichlet, dvals = [], [], [], []
    for mesh, off in zip(meshes, offsets):
        basis = Basis(mesh, ElementTriP1(), intorder=4)
        blocks.append(asm(laplace, basis))
        xq = basis.global_coordinates()
        fq = exact_solution(case, xq[0], xq[1])[3]
        loads.append(asm(_source, basis, f=fq))
        # the outer boundary; the interface's end points lie on it and stay Dirichlet
        bnodes = mesh.boundary_nodes()
        on_interface = np.abs(mesh.p[0, bnodes] - INTERFACE_X) < 1e-12
        bnodes = np.union1d(bnodes[~on_interface], interface_nodes(mesh)[[0, -1]])
        dirichlet.append(bnodes + off)
        dvals.append(exact_solution(case, mesh.p[0, bnodes], mesh.p[1, bnodes])[0])
    A = sp.block_diag(blocks, format="csr")
    f = np.concatenate(loads)
    dirichlet = np.concatenate(dirichlet)
    dirichlet_values = np.concatenate(dvals)

    n = offsets[-1]
    left = interface_nodes(meshes[0]) + offsets[0]
    right = interface_nodes(meshes[1]) + offsets[1]
    yl, yr = meshes[0].p[1, left - offsets[0]], meshes[1].p[1, right - offsets[1]]
    penalty = sp.csr_matrix((n, n))
    if variant == "conforming":
        # shared interface nodes: right's interface node == left's (same y)
        constrained, other, T = right[1:-1], left, trace_interpolation(yl, yr[1:-1])
    else:
        if constrained_side == "coarse":
            (c_nodes, c_y), (o_nodes, o_y) = (left, yl), (right, yr)
        else:
            (c_nodes, c_y), (o_nodes, o_y) = (right, yr), (left, yl)
        constrained, other, T = c_nodes[1:-1], o_nodes, trace_interpolation(o_y, c_y[1:-1])
        if variant == "mortar":
            T_other, T_ends = mortar_coupling(c_y, o_y)
            other = np.concatenate([o_nodes, c_nodes[[0, -1]]])
            T = sp.hstack([T_other, T_ends]).tocsr()
        if variant.startswith("stabilised_a"):
            alpha = float(variant.removeprefix("stabilised_a"))
            # jump at the other side's nodes: [u](y_j) = u_other(y_j) - u_constrained trace(y_j)
            Tc = trace_interpolation(c_y, o_y)
            jump = (sp.csr_matrix((np.ones(len(o_nodes)), (np.arange(len(o_nodes)), o_nodes)),
                                  shape=(len(o_nodes), n))
                    - _embed_columns(Tc, c_nodes, n))
            W = sp.diags(lumped_interface_weights(o_y, alpha))
            penalty = (jump.T @ W @ jump).tocsr()
    constraint = _embed_columns(T, other, n)
    h = 1.0 / (n_coarse if variant == "conforming" else n_fine)
    return Discretisation(meshes, offsets, A, f, penalty, dirichlet, dirichlet_values,
                          constrained, constraint, h)


@LinearForm
def _source(v, w):
    return w["f"] * v


def _embed_columns(M: sp.spmatrix, columns: np.ndarray, n: int) -> sp.csr_matrix:
    """Matrix acting on the global vector: column j of M goes to column columns[j]."""
    M = sp.coo_matrix(M)
    return sp.csr_matrix((M.data, (M.row, columns[M.col])), shape=(M.shape[0], n))


def elimination(disc: Discretisation) -> tuple[sp.csr_matrix, np.ndarray]:
    """Return ``(P, u0)`` with ``u = P w + u0`` for the free unknowns ``w``.

    Free = neither Dirichlet nor constrained. Constrained nodes take the
    interpolated other-side values (which may involve Dirichlet end points, whose
    contribution goes into ``u0``).
    """
    n = disc.n_nodes
    fixed = np.zeros(n, dtype=bool)
    fixed[disc.dirichlet] = True
    fixed[disc.constrained] = True
    free = np.flatnonzero(~fixed)
    col_of = -np.ones(n, dtype=int)
    col_of[free] = np.arange(len(free))
    u0 = np.zeros(n)
    u0[disc.dirichlet] = disc.dirichlet_values
    # constrained rows: T acts on other-side interface nodes, each free or Dirichlet
    Tc = sp.coo_matrix(disc.constraint)
    if np.any(fixed[Tc.col] & ~np.isin(Tc.col, disc.dirichlet)):
        raise RuntimeError("a constraint refers to another constrained node")
    u0[disc.constrained] = disc.constraint @ u0
    is_free = col_of[Tc.col] >= 0
    rows = np.concatenate([free, disc.constrained[Tc.row[is_free]]])
    cols = np.concatenate([np.arange(len(free)), col_of[Tc.col[is_free]]])
    vals = np.concatenate([np.ones(len(free)), Tc.data[is_free]])
    P = sp.csr_matrix((vals, (rows, cols)), shape=(n, len(free)))
    return P, u0


@dataclass
class LaplaceSolution:
    """Result of one solve: nodal values per mesh, errors and bookkeeping."""

    case: str
    variant: str
    constrained: str
    level: int
    h: float
    ndof: int
    err_h1: float
    err_l2: float
    residual: float
    lambda_min: float | None
    meshes: list
    u: list

    def record(self) -> dict:
        return {"case": self.case, "variant": self.variant, "constrained": self.constrained,
                "level": self.level, "h": self.h, "ndof": self.ndof, "err_h1": self.err_h1,
                "err_l2": self.err_l2, "residual": self.residual}


def reduced_system(disc: Discretisation) -> tuple[sp.csr_matrix, np.ndarray, sp.csr_matrix, np.ndarray]:
    """``(K, rhs, P, u0)``: K = P^T (A + penalty) P, rhs = P^T (f - (A + penalty) u0)."""
    P, u0 = elimination(disc)
    As = disc.A + disc.penalty
    K = (P.T @ As @ P).tocsr()
    rhs = P.T @ (disc.f - As @ u0)
    return K, rhs, P, u0


def errors(meshes: list, u: list, case: str, intorder: int = 6) -> tuple[float, float]:
    """H1-seminorm and L2 errors against the exact solution by quadrature of
    order ``intorder`` (> 2, the P1 space's), summed over the subdomains."""

    @Functional
    def h1(w):
        _, ux, uy, _ = exact_solution(case, w.x[0], w.x[1])
        return (w["uh"].grad[0] - ux) ** 2 + (w["uh"].grad[1] - uy) ** 2

    @Functional
    def l2(w):
        return (w["uh"] - exact_solution(case, w.x[0], w.x[1])[0]) ** 2

    e1 = e0 = 0.0
    for mesh, uu in zip(meshes, u):
        basis = Basis(mesh, ElementTriP1(), intorder=intorder)
        uh = basis.interpolate(uu)
        e1 += h1.assemble(basis, uh=uh)
        e0 += l2.assemble(basis, uh=uh)
    return float(np.sqrt(e1)), float(np.sqrt(e0))


def smallest_eigenvalue(K: sp.spmatrix) -> float:
    """Smallest eigenvalue of the symmetric reduced operator (dense for small K)."""
    if K.shape[0] <= 3000:
        return float(np.linalg.eigvalsh(K.toarray())[0])
    return float(spla.eigsh(K, k=1, sigma=0, which="LM", return_eigenvectors=False)[0])


def solve(level: int, check_definite: bool = False, **params) -> LaplaceSolution:
    """Assemble, eliminate the nodal constraints, solve directly, measure errors.

    Parameters
    ----------
    level : int
        Refinement level (see :func:`cells_per_unit`).
    check_definite : bool
        Also compute the smallest eigenvalue of the reduced operator.
    **params
        The problem's parameters (``case``, ``variant``, ``ratio``,
        ``constrained``; declared once in :data:`PROBLEM`, defaults there).
    """
    p = PROBLEM.options(**params)
    disc = assemble(level, p.case, p.variant, parse_ratio(p.ratio), p.constrained)
    K, rhs, P, u0 = reduced_system(disc)
    w = spla.spsolve(K.tocsc(), rhs)
    residual = float(np.linalg.norm(K @ w - rhs) / max(np.linalg.norm(rhs), 1e-300))
    u = P @ w + u0
    parts = [u[a:b] for a, b in zip(disc.offsets[:-1], disc.offsets[1:])]
    err_h1, err_l2 = errors(disc.meshes, parts, p.case)
    lam = smallest_eigenvalue(K) if check_definite else None
    return LaplaceSolution(p.case, p.variant, p.constrained, level, disc.h, K.shape[0], err_h1,
                           err_l2, residual, lam, disc.meshes, parts)


def build(level: int, p: Options) -> "LaplaceProblem":
    """Registry entry point: a lazily solved Laplace problem."""
    parse_ratio(p.ratio)
    return LaplaceProblem(level=level, params=dict(p))


@dataclass
class LaplaceProblem:
    """What ``contactbench solve`` gets for this linear (no-contact) problem."""

    level: int
    params: dict

    def solve(self) -> LaplaceSolution:
        return solve(self.level, **self.params)


PROBLEM = ProblemSpec(
    name="laplace_nonmatching",
    summary="Laplace on (0,1)^2 with non-matching P1 grids across x=1/2; nodal constraints "
            "+ stabilisation (thesis Ch. 6)",
    kind="linear",
    levels=(0, 8),
    default_level=2,
    parameters=(
        Parameter("case", "sin10x", "exact solution: sin10x (Sect. 6.6) or linear (patch test)",
                  choices=CASES),
        Parameter("variant", "stabilised_a1", "interface coupling", choices=VARIANTS),
        Parameter("ratio", "2:3", "cells per unit length, coarse:fine (p:q, 1 <= p <= q <= 16)"),
        Parameter("constrained", "coarse", "side whose interface nodes carry the constraints",
                  choices=("coarse", "fine")),
    ),
    build=build,
)
