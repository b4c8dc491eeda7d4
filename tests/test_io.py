"""Files at the edges: atomic writes keep the previous version, results carry a checksummed
sidecar with provenance, corrupted or partial results are detected and swept."""
import json
import os

import pandas as pd
import pytest

from workflows.io import (META, NON_FINITE, PARTIAL, CorruptedResult, check_result, json_text,
                          provenance, read_csv, read_json, run_solvers, sweep_results,
                          write_csv, write_json)


def test_a_failed_write_leaves_the_previous_file_and_no_partial(tmp_path):
    path = tmp_path / "table.csv"
    write_csv(path, pd.DataFrame({"a": [1, 2]}))
    before = (path.read_bytes(), (tmp_path / ("table.csv" + META)).read_bytes())

    class Boom:
        def to_csv(self, tmp, index):
            with open(tmp, "w") as fh:
                fh.write("a\n1\n")               # half-written ...
            raise OSError("disk full")           # ... then the write fails

    with pytest.raises(OSError, match="disk full"):
        write_csv(path, Boom())
    assert (path.read_bytes(), (tmp_path / ("table.csv" + META)).read_bytes()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv", "table.csv" + META]


def test_every_result_has_a_checksummed_sidecar_with_provenance(tmp_path):
    path = tmp_path / "run.json"
    write_json(path, {"x": 1})
    meta = json.loads((tmp_path / ("run.json" + META)).read_text())
    assert meta["bytes"] == path.stat().st_size and len(meta["sha256"]) == 64
    prov = meta["provenance"]
    assert prov["commit"] and prov["cpu_count"] == os.cpu_count() and prov["cpu_model"]
    assert prov["packages"]["numpy"] and "created" in prov
    assert check_result(path)


def test_a_corrupted_result_is_detected_and_swept(tmp_path):
    good, bad = tmp_path / "good.csv", tmp_path / "sub" / "bad.csv"
    for p in (good, bad):
        write_csv(p, pd.DataFrame({"a": range(100)}))
    with open(bad, "r+b") as fh:                # truncated by a crash outside our writers
        fh.truncate(50)
    assert check_result(good) and not check_result(bad)
    assert read_csv(good)["a"].sum() == 4950
    with pytest.raises(CorruptedResult, match="bad.csv"):
        read_csv(bad)
    partial = tmp_path / f".x.csv{PARTIAL}abc.csv"   # left by a killed process
    partial.write_text("half")
    removed = sweep_results(tmp_path)
    assert sorted(map(os.path.basename, removed)) == [partial.name, "bad.csv"]
    assert not bad.exists() and not (tmp_path / "sub" / ("bad.csv" + META)).exists()
    assert good.exists() and check_result(good)


def test_a_file_without_sidecar_is_not_judged(tmp_path):
    plain = tmp_path / "reference.csv"
    plain.write_text("a\n1\n")
    assert check_result(plain) and sweep_results(tmp_path) == []
    assert provenance(seed=3)["seed"] == 3


def test_one_json_convention_for_non_finite_numbers(tmp_path):
    """JSON has no inf or nan: the suite writes them as strings and reads them back."""
    import numpy as np

    data = {"energy_bound": float("inf"), "gap": np.float64(-np.inf), "x": [1.5, np.nan],
            "kkt": None, "n": np.int64(3), "message": "converged"}
    text = json_text(data)
    assert "Infinity" not in text and "NaN" not in text
    raw = json.loads(text)                   # plain JSON for any reader
    assert raw["energy_bound"] == "inf" and raw["gap"] == "-inf" and raw["x"][1] == "nan"
    write_json(tmp_path / "r.json", data)
    back = read_json(tmp_path / "r.json")
    assert back["energy_bound"] == np.inf and back["gap"] == -np.inf
    assert back["x"][0] == 1.5 and np.isnan(back["x"][1])
    assert back["kkt"] is None and back["n"] == 3 and back["message"] == "converged"
    assert set(NON_FINITE) == {"inf", "-inf", "nan"}
    # the exported set's own reader (it needs nothing of the suite) agrees
    import importlib.util
    from workflows.export import QPBENCHMARK_MODULE
    spec = importlib.util.spec_from_file_location("contact_qp", QPBENCHMARK_MODULE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    theirs = module.read_json(tmp_path / "r.json")
    assert theirs["energy_bound"] == np.inf and np.isnan(theirs["x"][1])


def test_a_regeneration_runs_the_solver_set_it_fixed_at_its_start(monkeypatch):
    from problems.spec import ParameterError
    from solvers.interface import solver_set, solvers

    registry = solvers()
    monkeypatch.delenv("CONTACTBENCH_SOLVER_SET", raising=False)
    assert run_solvers(registry) == list(registry)       # outside a run: every solver
    assert provenance()["solver_set"] is None
    fixed = {k: v for k, v in solver_set().items() if k in ("pdas", "osqp")}
    assert fixed["osqp"] == {"role": "library", "origin": "built-in",
                             "package": "contactbench", "version": None}
    monkeypatch.setenv("CONTACTBENCH_SOLVER_SET", json.dumps(fixed))
    # a solver registered after the start (a plug-in installed mid-run) does not join
    assert run_solvers({**registry, "late": registry["osqp"]}) == ["osqp", "pdas"]
    with pytest.raises(ParameterError, match="solver.s. osqp of this run's solver set"):
        run_solvers({k: v for k, v in registry.items() if k != "osqp"})
