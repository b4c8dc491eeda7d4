"""Registries, the command-line interface and bad-input behaviour."""
import json

import pytest

from problems.spec import Parameter, ParameterError, problems, resolve_parameters
from workflows.cli import main


def test_problem_registry_finds_modules_with_a_problem_spec():
    reg = problems()
    assert "laplace_nonmatching" in reg
    assert all(spec.name == name for name, spec in reg.items())
    assert "spec" not in reg and "fem" not in reg  # machinery is not a problem


def test_parameter_validation_messages():
    p = Parameter("load", 0.01, "body force", low=0.0, low_open=True)
    assert p.validate("0.5") == 0.5
    with pytest.raises(ParameterError, match=r"'load'.*\(0.0, inf\)"):
        p.validate("-1")
    with pytest.raises(ParameterError, match="'load'"):
        p.validate("abc")
    with pytest.raises(ParameterError, match="not finite"):
        p.validate("nan")
    with pytest.raises(ParameterError, match="known parameters: load"):
        resolve_parameters((p,), {"lod": 1}, "problem 'x'")


def test_cli_list(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "laplace_nonmatching" in out and "studies" in out and "tolerance presets" in out


def test_cli_solve_writes_json(tmp_path):
    out = tmp_path / "run.json"
    rc = main(["solve", "--problem", "laplace_nonmatching", "--level", "1", "--set", "case=linear",
               "--set", "variant=conforming", "--out", str(out)])
    assert rc == 0
    data = json.loads(out.read_text())
    assert data["status"] == "converged" and data["err_h1"] < 1e-11
    assert data["provenance"]["packages"]["scikit-fem"]


@pytest.mark.parametrize("argv, needle", [
    (["--problem", "nope"], "unknown problem 'nope'; allowed: "),
    (["--problem", "laplace_nonmatching", "--level", "99"], "'level'"),
    (["--problem", "laplace_nonmatching", "--set", "alpha=1"], "known parameters"),
    (["--problem", "laplace_nonmatching", "--set", "case"], "key=value"),
    (["--problem", "laplace_nonmatching", "--solver", "osqp"], "allowed: direct"),
])
def test_cli_bad_input_is_a_clear_error_and_writes_nothing(tmp_path, capsys, argv, needle):
    out = tmp_path / "x.json"
    assert main(["solve", *argv, "--out", str(out)]) == 2
    assert needle in capsys.readouterr().err
    assert not out.exists()


def test_cli_solve_contact_problem_writes_state_and_fields(tmp_path):
    out, vtu = tmp_path / "cs.json", tmp_path / "cs.vtu"
    rc = main(["solve", "--problem", "circle_square", "--level", "0", "--solver", "pdas",
               "--tol", "high", "--set", "E2=2.0", "--out", str(out), "--vtu", str(vtu)])
    assert rc == 0
    data = json.loads(out.read_text())
    assert data["status"] == "converged" and data["kkt_max"] <= 1e-9
    assert data["params"]["E2"] == 2.0 and data["params"]["radius"] == 0.707
    contact = data["contact"]
    assert set(contact) >= {"x", "p", "pressure", "force", "active"}
    assert len(contact["x"]) == data["m"] == 17
    # the square pushes the circle up with the total contact force, and only there
    assert contact["force"][1] > 0 and abs(contact["force"][0]) < 1e-10
    assert abs(contact["force"][1] - sum(contact["p"])) < 1e-14
    import meshio
    mesh = meshio.read(vtu)
    assert {"displacement", "contact_pressure"} <= set(mesh.point_data)
    assert "von_mises" in mesh.cell_data


def test_cli_unknown_solver_option_is_rejected(tmp_path, capsys):
    rc = main(["solve", "--problem", "circle_square", "--level", "0", "--solver", "osqp",
               "--set", "polish=maybe", "--out", str(tmp_path / "x.json")])
    assert rc == 2 and "'polish'" in capsys.readouterr().err
