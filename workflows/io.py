"""Files at the edges: atomic writes, checksummed results and run provenance.

Every result file is written to a temporary file in the target directory
(``.<name>.partial-XXXX``) and moved into place with ``os.replace``, so a crash
or a failed write never leaves a half-written file behind and the previous
version survives. Beside every result ``<file>`` a sidecar ``<file>.meta.json``
records its size, its SHA-256 and where it came from (:func:`provenance`: commit,
packages, CPU, cores and threads, the workflow's config). Readers check the
checksum (:func:`read_checked`); the workflow sweeps corrupted or truncated
results and stale partial files before it plans (:func:`sweep_results`), so they
are rebuilt, never silently read.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import subprocess
import tempfile
from functools import lru_cache
from contextlib import contextmanager
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any, Iterator

import numpy as np

PACKAGES = ("numpy", "scipy", "scikit-fem", "ngsolve", "pyamg", "qpsolvers", "osqp", "proxsuite",
            "clarabel", "piqp", "qpalm", "cvxopt", "highspy", "scs", "ecos", "pandas", "meshio",
            "matplotlib", "snakemake", "mkl")


#: Marker of the temporary files :func:`atomic_path` writes (swept if a process died).
PARTIAL = ".partial-"
META = ".meta.json"


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None,
                meta: bool = True) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it into place and
    write the checksummed sidecar ``path.meta.json`` (unless ``meta`` is False).

    On an exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}{PARTIAL}",
                               suffix=suffix or path.suffix)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would make results private
    try:
        yield Path(tmp)
        digest, size = _sha256(Path(tmp))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    if meta:
        write_text(str(path) + META, json.dumps(
            {"file": path.name, "bytes": size, "sha256": digest, "provenance": provenance()},
            indent=1) + "\n", meta=False)


def _sha256(path: Path) -> tuple[str, int]:
    h = hashlib.sha256()
    size = 0
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
            size += len(block)
    return h.hexdigest(), size


class CorruptedResult(RuntimeError):
    """A result file does not match its checksummed sidecar (truncated or altered)."""


def check_result(path: str | os.PathLike) -> bool:
    """True if ``path`` matches its sidecar (size and SHA-256); True without a sidecar
    (a file the suite did not write); False if it is missing or does not match."""
    path = Path(path)
    side = Path(str(path) + META)
    if not side.exists():
        return True
    if not path.exists():
        return False
    try:
        meta = json.loads(side.read_text())
    except (OSError, ValueError):
        return False
    if path.stat().st_size != meta.get("bytes"):
        return False
    return _sha256(path)[0] == meta.get("sha256")


def read_checked(path: str | os.PathLike) -> Path:
    """``path`` after checking it against its sidecar.

    Raises
    ------
    CorruptedResult
        Naming the file: delete it (``snakemake`` then rebuilds it).
    """
    if not check_result(path):
        raise CorruptedResult(f"result file {str(path)!r} does not match its checksum "
                              f"({Path(str(path) + META).name}): truncated or altered; delete "
                              "it and rerun snakemake to rebuild it")
    return Path(path)


def sweep_results(root: str | os.PathLike = "results") -> list[str]:
    """Remove corrupted results (with their sidecars) and stale partial files below
    ``root``, so that the workflow rebuilds them. Returns the removed paths."""
    removed = []
    root = Path(root)
    if not root.exists():
        return removed
    for side in root.rglob("*" + META):
        target = Path(str(side)[: -len(META)])
        if target.exists() and not check_result(target):
            target.unlink()
            side.unlink()
            removed.append(str(target))
    for partial in root.rglob(f"*{PARTIAL}*"):
        partial.unlink(missing_ok=True)
        removed.append(str(partial))
    return removed


def write_text(path: str | os.PathLike, text: str, meta: bool = True) -> None:
    """Atomically write ``text`` to ``path`` (with its checksummed sidecar)."""
    with atomic_path(path, meta=meta) as tmp:
        tmp.write_text(text)


#: How a non-finite number is written in the suite's JSON files (JSON has no inf or nan):
#: as one of these strings, which :func:`read_json` turns back into floats. ``null``
#: means "not computed" (e.g. the residuals of a run without an answer), never a number.
NON_FINITE = {"inf": float("inf"), "-inf": float("-inf"), "nan": float("nan")}


def jsonable(obj: Any) -> Any:
    """``obj`` with numpy arrays and scalars made plain, and every non-finite float
    written as ``"inf"``, ``"-inf"`` or ``"nan"`` (:data:`NON_FINITE`)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if np.isfinite(x) else str(x)
    return obj


def json_text(data: Any) -> str:
    """``data`` as the suite's JSON (:func:`jsonable`; a non-finite number that slipped
    through would raise instead of writing the non-standard ``Infinity``)."""
    return json.dumps(jsonable(data), indent=1, allow_nan=False) + "\n"


