"""fclib's global form of the test set's problems (:mod:`workflows.fclib`): written by
``contactbench export --format fclib``, read back by an independent reader (``h5py`` and
``scipy`` here, none of the suite's code), the mapping checked against the suite's own
arrays, and the exported reference checked against Coulomb's law in De Saxce's form; the
exported local problems solved by Siconos, an independent code, to the reference."""
from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

from solvers.kernels import fclib_form
from workflows.cli import main
from workflows.fclib import (FclibError, contact_arrays, law_residual, local_problem,
                             natural_map_residual, read_global, read_local, write_global,
                             write_local)
from workflows.problem_set import load

#: A 2D and a 3D Coulomb step, a Tresca step and a frictionless problem (level 0).
PROBLEMS = ("circle_square_coulomb_q05_L0", "cube_sphere_coulomb_q05_L0",
            "circle_square_tresca_q05_L0", "hard_grazing_L0")
#: The exported reference satisfies Coulomb's law to this (relative natural-map residual):
#: a Coulomb step's slip bounds s = mu p are rounded to 8 significant digits.
LAW_TOL = 1e-8


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    out = tmp_path_factory.mktemp("fclib") / "set"
    families = sorted({name.rsplit("_L", 1)[0] for name in PROBLEMS})
    assert main(["export", "--set", "contact-qp-5", "--class", "small", "--families",
                 *families, "--format", "fclib", "--out", str(out), "--quiet"]) == 0
    return out


def plain_matrix(group) -> sp.csc_matrix:
    """fclib's compressed-column matrix read with h5py and scipy alone."""
    assert int(group["nz"][0]) == -1
    m, n = int(group["m"][0]), int(group["n"][0])
    return sp.csc_matrix((group["x"][()], group["i"][()], group["p"][()]), shape=(m, n))


def de_saxce_residual(M, H, f, w, mu, v, r, d) -> float:
    """Coulomb's law in De Saxce's form at ``(v, r)``, written out per contact: the
    largest of the equilibrium's, r in K, u^ in K* and r . u^ = 0 (relative)."""
    u = (H.T @ v + w).reshape(-1, d)
    r = r.reshape(-1, d)
    hat = u.copy()
    hat[:, 0] += mu * np.linalg.norm(u[:, 1:], axis=1)
    r_scale, u_scale = np.abs(r).max(), np.abs(u).max()
    # K = {|r_T| <= mu r_N}, its dual cone K* = {mu |x_T| <= x_N}
    in_cone = np.maximum(np.linalg.norm(r[:, 1:], axis=1) - mu * r[:, 0], 0).max() / r_scale
    in_dual = np.maximum(mu * np.linalg.norm(hat[:, 1:], axis=1) - hat[:, 0], 0).max() / u_scale
    complementary = np.abs(np.einsum("ij,ij->i", r, hat)).max() / (r_scale * u_scale)
    balance = np.linalg.norm(M @ v + f - H @ r.ravel()) / np.linalg.norm(f)
    return float(max(in_cone, in_dual, complementary, balance))


