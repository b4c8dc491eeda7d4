"""netgen's meshes kept between processes (workflows/mesh_store.py, problems/fem/mesh.py)."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from problems.fem import mesh
from problems.fem.mesh import _kept, keep_meshes, mesh_key, netgen_ball
from workflows.mesh_store import CACHE_VARIABLE, MeshFiles, keep_meshes_from_environment


@pytest.fixture
def store(tmp_path):
    """A fresh directory store for the test, the session's store back afterwards."""
    before = mesh._STORE[0]
    keep_meshes(MeshFiles(tmp_path / "meshes"))
    yield mesh._STORE[0]
    keep_meshes(before)


def counting_generator():
    calls = []

    def generate(center, radius, maxh):
        calls.append((tuple(center), radius, maxh))
        return np.array([[0.0, 0.0], [radius, 0.0], [0.0, maxh]]), np.array([[0, 1, 2]])

    return generate, calls


def test_a_kept_mesh_is_generated_once_per_store(store):
    generate, calls = counting_generator()
    first = _kept(generate)((0.0, 0.0), 1.0, 0.5)
    again = _kept(generate)((0.0, 0.0), 1.0, 0.5)        # a second process: no lru cache
    other = _kept(generate)((0.0, 0.0), 1.0, 0.25)
    assert len(calls) == 2 and calls[1][2] == 0.25
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)
    assert other[0][2, 1] == 0.25
    assert len(list(store.folder.glob("generate-*.npz"))) == 2


def test_without_a_store_every_call_generates():
    before = mesh._STORE[0]
    keep_meshes(None)
    try:
        generate, calls = counting_generator()
        _kept(generate)((0.0, 0.0), 1.0, 0.5)
        _kept(generate)((0.0, 0.0), 1.0, 0.5)
    finally:
        keep_meshes(before)
    assert len(calls) == 2


def test_an_unreadable_entry_is_meshed_anew(store):
    generate, calls = counting_generator()
    key = mesh_key(generate, (0.0, 0.0), (1.0, 0.5))
    store.folder.mkdir(parents=True)
    (store.folder / f"{key}.npz").write_bytes(b"not a zip file")
    points, _ = _kept(generate)((0.0, 0.0), 1.0, 0.5)
    assert len(calls) == 1 and points[1, 0] == 1.0
    assert store.load(key)[0][1, 0] == 1.0                 # written again, whole


def test_a_read_only_store_leaves_the_meshes_to_each_process(tmp_path):
    blocked = tmp_path / "file"
    blocked.write_text("a file where the directory would be")
    files = MeshFiles(blocked / "meshes")
    files.keep("k", np.zeros((3, 2)), np.zeros((1, 3), dtype=np.int64))
    assert files.load("k") is None


def test_the_key_names_the_generator_and_its_arguments():
    generate, _ = counting_generator()
    key = mesh_key(generate, (0.0, 0.0), (1.0, 0.5))
    assert key.startswith("generate-")
    assert key == mesh_key(generate, (0.0, 0.0), (1.0, 0.5))
    assert key != mesh_key(generate, (0.0, 0.0), (1.0, 0.25))
    assert key != mesh_key(netgen_ball.__wrapped__, (0.0, 0.0), (1.0, 0.5))


def test_netgen_meshes_the_ball_identically_each_time(store):
    """What keeping a mesh relies on: netgen gives the same arrays for the same call, so
    a kept mesh is the one the process would have generated."""
    kept = _kept(netgen_ball.__wrapped__)((0.0, 0.0, 0.0), 1.0, 0.6)
    fresh = netgen_ball.__wrapped__(np.array([0.0, 0.0, 0.0]), 1.0, 0.6)
    read = _kept(netgen_ball.__wrapped__)((0.0, 0.0, 0.0), 1.0, 0.6)
    assert kept[1].shape[0] > 50
    for a, b, c in zip(kept, fresh, read):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)


@pytest.mark.parametrize("package", ["workflows.studies", "workflows.scripts"])
def test_the_steps_keep_meshes_where_the_environment_says(tmp_path, package):
    """A study's run step (any module of the studies' package) and a benchmark script keep
    netgen's meshes where $CONTACTBENCH_CACHE_DIR says."""
    code = (f"import {package}; from problems.fem import mesh; "
            "print(mesh._STORE[0].folder)")
    env = {**os.environ, CACHE_VARIABLE: str(tmp_path / "kept")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == str(tmp_path / "kept")


@pytest.mark.parametrize("value", ["", None])
def test_no_directory_no_store(monkeypatch, value):
    before = mesh._STORE[0]
    if value is None:
        monkeypatch.delenv(CACHE_VARIABLE, raising=False)
    else:
        monkeypatch.setenv(CACHE_VARIABLE, value)
    try:
        assert keep_meshes_from_environment() is None and mesh._STORE[0] is None
    finally:
        keep_meshes(before)
