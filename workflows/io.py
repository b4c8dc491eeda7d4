"""Files at the edges: atomic writes and run provenance.

Every result file is written to a temporary file in the target directory and
moved into place with ``os.replace``, so a crash never leaves a half-written
file behind (and Snakemake never sees one).
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import tempfile
from contextlib import contextmanager
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any, Iterator

import numpy as np

PACKAGES = ("numpy", "scipy", "scikit-fem", "ngsolve", "pyamg", "osqp", "proxsuite", "clarabel",
            "pandas", "meshio", "matplotlib", "snakemake")


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it into place.

    On an exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix or path.suffix)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would make results private
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text(path: str | os.PathLike, text: str) -> None:
    """Atomically write ``text`` to ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if np.isfinite(x) else str(x)
    return obj


def write_json(path: str | os.PathLike, data: Any) -> None:
    """Atomically write ``data`` as JSON (numpy arrays and scalars converted)."""
    write_text(path, json.dumps(_jsonable(data), indent=1) + "\n")


def write_csv(path: str | os.PathLike, frame) -> None:
    """Atomically write a pandas DataFrame as CSV (no index)."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False)


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


def provenance(seed: int | None = None) -> dict:
    """Where a result came from: commit, package versions, machine, threads, seed."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    threads = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                              "MKL_NUM_THREADS")}
    return {"commit": git_commit(), "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "python": platform.python_version(), "machine": platform.machine(),
            "processor": platform.processor(), "node": platform.node(), "cpu_count": os.cpu_count(),
            "threads": threads, "packages": versions, "seed": seed}


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