@pytest.mark.parametrize("name", [p for p in PROBLEMS if "tresca" not in p])
def test_an_fclib_file_reads_back_into_the_suites_arrays(export, name):
    folder = export / name
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["fclib"]["file"] == "fclib.hdf5"
    item = next(p for p in load("contact-qp-5").problems("small") if p.name == name)
    qp = item.build()
    d = qp.dim
    with h5py.File(folder / "fclib.hdf5", "r") as h5:
        g = h5["fclib_global"]
        assert int(g["spacedim"][0]) == d
        M, H = plain_matrix(g["M"]), plain_matrix(g["H"])
        f, w, mu = (g["vectors"][key][()] for key in ("f", "w", "mu"))
        v, r = h5["solution"]["v"][()], h5["solution"]["r"][()]
        guesses = int(h5["guesses"]["number_of_guesses"][0]) if "guesses" in h5 else 0
    # the mapping: M = A, f = -f, per contact the normal column -B_i' and gap g_i first
    assert (M != sp.csc_matrix(qp.A)).nnz == 0 and np.array_equal(f, -qp.f)
    assert H.shape == (qp.n, qp.m * d) and mu.size == qp.m
    normal = np.arange(qp.m) * d
    assert (H[:, normal].T != -sp.csr_matrix(qp.B)).nnz == 0
    assert np.array_equal(w[normal], qp.g)
    fr = qp.friction
    if fr is None:
        assert not mu.any() and H[:, np.setdiff1d(np.arange(H.shape[1]), normal)].nnz == 0
    else:
        assert np.all(mu == fr.mu) and guesses == 1
        tangential = (normal[:, None] + np.arange(1, d)).ravel()
        assert (H[:, tangential].T != -sp.csr_matrix(fr.T)).nnz == 0
        assert np.array_equal(w[tangential], fr.previous - fr.offset)
        # the exported state: r_T = lam, u_T = -slip (friction opposes the slip)
        assert np.allclose((H.T @ v + w)[tangential], -fr.slip(v), rtol=0, atol=1e-15)
    assert de_saxce_residual(M, H, f, w, mu, v, r, d) <= LAW_TOL
    problem = read_global(folder / "fclib.hdf5")
    assert natural_map_residual(problem, v, r) <= LAW_TOL
    off = r.copy()                              # either check refutes a reaction off by 1e-4
    off[np.argmax(np.abs(r))] *= 1 + 1e-4
    assert de_saxce_residual(M, H, f, w, mu, v, off, d) > LAW_TOL
    assert natural_map_residual(problem, v, off) > LAW_TOL
    assert meta["fclib"]["natural_map_residual"] <= LAW_TOL
    # the local (Delassus) form in the same file: u = W r + q, the same u, the same law
    local = read_local(folder / "fclib.hdf5")
    assert meta["fclib"]["local"].startswith("fclib_local")
    u_local = local.W @ r + local.q
    assert np.allclose(u_local, H.T @ v + w, rtol=0, atol=1e-9 * np.abs(w).max())
    assert law_residual(u_local, r, local.mu, d) <= LAW_TOL
    assert law_residual(local.W @ off + local.q, off, local.mu, d) > LAW_TOL
    arrays = contact_arrays(problem)
    assert (arrays["B"] != sp.csr_matrix(qp.B)).nnz == 0 and np.array_equal(arrays["g"], qp.g)
    assert np.array_equal(arrays["f"], qp.f)


def test_what_fclib_cannot_hold_is_said(export, tmp_path, monkeypatch):
    tresca = json.loads((export / "circle_square_tresca_q05_L0" / "meta.json").read_text())
    assert tresca["fclib"]["file"] is None and "Coulomb's" in tresca["fclib"]["reason"]
    assert not (export / "circle_square_tresca_q05_L0" / "fclib.hdf5").exists()
    # a file with the local form only (as most of fclib's published problems): read by
    # read_local, refused by read_global (no stiffness matrix to build the suite's problem)
    problem = read_global(export / "hard_grazing_L0" / "fclib.hdf5")
    local = tmp_path / "local.hdf5"
    write_local(local, local_problem(problem))
    assert read_local(local).W.shape == (problem.H.shape[1],) * 2
    with pytest.raises(FclibError, match="local problem .* no stiffness matrix"):
        read_global(local)
    with h5py.File(tmp_path / "none.hdf5", "w") as h5:
        h5.create_group("other")
    with pytest.raises(FclibError, match="neither /fclib_global nor /fclib_local"):
        read_global(tmp_path / "none.hdf5")
    with pytest.raises(FclibError, match="no /fclib_local"):
        read_local(tmp_path / "none.hdf5")
    with h5py.File(local, "r+") as h5:
        h5["fclib_local"].create_group("R")
    with pytest.raises(FclibError, match="bilateral constraints"):
        read_local(local)
    monkeypatch.setattr(fclib_form, "LOCAL_MAX_ENTRIES", problem.H.shape[1] ** 2 - 1)
    with pytest.raises(FclibError, match="entries exceed .* the global form only"):
        local_problem(problem)


