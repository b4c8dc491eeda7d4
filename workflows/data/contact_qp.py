"""qpbenchmark test set of an exported contact QP set (``contactbench export``).

This file sits in the exported folder beside ``index.json`` and the problem
folders, and needs neither the suite nor anything beyond numpy, scipy and
qpbenchmark::

    qpbenchmark DIR/contact_qp.py run --solver osqp --settings mid_accuracy \\
        --results-path DIR/results/osqp.csv --author NAME

Each problem is ``min 1/2 x'Px + q'x  s.t.  Gx <= h`` read from ``problem.npz``
(the same arrays as the ``.mtx`` files); the set's problems in the conic form
(``form`` ``cone`` in ``index.json``: 3D frictional steps, second-order cones) are
left out, qpbenchmark takes QPs only. qpbenchmark's default settings and
tolerances apply (``low_accuracy``, ``mid_accuracy``, ``high_accuracy``,
``default``); the time limit per run is ``CONTACT_QP_TIME_LIMIT`` seconds
(default 60). ``CONTACT_QP_DIR`` points the module at another exported folder.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from qpbenchmark.problem import Problem
from qpbenchmark.test_set import TestSet


#: The export's JSON writes a non-finite number as one of these strings (JSON has none).
NON_FINITE = {"inf": float("inf"), "-inf": float("-inf"), "nan": float("nan")}


def read_json(path: Path):
    """A JSON file of the export, its ``"inf"``, ``"-inf"``, ``"nan"`` read as floats."""
    def number(v):
        if isinstance(v, list):
            return [number(x) for x in v]
        return NON_FINITE.get(v, v) if isinstance(v, str) else v

    def back(obj: dict) -> dict:
        return {k: number(v) for k, v in obj.items()}
    with open(path, encoding="utf-8") as fh:
        return json.load(fh, object_hook=back)


def folder() -> Path:
    """The exported set this module reads (its own folder unless ``CONTACT_QP_DIR``)."""
    return Path(os.environ.get("CONTACT_QP_DIR", Path(__file__).resolve().parent))


def read_problem(path: Path, name: str) -> Problem:
    """One exported problem as a qpbenchmark :class:`Problem` (sparse CSC)."""
    with np.load(path / "problem.npz") as z:
        def csc(k):
            return sp.csr_matrix((z[f"{k}_data"], z[f"{k}_indices"], z[f"{k}_indptr"]),
                                 shape=tuple(z[f"{k}_shape"])).tocsc()
        return Problem(csc("P"), z["q"], csc("G"), z["h"], None, None, None, None, name=name)


class ContactQp(TestSet):
    """Two-body contact QPs (frictionless, and 2D Tresca steps) from the contactbench suite."""

    @property
    def description(self) -> str:
        return self.index["description"]

    @property
    def title(self) -> str:
        qps = [e for e in self.index["problems"] if e.get("form", "qp") == "qp"]
        return (f"Contact QP test set {self.index['set']}, class "
                f"{self.index['size_class']} ({len(qps)} QPs)")

    @property
    def sparse_only(self) -> bool:
        return True

    def __init__(self):
        self.index = read_json(folder() / "index.json")
        super().__init__()

    def define_tolerances(self, runtime: float | None = None) -> None:
        super().define_tolerances(
            float(os.environ.get("CONTACT_QP_TIME_LIMIT", 60.0)) if runtime is None else runtime)

    def __iter__(self):
        for entry in self.index["problems"]:
            if entry.get("form", "qp") == "qp":
                yield read_problem(folder() / entry["folder"], entry["name"])
