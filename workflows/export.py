"""Export a test set's problems as plain files that a QP user reads without the suite.

Convention: ``min 1/2 x'Px + q'x  s.t.  Gx <= h`` with ``P`` the stiffness, ``q = -f``,
``G`` the contact rows and ``h`` the gaps. A stabilised problem (the thesis's
Sect. 7.5, a ``C`` block) is exported in its slack form
(:func:`problems.slack.slack_form`): ``x = (u, s)``, ``s_i = c_i z_i``. Each problem
is a folder ``<out>/<problem>/``::

    P.mtx q.mtx G.mtx h.mtx   Matrix Market, as scipy.io.mmwrite writes them
    problem.npz                the same arrays (P, G as CSR: *_data, *_indices, *_indptr, *_shape)
    solution.npz               the exact reference: x, z (multipliers of Gx <= h)
    meta.json                  objective, scene, level, parameters, sizes, units, norms,
                               a condition estimate, the reference's residuals, checksums

and ``<out>/index.json`` lists them; ``<out>/contact_qp.py`` is qpbenchmark's test-set
module for the folder (``qpbenchmark <out>/contact_qp.py run ...``; it reads the
problems whose ``form`` is ``qp``).

A frictional problem (one Tresca step, :mod:`problems.friction.forms`) has ``x = (u, t)``,
``t_i >= |slip_i|`` per node with a slip bound ``s_i > 0``. In 2D it is a QP (``form``
``qp``, :func:`problems.friction.forms.split_program`), written as above; in 3D
(isotropic friction) a second-order cone program (``form`` ``cone``,
:func:`problems.friction.forms.cone_program`) in the conic form Clarabel and SCS take::

    min 1/2 x'Px + q'x   s.t.   Ax + s = b,   s in K = R+^l x SOC(k_1) x ... x SOC(k_c)

written as ``P.mtx q.mtx A.mtx b.mtx`` (and ``A_*``, ``b`` in ``problem.npz``), the cone
sizes in ``meta.json`` (``cones``: ``zero`` 0, ``nonnegative`` l, ``second_order`` the
list of k_j; a second-order cone ``|s[1:]| <= s[0]``). Its ``solution.npz`` holds ``x``,
``z`` (the multipliers of the program's rows, ``Px + q + G'z = 0`` resp. ``A'z``) and the
suite's ``u``, ``p`` (normal), ``lam`` (tangential); ``warm_start.npz`` the same for the
previous step's reference solution (the warm start of a load path). The objective of
``x = (u, |slip(u)|)`` is the step's energy ``1/2 u'Au - f'u + sum s_i |slip_i(u)|``
exactly (``objective_constant`` 0: the slip's reference ``previous - offset`` sits in
``h`` resp. ``b``). A set is written
into a temporary folder beside ``out`` and renamed into place when complete: an
interrupted export leaves nothing behind, an existing one is replaced only when asked.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.floating import floating_modes
from problems.friction.forms import (lift, program_multipliers, standard_program,
                                     tresca_step)
from problems.friction.residuals import tresca_energy
from problems.slack import slack_form
from workflows.io import _sha256 as file_digest, json_text, provenance
from workflows.problem_set import SetProblem, TestSet

CONVENTION = "min 1/2 x'Px + q'x  s.t.  Gx <= h"
#: The conic form of a 3D frictional step (Clarabel's and SCS's).
CONE_CONVENTION = "min 1/2 x'Px + q'x  s.t.  Ax + s = b,  s in K"
#: Each form's convention and its constraint arrays' names.
FORMS = {"qp": (CONVENTION, ("G", "h")), "cone": (CONE_CONVENTION, ("A", "b"))}
#: The qpbenchmark test-set module copied into every export (class ContactQp).
QPBENCHMARK_MODULE = Path(__file__).resolve().parent / "data" / "contact_qp.py"
#: Largest n whose condition number is estimated (a few solves with A each).
CONDITION_LIMIT = 300_000


class ExportError(ValueError):
    """An output folder that may not be written (the message says why)."""


def form_of(qp) -> str:
    """``qp`` (a frictionless problem, a 2D or faceted Tresca step: nonnegative rows only)
    or ``cone`` (an isotropic 3D Tresca step: second-order cones)."""
    if qp.friction is None:
        return "qp"
    return program_form(standard_program(tresca_step(qp)))


def program_form(program) -> str:
    """``cone`` if the Tresca step's program has second-order cones, else ``qp``."""
    return "cone" if program.cones else "qp"


