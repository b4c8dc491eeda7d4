"""netgen's meshes kept between processes, in a directory of ``.npz`` files.

Every script of the workflow and the command line keep them where
``$CONTACTBENCH_CACHE_DIR`` names (:func:`keep_meshes_from_environment`); the Snakefile
names ``results/cache/meshes``, so a run's processes mesh each geometry once and a fresh
clone starts with none. Unset or empty: every process meshes anew. A mesh is written
atomically (a reader finds a whole entry or none); an entry that cannot be read is
meshed anew and written again. The keys: :func:`problems.fem.mesh.mesh_key`.
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from problems.fem.mesh import keep_meshes
from workflows.io import atomic_path

#: The environment variable naming the directory (unset or empty: no meshes kept).
CACHE_VARIABLE = "CONTACTBENCH_CACHE_DIR"


@dataclass(frozen=True)
class MeshFiles:
    """A directory of meshes, one ``<key>.npz`` (``points``, ``cells``) per mesh."""

    folder: Path

    def load(self, key: str) -> tuple[np.ndarray, np.ndarray] | None:
        try:
            with np.load(self.folder / f"{key}.npz") as z:
                return z["points"], z["cells"]
        except (OSError, ValueError, KeyError, zipfile.BadZipFile):
            return None

    def keep(self, key: str, points: np.ndarray, cells: np.ndarray) -> None:
        try:
            with atomic_path(self.folder / f"{key}.npz", meta=False) as tmp, \
                    open(tmp, "wb") as out:
                np.savez(out, points=points, cells=cells)
        except OSError:                    # a read-only or full disk: this process meshes
            pass


def keep_meshes_from_environment() -> MeshFiles | None:
    """Keep netgen's meshes in ``$CONTACTBENCH_CACHE_DIR`` (none if unset or empty);
    returns the store."""
    folder = os.environ.get(CACHE_VARIABLE)
    store = MeshFiles(Path(folder)) if folder else None
    keep_meshes(store)
    return store