@pytest.mark.parametrize("name", ["circle_square_coulomb_q05_L0", "cube_sphere_coulomb_q05_L0"])
def test_the_delassus_operator_of_partial_solves_is_the_whole_one(export, name):
    """The local form's W, formed from partial solves on the contact rows
    (:func:`local_problem`), is ``H' M^-1 H`` of whole solves with SuperLU (another
    backend, every component) to 1e-12, and so is q; a factorisation whose components
    miss H's rows is refused, not used."""
    from solvers.kernels.cholesky import factorize

    problem = read_global(export / name / "fclib.hdf5")
    H = sp.csc_matrix(problem.H)
    whole = factorize(problem.M, backend="splu")
    W = H.T @ whole.solve(H.toarray())
    q = problem.w - H.T @ whole.solve(problem.f)
    local = local_problem(problem)
    assert np.abs(local.W - W).max() <= 1e-12 * np.abs(W).max()
    assert np.abs(local.q - q).max() <= 1e-12 * np.abs(q).max()
    with pytest.raises(ValueError, match="parameter 'factor'"):
        local_problem(problem, factorize(problem.M))


def test_triplet_and_row_matrices_of_other_writers_are_read(export, tmp_path):
    """fclib's C library writes triplet (nz >= 0), column (-1) and row (-2) matrices:
    the same problem in each reads to the same arrays; another nz is refused."""
    problem = read_global(export / "hard_grazing_L0" / "fclib.hdf5")
    path = write_global(tmp_path / "again.hdf5", problem)
    for nz, make in ((None, sp.coo_matrix), (-2, sp.csr_matrix)):
        with h5py.File(path, "r+") as h5:
            group = h5["fclib_global/H"]
            A = make(problem.H)
            for key in ("p", "i", "x", "nz"):
                del group[key]
            if nz is None:
                group["nz"], group["p"], group["i"], group["x"] = [A.nnz], A.col, A.row, A.data
            else:
                group["nz"], group["p"], group["i"], group["x"] = [nz], A.indptr, A.indices, A.data
        assert (read_global(path).H != problem.H).nnz == 0
    with h5py.File(path, "r+") as h5:
        h5["fclib_global/H/nz"][0] = -3
    with pytest.raises(FclibError, match="nz = -3 is not an fclib matrix type"):
        read_global(path)


SYSTEM_PYTHON = "/usr/bin/python3"
SICONOS_SCRIPT = Path(__file__).with_name("siconos_fclib.py")
#: Siconos's answer against the exported reference (relative, max norm): the reference's
#: Coulomb bounds are rounded to 8 significant digits.
SICONOS_AGREEMENT = 1e-6


def siconos_missing() -> str:
    """Why Siconos cannot run here ("" if it can)."""
    import subprocess
    if not Path(SYSTEM_PYTHON).exists():
        return f"no {SYSTEM_PYTHON}"
    probe = subprocess.run([SYSTEM_PYTHON, "-c", "import siconos.numerics, h5py"],
                           capture_output=True, text=True)
    return ("" if probe.returncode == 0 else
            "Siconos or h5py missing for the system Python (make siconos: apt-get install "
            "python3-siconos python3-h5py)")


@pytest.mark.parametrize("name", ["circle_square_coulomb_q05_L0", "cube_sphere_coulomb_q05_L0"])
def test_siconos_solves_the_exported_coulomb_step_to_the_reference(export, name):
    """Siconos (nonsmooth Gauss-Seidel, under the system Python, reading the file with its
    own h5py: nothing of the suite) solves the exported local problem of a 2D and a 3D
    Coulomb step to the suite's exact reference: the mapping's signs and the law agree."""
    import subprocess
    why = siconos_missing()
    if why:
        pytest.skip(why)
    out = subprocess.run([SYSTEM_PYTHON, str(SICONOS_SCRIPT), str(export / name / "fclib.hdf5")],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    answer = json.loads(out.stdout.strip().splitlines()[-1])
    assert answer["info"] == 0, answer["error"]
    r = np.array(answer["r"])
    problem = read_global(export / name / "fclib.hdf5")
    r_ref = problem.solution["r"]
    assert np.abs(r - r_ref).max() <= SICONOS_AGREEMENT * np.abs(r_ref).max()
    local = read_local(export / name / "fclib.hdf5")
    assert law_residual(local.W @ r + local.q, r, local.mu, problem.spacedim) <= LAW_TOL
