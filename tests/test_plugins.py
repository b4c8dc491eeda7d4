"""Bring your own solver: a solver in another installed package joins through the
entry-point group ``contactbench.solvers`` without a file of the suite changed.

The example package (``tests/example_solver``: projected Barzilai-Borwein on the dual) is
installed with pip into a temporary folder that only the subprocesses here see
(``PYTHONPATH``), then run as a user would: ``contactbench list``, ``contactbench solve``
and the solver comparison of one scene level (what the study's rule runs). A broken or
clashing plug-in is left out with a warning, never a traceback.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pandas as pd
import pytest

from solvers import interface
from solvers.interface import ENTRY_POINT_GROUP, SolverSpec, solvers

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = Path(__file__).resolve().parent / "example_solver"
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory) -> dict:
    """The environment of a user who has installed the example package."""
    target = tmp_path_factory.mktemp("site")
    source = tmp_path_factory.mktemp("src") / "example_solver"    # pip builds in the tree
    shutil.copytree(EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info"))
    out = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                          "--no-build-isolation", "--target", str(target), str(source)],
                         capture_output=True, text=True, timeout=600, cwd=source)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-3000:]
    assert list(target.glob("contactbench_example_solver-*.dist-info"))
    path = os.pathsep.join(filter(None, [str(target), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path}


def run(args: list[str], env: dict, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, timeout=600, env=env, cwd=cwd)


def test_the_plugin_is_listed(plugin_env, tmp_path):
    out = run([str(BIN / "contactbench"), "list"], plugin_env, tmp_path)
    assert out.returncode == 0, out.stderr
    line = next(l for l in out.stdout.splitlines() if l.strip().startswith("dual_bb"))
    assert "[other; plug-in contactbench_example_solver]" in line
    assert "--set rtol=" in out.stdout            # its declared option, as for every solver
    # without the package nothing of it is there
    bare = run([str(BIN / "contactbench"), "list"], dict(os.environ), tmp_path)
    assert "dual_bb" not in bare.stdout


def test_the_plugin_solves_through_the_cli_and_is_verified(plugin_env, tmp_path):
    out = run([str(BIN / "contactbench"), "solve", "--problem", "circle_square", "--level", "0",
               "--solver", "dual_bb", "--set", "rtol=0.01", "--out", str(tmp_path / "r.json")],
              plugin_env, tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["solver"] == "dual_bb" and data["solver_options"] == {"rtol": 0.01}
    # the suite's verification, not the plug-in's word: KKT and the certified bound
    assert data["status"] == "converged", data["message"]
    assert data["kkt_max"] <= 1e-6 and data["energy_bound"] <= 1e-6


@pytest.mark.parametrize("scene", ["circle_square", "cube_sphere"])
def test_the_template_verifies_at_mid_without_changes(plugin_env, tmp_path, scene):
    """The template as it is (default options, default max_iter) at the preset mid on
    level 1: its own stop is tight enough for the suite's verification."""
    out = run([str(BIN / "contactbench"), "solve", "--problem", scene, "--level", "1",
               "--solver", "dual_bb", "--out", str(tmp_path / "r.json")], plugin_env, tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    data = json.loads((tmp_path / "r.json").read_text())
    assert (data["status"], data["failed_check"]) == ("converged", ""), data["message"]
    assert data["kkt_max"] <= 1e-6 and data["energy_bound"] <= 1e-6
    assert data["solver_options"] == {"rtol": 0.5}


def test_the_plugin_is_recorded_with_its_package_in_the_solver_set(plugin_env, tmp_path):
    out = run([sys.executable, "-c", "import json; from solvers.interface import solver_set; "
               "print(json.dumps(solver_set()))"], plugin_env, ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    fixed = json.loads(out.stdout)
    assert fixed["dual_bb"] == {"role": "other", "origin": "plug-in",
                                "package": "contactbench-example-solver", "version": "0.1.0"}
    assert fixed["osqp"]["origin"] == "built-in"


def test_the_plugin_runs_in_the_solver_comparison(plugin_env, tmp_path):
    """The script the study's rule runs, with the config line ``solvers: [dual_bb, osqp]``
    turned into its ``--solvers`` (workflows/solver_comparison.smk)."""
    csv = tmp_path / "solvers_L0.csv"
    out = run([sys.executable, "-m", "workflows.scripts.solver_comparison", "--problem",
               "circle_square", "--level", "0", "--solvers", "dual_bb", "osqp", "--presets",
               "mid", "--time-limit", "60", "--out", str(csv)], plugin_env, ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    table = pd.read_csv(csv)
    row = table[table.solver == "dual_bb"].iloc[0]
    assert row.status == "converged" and row.energy_error < 1e-5
    assert set(table.solver) == {"pdas", "linear_floor", "dual_bb", "osqp"}


def test_the_plugin_joins_a_study_by_a_config_line(plugin_env, tmp_path):
    """The solver comparison study of the tiny scale, regenerated by Snakemake with one
    line added to its config: ``solvers: [dual_bb, osqp]``."""
    import yaml

    config = yaml.safe_load((ROOT / "workflows/config/tiny.yaml").read_text())
    config["solver_comparison"]["solvers"] = ["dual_bb", "osqp"]
    configfile = tmp_path / "with_plugin.yaml"
    configfile.write_text(yaml.safe_dump(config))
    out = run([str(BIN / "snakemake"), "-s", str(ROOT / "Snakefile"), "--configfile",
               str(configfile), "--profile", str(ROOT / "workflows/profiles/default"),
               "--cores", "2", "results/circle_square/solvers.csv"], plugin_env, tmp_path)
    assert out.returncode == 0, (out.stdout + out.stderr)[-4000:]
    table = pd.read_csv(tmp_path / "results/circle_square/solvers.csv")
    assert set(table.solver) == {"pdas", "linear_floor", "dual_bb", "osqp"}
    assert (table.loc[table.solver == "dual_bb", "status"] == "converged").all()
    # the run's solver set, fixed when it started, is in every result's provenance
    meta = json.loads((tmp_path / "results/circle_square/solvers.csv.meta.json").read_text())
    fixed = meta["provenance"]["solver_set"]
    assert fixed["dual_bb"]["package"] == "contactbench-example-solver"
    assert fixed["dual_bb"]["version"] == "0.1.0" and "osqp" in fixed


def test_the_config_line_is_checked_against_the_registry():
    from workflows.studies import ConfigError, check_config

    import yaml
    config = yaml.safe_load((ROOT / "workflows/config/tiny.yaml").read_text())
    config["solver_comparison"]["solvers"] = ["osqp", "dual_bb"]
    with pytest.raises(ConfigError, match=r"'solver_comparison.solvers': \['dual_bb'\] are not"):
        check_config(config)
    config["solver_comparison"]["solvers"] = ["osqp", "pdas"]
    check_config(config)


class _EntryPoint:
    def __init__(self, name, value, load):
        self.name, self.value, self._load = name, value, load

    def load(self):
        return self._load()


def _with_entry_points(monkeypatch, eps):
    import importlib.metadata as md

    monkeypatch.setattr(md, "entry_points",
                        lambda group=None: [e for e in eps] if group == ENTRY_POINT_GROUP else [])
    interface.external_solvers.cache_clear()


def test_a_broken_or_clashing_plugin_is_left_out_with_a_warning(monkeypatch):
    osqp = solvers()["osqp"]
    good = SolverSpec(name="mine", summary="x", solve=osqp.solve)

    def broken():
        raise ImportError("no module named 'their_dependency'")

    eps = [_EntryPoint("broken", "pkg:SOLVER", broken),
           _EntryPoint("notaspec", "pkg:thing", lambda: 42),
           _EntryPoint("clash", "pkg:OSQP", lambda: SolverSpec(name="osqp", summary="mine",
                                                               solve=osqp.solve)),
           _EntryPoint("mine", "pkg:SOLVER", lambda: good),
           _EntryPoint("mine_again", "other:SOLVER",
                       lambda: SolverSpec(name="mine", summary="y", solve=osqp.solve))]
    try:
        _with_entry_points(monkeypatch, eps)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            registry = solvers()
        text = "\n".join(str(w.message) for w in caught)
        assert registry["mine"] is good and registry["osqp"] is osqp
        assert "'broken' (pkg:SOLVER) is left out: it could not be loaded (ImportError" in text
        assert "'notaspec' (pkg:thing) is left out: it names a int" in text
        assert "'osqp'" in text and "a built-in solver has that name" in text
        assert "'mine_again' (other:SOLVER) is left out: another plug-in registers" in text
    finally:
        monkeypatch.undo()
        interface.external_solvers.cache_clear()
    assert "mine" not in solvers()