def _finite_back(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _finite_back(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite_back(v) for v in obj]
    if isinstance(obj, str) and obj in NON_FINITE:
        return NON_FINITE[obj]
    return obj


def read_json(path: str | os.PathLike) -> Any:
    """A JSON file of the suite with ``"inf"``, ``"-inf"`` and ``"nan"`` read back as
    floats (:data:`NON_FINITE`); checked against its sidecar where it has one
    (:func:`read_checked`)."""
    return _finite_back(json.loads(read_checked(path).read_text(encoding="utf-8")))


def write_json(path: str | os.PathLike, data: Any) -> None:
    """Atomically write ``data`` as JSON (:func:`json_text`)."""
    write_text(path, json_text(data))


def write_csv(path: str | os.PathLike, frame) -> None:
    """Atomically write a pandas DataFrame as CSV (no index)."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False)


def read_csv(path: str | os.PathLike):
    """A result CSV, after checking it against its sidecar (:func:`read_checked`)."""
    import pandas as pd

    return pd.read_csv(read_checked(path))


def git_commit() -> str:
    """Commit of the working tree (with ``+dirty`` if modified), or ``unknown``."""
    root = Path(__file__).resolve().parent.parent
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                             text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (rev or "unknown") + ("+dirty" if dirty else "")


@lru_cache(maxsize=1)
def _static_provenance() -> dict:
    """The parts of :func:`provenance` that do not change within a process."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    threads = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                              "MKL_NUM_THREADS")}
    return {"commit": git_commit(), "python": platform.python_version(),
            "machine": platform.machine(), "cpu_model": cpu_model(), "node": platform.node(),
            "cpu_count": os.cpu_count(), "threads": threads, "blas": blas_threads(),
            "packages": versions,
            "configfile": os.environ.get("CONTACTBENCH_CONFIGFILE"),
            "config_sha256": os.environ.get("CONTACTBENCH_CONFIG_SHA256")}


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), or the platform's processor string."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def blas_threads() -> dict:
    """Thread counts of the loaded BLAS/OpenMP libraries (threadpoolctl if present)."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return {}
    return {f"{i.get('internal_api')}:{Path(i.get('filepath', '')).name}": i.get("num_threads")
            for i in threadpool_info()}


#: The environment variable through which a regeneration hands its solver set, fixed when
#: it starts (the Snakefile: :func:`solvers.interface.solver_set` as JSON), to every job.
SOLVER_SET_ENV = "CONTACTBENCH_SOLVER_SET"


def run_solver_set() -> dict | None:
    """The solver set of the regeneration this process runs in (``{name: {"role",
    "origin", "package", "version"}}``, fixed when it started), or None outside one."""
    text = os.environ.get(SOLVER_SET_ENV)
    return json.loads(text) if text else None


def run_solvers(registry: dict) -> list[str]:
    """The solvers a study runs by default: the run's fixed set (:func:`run_solver_set`),
    or outside a regeneration every solver of ``registry``.

    Raises
    ------
    ParameterError
        If a solver of the run's set is no longer registered (uninstalled mid-run).
    """
    fixed = run_solver_set()
    if fixed is None:
        return list(registry)
    gone = sorted(set(fixed) - set(registry))
    if gone:
        from problems.spec import ParameterError

        raise ParameterError(f"solver(s) {', '.join(gone)} of this run's solver set (fixed "
                             "when the run started) are no longer registered; allowed: "
                             "reinstall them, or start the run again")
    return [name for name in registry if name in fixed]


def provenance(seed: int | None = None) -> dict:
    """Where a result came from: commit (``+dirty`` if the tree was modified), package
    versions, CPU model, cores and BLAS/OpenMP threads, the workflow's config file and
    hash and the run's solver set with each plug-in's package and version (from the
    Snakefile's environment), time and seed."""
    return {**_static_provenance(), "solver_set": run_solver_set(), "seed": seed,
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds")}


def write_vtu(path: str | os.PathLike, fields: dict) -> None:
    """Write a field dict of :func:`problems.fem.fields.contact_fields` as VTU (atomically).

    Point data: ``displacement``, ``contact_pressure``, ``body``; cell data:
    ``von_mises``. 2D points and vectors get a zero z-component (VTU is 3D).
    """
    import meshio

    points, cells, disp = fields["points"], fields["cells"], fields["displacement"]
    if points.shape[1] == 2:
        points = np.hstack([points, np.zeros((len(points), 1))])
        disp = np.hstack([disp, np.zeros((len(disp), 1))])
    kind = "triangle" if cells.shape[1] == 3 else "tetra"
    mesh = meshio.Mesh(points, [(kind, cells)],
                       point_data={"displacement": disp,
                                   "contact_pressure": fields["contact_pressure"],
                                   "body": np.asarray(fields["body"], dtype=float)},
                       cell_data={"von_mises": [fields["von_mises"]]})
    with atomic_path(path, suffix=".vtu") as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