def qp_arrays(qp) -> dict[str, np.ndarray | sp.csr_matrix]:
    """The exported arrays of ``qp``: ``P, q, G, h`` (the slack form if ``qp.C``; a 2D
    Tresca step's split QP), or a 3D Tresca step's ``P, q, A, b`` (:func:`form_of`)."""
    if qp.friction is not None:
        program = standard_program(tresca_step(qp))
        G, h = FORMS[program_form(program)][1]     # the program built once
        return {"P": sp.csr_matrix(program.P), "q": np.asarray(program.q, dtype=float),
                G: sp.csr_matrix(program.G), h: np.asarray(program.h, dtype=float)}
    s = slack_form(qp)
    return {"P": sp.csr_matrix(s.A), "q": -np.asarray(s.f, dtype=float),
            "G": sp.csr_matrix(s.B), "h": np.asarray(s.g, dtype=float)}


def exported_solution(qp, u: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``x`` of the exported problem for the contact solution ``(u, p)``: ``u``, or
    ``(u, s)`` with ``s = c p`` on the penalised rows of the slack form, or a Tresca
    step's ``(u, t)``, ``t_i = |slip_i(u)|`` (:func:`problems.friction.forms.lift`)."""
    if qp.friction is not None:
        step = tresca_step(qp)
        return lift(step, standard_program(step), u)
    if qp.C is None:
        return np.asarray(u, dtype=float)
    c = qp.C.diagonal()
    return np.concatenate([u, (c * p)[c > 0]])


def objective(qp, u: np.ndarray, p: np.ndarray) -> float:
    """``1/2 x'Px + q'x`` at ``x`` = :func:`exported_solution` (the energy
    ``1/2 u'Au - f'u``, plus ``1/2 p'Cp`` for a stabilised problem, plus
    ``sum s_i |slip_i(u)|`` for a Tresca step)."""
    if qp.friction is not None:
        return tresca_energy(qp, np.asarray(u, dtype=float))
    J = 0.5 * float(u @ (qp.A @ u)) - float(qp.f @ u)
    if qp.C is not None:
        J += 0.5 * float(p @ (qp.C @ p))
    return J


def condition_estimate(qp) -> dict:
    """``kappa_1(P)`` by Hager-Higham's 1-norm estimates of ``P`` and ``P^-1``
    (``scipy.sparse.linalg.onenormest``; ``P^-1`` through the verification's linear
    solver, :func:`solvers.certificate.linear_solver`)."""
    from solvers.certificate import linear_solver

    if qp.n > CONDITION_LIMIT:
        return {"kappa_1": None, "method": f"not estimated above n = {CONDITION_LIMIT}"}
    solve_A = linear_solver(qp)
    inv = spla.LinearOperator(qp.A.shape, matvec=solve_A, rmatvec=solve_A, dtype=float)
    norm_P, norm_inv = spla.onenormest(qp.A), spla.onenormest(inv)
    if qp.C is not None:                         # P = blockdiag(A, diag(1/c)) on c > 0
        c = qp.C.diagonal()
        c = c[c > 0]
        if c.size:
            norm_P, norm_inv = max(norm_P, float(np.max(1 / c))), max(norm_inv, float(np.max(c)))
    return {"kappa_1": float(norm_P * norm_inv), "norm_1_P": float(norm_P),
            "norm_1_P_inverse": float(norm_inv),
            "method": "scipy.sparse.linalg.onenormest of P and of P^-1 (Hager-Higham)"}


def write_problem(folder: Path, item: SetProblem, set_id: str,
                  reference_tol: float = 1e-10, fclib: bool = False,
                  multigrid: bool = False) -> dict:
    """Build ``item``, solve it exactly and write its folder; returns its index entry.
    ``fclib``: the folder also holds the problem's fclib global file where it has one
    (:func:`fclib_file`); ``multigrid``: its multigrid data (:func:`multigrid_file`).

    Raises
    ------
    RuntimeError
        If the exact reference does not converge (nothing is exported then).
    """
    from solvers.interface import solve
    from solvers.reference import reference_solve

    qp = item.build()
    ref = (reference_solve(qp, tol=reference_tol) if qp.friction is None else
           solve(qp, "tresca_exact", tol=reference_tol))
    if ref.status != "converged":
        raise RuntimeError(f"the exact reference failed on {item.name}: {ref.status} "
                           f"{ref.message}")
    form = form_of(qp)
    convention, (g_name, h_name) = FORMS[form]
    arrays = qp_arrays(qp)
    folder.mkdir(parents=True)
    for key, value in arrays.items():
        scipy.io.mmwrite(folder / f"{key}.mtx",
                         value if sp.issparse(value) else value.reshape(-1, 1),
                         comment=f"{set_id} {item.name}: {key} of {convention}")
    P, G = arrays["P"], arrays[g_name]
    np.savez_compressed(folder / "problem.npz", q=arrays["q"], **{h_name: arrays[h_name]},
                        **{f"{k}_{a}": getattr(M, a) for k, M in (("P", P), (g_name, G))
                           for a in ("data", "indices", "indptr")},
                        P_shape=np.array(P.shape), **{f"{g_name}_shape": np.array(G.shape)})
    x = exported_solution(qp, ref.u, ref.p)
    # the reference's multipliers are >= 0 up to round-off (-1e-17 where a row is inactive)
    p_ref = np.maximum(np.asarray(ref.p, dtype=float), 0.0)
    friction = None
    if qp.friction is None:
        np.savez_compressed(folder / "solution.npz", x=x, z=p_ref)
    else:
        friction = friction_solution_files(folder, item, qp, ref.u, p_ref, ref.tangential)
    fclib_entry = fclib_file(folder, item, qp, ref.u, p_ref, ref.tangential) if fclib else None
    multigrid_entry = multigrid_file(folder, qp) if multigrid else None
    J = objective(qp, ref.u, ref.p)
    tight = (tight_rows(G, arrays[h_name], x) if form == "qp" else
             tight_rows(G[:qp.m], arrays[h_name][:qp.m], x))
    meta = {
        "name": item.name, "set": set_id, "family": item.family, "problem": item.problem,
        "level": item.level, "size_class": item.size_class,
        "params": dict(problems_options(item)), "dim": qp.dim, "units": qp.units,
        "convention": convention,
        "form": form,
        "x": (FRICTION_X if qp.friction is not None else
              "the slack form of the stabilised problem (Sect. 7.5): x = (u, s), "
              "s_i = c_i z_i on the penalised rows" if qp.C is not None else
              "x = u, the displacements of both bodies (Dirichlet unknowns eliminated)"),
        "n": int(P.shape[0]), "m": int(G.shape[0]), "n_displacements": int(qp.n),
        "nnz_P": int(P.nnz), f"nnz_{g_name}": int(G.nnz),
        "objective": J, "objective_constant": 0.0,
        **({"cones": cone_sizes(qp)} if form == "cone" else {}),
        **({"friction": friction} if friction is not None else {}),
        **({"fclib": fclib_entry} if fclib_entry is not None else {}),
        **({"multigrid": multigrid_entry} if multigrid_entry is not None else {}),
        "solution": {"file": "solution.npz", "x": "x", "z": "z",
                     "active_rows": int(np.sum(ref.p > 0)), **tight},
        "reference": {"solver": ref.solver, "status": ref.status, "tol": reference_tol,
                      "kkt": ref.kkt.as_dict(prefix="") if ref.kkt is not None else None,
                      "relative_energy_bound": ref.gap.certified_bound
                      if ref.gap is not None else None},
        "norms": {"P_max": float(abs(P).max()) if P.nnz else 0.0,
                  "P_fro": float(spla.norm(P)), "q_inf": float(np.max(np.abs(arrays["q"]))),
                  f"{g_name}_max": float(abs(G).max()) if G.nnz else 0.0,
                  f"{h_name}_inf": float(np.max(np.abs(arrays[h_name]), initial=0.0)),
                  "x_inf": float(np.max(np.abs(x))), "z_inf": float(np.max(ref.p, initial=0.0))},
        "condition": {**condition_estimate(qp), **({"of": "A, the displacement block of "
                                                          "P = diag(A, 0)"}
                                                   if qp.friction is not None else {})},
        "floating_modes": int(floating_modes(qp).shape[1]),
        "files": {},
    }
    meta["files"] = {f.name: file_digest(f)[0] for f in sorted(folder.iterdir())}
    (folder / "meta.json").write_text(json_text(meta), encoding="utf-8")
    return {"name": item.name, "family": item.family, "problem": item.problem,
            "level": item.level, "size_class": item.size_class, "form": form,
            "n": meta["n"], "m": meta["m"],
            "dependent_tight_rows": meta["solution"]["dependent_tight_rows"],
            "objective": J, "folder": item.name,
            "meta_sha256": file_digest(folder / "meta.json")[0]}


#: A problem folder's multigrid data (``--multigrid``).
MULTIGRID_FILE = "multigrid.npz"


def multigrid_file(folder: Path, qp) -> dict:
    """Write what a multigrid solver needs of ``qp`` into ``folder`` (``multigrid.npz``,
    and ``mesh.vtu`` for meshio); returns meta.json's ``multigrid`` entry.

    Per unknown of ``u`` (the first ``n_displacements`` entries of ``x``): its node, its
    component and that node's coordinates, its body; ``near_null_space``, the rigid-body
    motions of each body restricted to the unknowns (the near-null space smoothed
    aggregation takes as ``B``); ``prolongations``, the nested hierarchy's ``P_k`` from
    level ``k`` to ``k + 1`` on the free unknowns, coarsest first, the last ending on
    ``u`` (``P{k}_data``, ``_indices``, ``_indptr``, ``_shape``: CSR).
    """
    import meshio

    mesh, ml = qp.mesh, qp.multilevel
    node, component = np.divmod(np.asarray(qp.free_dofs), qp.dim)
    arrays = {"node": node, "component": component, "coordinates": mesh.points[node],
              "body": (ml.body_of_dof if ml.body_of_dof is not None
                       else mesh.body_of_node[node])}
    if ml.rigid_body_modes is not None:
        arrays["near_null_space"] = np.asarray(ml.rigid_body_modes, dtype=float)
    for k, P in enumerate(ml.prolongations):
        P = sp.csr_matrix(P)
        arrays.update({f"P{k}_data": P.data, f"P{k}_indices": P.indices,
                       f"P{k}_indptr": P.indptr, f"P{k}_shape": np.array(P.shape)})
    np.savez_compressed(folder / MULTIGRID_FILE, **arrays)
    linear = mesh.cells.shape[1] == qp.dim + 1
    kind = ({2: "triangle", 3: "tetra"} if linear else {2: "triangle6", 3: "tetra10"})[qp.dim]
    points = np.zeros((mesh.points.shape[0], 3))        # VTU's points are 3D
    points[:, :qp.dim] = mesh.points
    meshio.write(folder / "mesh.vtu", meshio.Mesh(
        points, [(kind, mesh.cells)], point_data={"body": mesh.body_of_node}))
    return {"file": MULTIGRID_FILE, "mesh": "mesh.vtu", "levels": len(ml.prolongations) + 1,
            "near_null_space": int(arrays["near_null_space"].shape[1])
            if "near_null_space" in arrays else 0,
            "of": "u, the first n_displacements entries of x"}


#: The fclib global file of a problem folder (``--format fclib``).
FCLIB_FILE = "fclib.hdf5"


def fclib_file(folder: Path, item: SetProblem, qp, u: np.ndarray, p: np.ndarray,
               lam: np.ndarray | None) -> dict:
    """Write ``qp``'s fclib file into ``folder`` (:mod:`workflows.fclib`: the global form of
    a Coulomb step, its previous step's reference as the guess, or of a frictionless
    problem with ``mu = 0``; the local form too where a dense Delassus operator fits) with
    the reference as its solution; returns meta.json's ``fclib`` entry: the file and its
    natural-map residual, or the reason there is none."""
    from workflows.fclib import (FclibError, global_problem, local_problem,
                                 natural_map_residual, reactions, solution_of, write_global,
                                 write_local)

    coulomb = qp.friction is not None and item.params.get("friction") == "coulomb"
    try:
        problem = global_problem(qp, coulomb=coulomb)
    except FclibError as err:
        return {"file": None, "reason": str(err)}
    r = reactions(problem, p, lam)
    problem.solution = solution_of(problem, u, r)
    if qp.friction is not None:
        warm = item.frictional_step().warm
        problem.guesses = (solution_of(problem, warm.u, reactions(
            problem, np.maximum(warm.p, 0.0), warm.lam)),)
    problem.info = {"title": f"{item.name} ({item.family}, level {item.level})",
                    "description": f"contactbench test set {item.family}: "
                                   f"{'Coulomb step' if coulomb else 'frictionless'}"}
    write_global(folder / FCLIB_FILE, problem)
    try:
        write_local(folder / FCLIB_FILE, local_problem(problem))
        local = "fclib_local: u = W r + q, W = H'M^-1 H dense"
    except FclibError as err:
        local = f"none: {err}"
    return {"file": FCLIB_FILE, "law": "coulomb" if coulomb else "frictionless (mu = 0)",
            "contacts": problem.contacts, "spacedim": problem.spacedim,
            "guesses": len(problem.guesses), "local": local,
            "natural_map_residual": natural_map_residual(problem, u, r)}


#: What ``x`` is in a frictional problem's export.
FRICTION_X = ("x = (u, t): u the displacements of both bodies (Dirichlet unknowns "
              "eliminated), t_i >= |slip_i(u)| one per node with a slip bound s_i > 0 "
              "(friction.bounded_nodes), slip(u) = T u + offset - previous")


def cone_sizes(qp) -> dict:
    """The cone ``K`` of a cone-form problem as Clarabel and SCS state it: ``zero`` rows
    (none), ``nonnegative`` rows, then one second-order cone per size in ``second_order``."""
    program = standard_program(tresca_step(qp))
    return {"zero": 0, "nonnegative": int(program.nonnegative),
            "second_order": [int(c) for c in program.cones]}


def friction_solution_files(folder: Path, item: SetProblem, qp, u: np.ndarray,
                            p: np.ndarray, lam: np.ndarray) -> dict:
    """Write a Tresca step's ``solution.npz`` and ``warm_start.npz`` (the previous step's
    reference, :func:`workflows.problem_set.frictional_steps`) into ``folder``; returns
    the ``friction`` entry of its meta.json: the path's law, ``mu``, the step and the path's number
    of tangential steps, the measured ``Q / (mu P)``, the slip bounds' range, Coulomb's
    fixed point and the files."""
    step = tresca_step(qp)
    program = standard_program(step)
    fs = item.frictional_step()

    def save(name, u_, p_, lam_):
        np.savez_compressed(folder / name, x=lift(step, program, u_),
                            z=program_multipliers(step, program, p_, lam_), u=u_, p=p_,
                            lam=np.asarray(lam_, dtype=float))

    save("solution.npz", u, p, lam)
    save("warm_start.npz", fs.warm.u, np.maximum(fs.warm.p, 0.0), fs.warm.lam)
    fr = qp.friction
    return {"law": item.params["friction"], "problem_law": f"{fr.law} (one step, s given)",
            "mu": fr.mu, "step": fs.step, "steps": fs.steps,
            "ratio": fs.ratio, "ratio_meaning": "Q / (mu P) of the reference solution",
            "slip_bound_max": float(np.max(fr.slip_bound, initial=0.0)),
            "bounded_nodes": int(program.bounded.size), "components": fr.components,
            "fixed_point": fs.fixed_point,
            "definition": "slip bounds and previous state rounded to 8 significant digits "
                          "of their largest entry (workflows.problem_set.definition_digits)",
            "solution": {"file": "solution.npz", "x": "x", "z": "z (the program's rows)",
                         "u": "u", "p": "p (normal)", "lam": "lam (tangential)"},
            "warm_start": {"file": "warm_start.npz",
                           "of": "the previous step's reference solution (the first "
                                 "tangential step's: the normal step's), in this step's "
                                 "program (t = |slip| of this step)"}}


def tight_rows(G: sp.spmatrix, h: np.ndarray, x: np.ndarray, rtol: float = 1e-8) -> dict:
    """How many rows of ``Gx <= h`` hold with equality at ``x`` (slack below ``rtol``
    times ``max(|h|, |Gx|)``), and how many of them are linearly dependent on the others
    (:func:`solvers.kernels.cholesky.row_basis` of their Gram matrix ``G_T G_T'``): where that is
    positive, LICQ fails at the solution and the multipliers ``z`` are not unique."""
    from solvers.kernels.cholesky import row_basis

    Gx = G @ x
    scale = max(float(np.max(np.abs(h), initial=0.0)), float(np.max(np.abs(Gx), initial=0.0)),
                1e-300)
    tight = np.flatnonzero(h - Gx <= rtol * scale)
    G_t = sp.csr_matrix(G)[tight]
    dropped = row_basis((G_t @ G_t.T).toarray()).dropped.size if tight.size else 0
    return {"tight_rows": int(tight.size), "dependent_tight_rows": int(dropped)}


def problems_options(item: SetProblem) -> dict:
    """Every parameter of ``item``'s problem (the overrides and the defaults)."""
    from problems.spec import problems

    return dict(problems()[item.problem].options(**item.params))


def check_out(out: Path, force: bool) -> None:
    """Refuse an output folder that exists (unless ``force``) or cannot be made."""
    if out.exists() and not force:
        raise ExportError(f"option '--out': {str(out)!r} exists; allowed: a new folder, or "
                          "--force to replace it")
    if out.exists() and not out.is_dir():
        raise ExportError(f"option '--out': {str(out)!r} is not a folder")
    parent = out.parent
    if not parent.is_dir():
        raise ExportError(f"option '--out': directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ExportError(f"option '--out': directory {str(parent)!r} is not writable")


def export_set(ts: TestSet, size_class: str, out: str | os.PathLike, force: bool = False,
               families: list[str] | None = None, progress: bool = True,
               fclib: bool = False, multigrid: bool = False) -> Path:
    """Write the problems of ``ts`` in ``size_class`` (of ``families``) to ``out``
    (``fclib``: each folder with its fclib file too, :func:`fclib_file`; ``multigrid``:
    with its multigrid data, :func:`multigrid_file`; either also where the set's
    ``files`` name it).

    The folder appears complete or not at all (written beside it, renamed into place).
    Returns ``out``.
    """
    from tqdm import tqdm

    out = Path(out)
    check_out(out, force)
    fclib, multigrid = fclib or "fclib" in ts.files, multigrid or "multigrid" in ts.files
    items = ts.problems(size_class, families)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        entries = [write_problem(tmp / item.name, item, ts.id, fclib=fclib,
                                 multigrid=multigrid)
                   for item in tqdm(items, desc=f"export {ts.id} {size_class}",
                                    disable=not progress)]
        index = {"set": ts.id, "name": ts.name, "version": ts.version,
                 "description": ts.description, "size_class": size_class,
                 "convention": CONVENTION, "conventions": {k: v[0] for k, v in FORMS.items()},
                 "problems": entries,
                 "families": sorted({e["family"] for e in entries}),
                 "qpbenchmark": f"qpbenchmark {out}/contact_qp.py run --solver osqp "
                                f"--settings mid_accuracy --results-path "
                                f"{out}/results/osqp.csv --author <name>",
                 "provenance": provenance()}
        (tmp / "index.json").write_text(json_text(index), encoding="utf-8")
        shutil.copyfile(QPBENCHMARK_MODULE, tmp / "contact_qp.py")
        if out.exists():                 # --force: the old set goes only once the new is whole
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old)
        else:
            tmp.rename(out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return out


def load_problem(folder: str | os.PathLike, source: str = "npz") -> dict:
    """``P, q, G, h`` of an exported problem (a cone-form problem's ``P, q, A, b``), from
    ``problem.npz`` or the ``.mtx`` files (``source``), as CSR matrices and 1-D arrays."""
    folder = Path(folder)
    G, h = FORMS["cone" if (folder / "A.mtx").exists() else "qp"][1]
    if source == "mtx":
        read = {k: scipy.io.mmread(folder / f"{k}.mtx") for k in ("P", "q", G, h)}
        return {"P": sp.csr_matrix(read["P"]), G: sp.csr_matrix(read[G]),
                "q": np.asarray(read["q"], dtype=float).ravel(),
                h: np.asarray(read[h], dtype=float).ravel()}
    if source != "npz":
        raise ValueError(f"source {source!r} is not allowed; allowed: npz, mtx")
    with np.load(folder / "problem.npz") as z:
        def csr(k):
            return sp.csr_matrix((z[f"{k}_data"], z[f"{k}_indices"], z[f"{k}_indptr"]),
                                 shape=tuple(z[f"{k}_shape"]))
        return {"P": csr("P"), G: csr(G), "q": z["q"], h: z[h]}
