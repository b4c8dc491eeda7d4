"""``contactbench study NAME ...`` runs a study's heavy step by hand with the script's own
argument checks: bad input ends with exit code 2 and one line naming what is allowed,
as for every other subcommand; each study declares its commands once (its module)."""
from __future__ import annotations

import importlib

import pytest

from workflows.cli import main
from workflows.studies import STUDIES, study_commands


def test_every_study_runs_by_hand_under_its_own_name():
    commands = study_commands()
    assert set(STUDIES) <= set(commands)
    for module in commands.values():
        assert callable(importlib.import_module(module).main)


def test_an_unknown_study_is_refused_with_the_allowed_names(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["study", "nope"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'nope'" in err and "element_order" in err


def test_the_script_s_own_checks_and_usage_apply(capsys, tmp_path):
    with pytest.raises(SystemExit) as stop:
        main(["study", "contact_solution", "--problem", "circle_square", "--set", "E1=-1",
              "--level", "0", "--outdir", str(tmp_path)])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "parameter 'E1'" in err and "allowed: a number in (0.0, inf)" in err
    assert err.startswith("usage: contactbench study contact_solution")
    assert not any(tmp_path.iterdir())                       # nothing written
    with pytest.raises(SystemExit) as stop:
        main(["study", "element_order", "--levels", "0"])    # a required option missing
    assert stop.value.code == 2 and "--problem" in capsys.readouterr().err
