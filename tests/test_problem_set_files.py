"""Test set version 6 (contact-qp-6): version 5's problems unchanged, and the set's
``files`` (the fclib file and the multigrid data in every problem folder) written by its
export without an option, the folders otherwise version 5's (byte for byte, the Matrix
Market files' arrays exactly)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.io import mmread

from workflows.cli import main
from workflows.problem_set import CURRENT, EXPORT_FILES, TestSetError, load

#: A frictionless and a frictional (Coulomb) family, in the small class.
FAMILIES = ("hard_no_contact", "cube_sphere_coulomb_q05")


def test_version_6_is_version_5_with_its_files():
    v5, v6 = load("contact-qp-5"), load("contact-qp-6")
    assert CURRENT == "contact-qp-6" and v6.files == EXPORT_FILES and v5.files == ()
    assert v6.problems() == v5.problems() and len(v6.problems()) == 252
    assert v6.families == v5.families and v6.classes == v5.classes
    assert v6.description.startswith(v5.description) and "Version 6" in v6.description


def test_a_set_names_only_the_files_the_export_knows(tmp_path):
    mine = tmp_path / "mine.yaml"
    mine.write_text("name: mine\nversion: 1\nextends: contact-qp-5\nfiles: [fclib, pdf]\n")
    with pytest.raises(TestSetError, match=r"'files': \['pdf'\] are not allowed; allowed: "
                                           "fclib, multigrid"):
        load(mine)
    mine.write_text("name: mine\nversion: 1\nextends: contact-qp-6\n")
    assert load(mine).files == EXPORT_FILES           # extending keeps the files


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    out = {}
    for version in ("contact-qp-5", "contact-qp-6"):
        out[version] = tmp_path_factory.mktemp(version) / "set"
        assert main(["export", "--set", version, "--class", "small", "--families", *FAMILIES,
                     "--out", str(out[version]), "--quiet"]) == 0
    return out


def test_the_export_of_version_6_adds_the_files_and_changes_nothing_else(exports):
    index = json.loads((exports["contact-qp-6"] / "index.json").read_text())
    assert index["set"] == "contact-qp-6" and len(index["problems"]) >= 2
    for entry in index["problems"]:
        new = json.loads((exports["contact-qp-6"] / entry["folder"] / "meta.json").read_text())
        old = json.loads((exports["contact-qp-5"] / entry["folder"] / "meta.json").read_text())
        added = set(new["files"]) - set(old["files"])
        assert added == {"fclib.hdf5", "multigrid.npz", "mesh.vtu"}, entry["name"]
        # the same bytes, but for the set's name in the Matrix Market files' comment line
        same = [k for k in old["files"] if not k.endswith(".mtx")]
        assert {k: new["files"][k] for k in same} == {k: old["files"][k] for k in same}
        for name in set(old["files"]) - set(same):
            a, b = (mmread(exports[v] / entry["folder"] / name)
                    for v in ("contact-qp-5", "contact-qp-6"))
            a, b = (x.toarray() if hasattr(x, "toarray") else x for x in (a, b))
            assert np.array_equal(a, b), (entry["name"], name)
        assert new["fclib"]["file"] == "fclib.hdf5" and new["multigrid"]
