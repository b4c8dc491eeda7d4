"""Fixtures shared by several test files."""
from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

# netgen's meshes kept for the session's processes (workflows/mesh_store.py), in a
# directory of its own: nothing read from an earlier run
os.environ.setdefault("CONTACTBENCH_CACHE_DIR", tempfile.mkdtemp(prefix="contactbench-meshes-"))
atexit.register(shutil.rmtree, os.environ["CONTACTBENCH_CACHE_DIR"], ignore_errors=True)

#: The templates of a solver and of a scene in a package of their own (entry-point groups
#: contactbench.solvers and contactbench.scenes).
EXAMPLE_SOLVER = Path(__file__).resolve().parent / "example_solver"
EXAMPLE_SCENE = Path(__file__).resolve().parent / "example_scene"


def install_example(example: Path, tmp_path_factory) -> Path:
    """``pip install`` the example package ``example`` into a folder of its own (as a user
    installs a plug-in; nothing of the suite's environment changes) and return it."""
    target = tmp_path_factory.mktemp("site")
    source = tmp_path_factory.mktemp("src") / example.name      # pip builds in the tree
    shutil.copytree(example, source, ignore=shutil.ignore_patterns("build", "*.egg-info"))
    out = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                          "--no-build-isolation", "--target", str(target), str(source)],
                         capture_output=True, text=True, timeout=600, cwd=source)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-3000:]
    assert list(target.glob("contactbench_example_*.dist-info"))
    return target


@pytest.fixture(scope="session")
def plugin_env(tmp_path_factory) -> dict:
    """The environment of a user who has installed the example solver's package."""
    target = install_example(EXAMPLE_SOLVER, tmp_path_factory)
    path = os.pathsep.join(filter(None, [str(target), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path}


@pytest.fixture(scope="session")
def example_scene_site(tmp_path_factory) -> Path:
    """The folder the example scene's package is installed into."""
    return install_example(EXAMPLE_SCENE, tmp_path_factory)


@pytest.fixture(scope="module")
def with_example_scene(example_scene_site):
    """The example scene registered in this process for one test module (as if its package
    were installed): ``problems()`` lists ``cylinder_pair`` until the module ends."""
    from problems.spec import external_problems

    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(example_scene_site))
        external_problems.cache_clear()
        yield
    external_problems.cache_clear()


@pytest.fixture
def cg_steps(monkeypatch) -> list:
    """The steps of every ``scipy.sparse.linalg.cg`` call the test makes, in order."""
    import scipy.sparse.linalg as linalg

    steps, plain_cg = [], linalg.cg

    def counted_cg(*args, **kwargs):
        count = [0]
        out = plain_cg(*args, callback=lambda _: count.__setitem__(0, count[0] + 1), **kwargs)
        steps.append(count[0])
        return out

    monkeypatch.setattr(linalg, "cg", counted_cg)
    return steps


@pytest.fixture
def qpbenchmark_set(monkeypatch):
    """``load(path)``: qpbenchmark's ``load_test_set`` on an export's ``contact_qp.py``, fresh.

    qpbenchmark appends the module's folder to ``sys.path`` and imports it by name, so in
    one process a second export's module would be the first one's (same name, first folder
    on the path): each load here drops the cached module, and the path is restored after
    the test."""
    from qpbenchmark.benchmark import load_test_set

    monkeypatch.setattr(sys, "path", list(sys.path))

    def load(path):
        monkeypatch.delitem(sys.modules, Path(path).stem, raising=False)
        return load_test_set(str(path))

    return load


#: The test files whose runs take minutes, started first when the tests are spread over
#: several processes (``make test``: pytest-xdist, a file to a process, in this order), so
#: that no process is left with one of them at the end while the others wait.
LONGEST_FIRST = ("test_regeneration.py", "test_friction_random.py", "test_friction_3d_solvers.py",
                 "test_workflow.py",
                 "test_quadratic.py", "test_plugins.py", "test_problem_set.py", "test_cli.py",
                 "test_petsc_tao.py", "test_hard_cases.py", "test_roll_stack_study.py")


def pytest_collection_modifyitems(items):
    """Run the files of :data:`LONGEST_FIRST` first, in its order (a stable sort: the order
    within a file and of the other files is kept)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def pytest_terminal_summary(terminalreporter):
    """The lines tests published with ``record_property("summary", text)`` (the random
    frictional family's counts of draws and fallbacks), printed after the run; their
    reports carry them from pytest-xdist's workers."""
    lines = [value for key in ("passed", "failed")
             for report in terminalreporter.stats.get(key, [])
             for name, value in getattr(report, "user_properties", []) if name == "summary"]
    if lines:
        terminalreporter.section("summaries")
        for line in lines:
            terminalreporter.write_line(line)
