"""``tests/compare_results.py``, the comparison of two regenerations' result tables: the
columns that differ named, timing columns and row order ignored, and the rows of two
checkouts paired by what identifies them even where their results differ in the last
digits."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from compare_results import differences, main, measured


def checkout(root: Path, frame: pd.DataFrame) -> Path:
    (root / "results").mkdir(parents=True)
    frame.to_csv(root / "results" / "solver.csv", index=False)
    return root


#: A residual first: sorted on before the rest, it would pair the rows by its last digits.
ROWS = {"kkt_max": [2e-11, 1e-11, 3e-12], "solver": ["tnnmg", "tnnmg", "ssn"],
        "start": ["cold", "warm", "cold"], "steps": [5, 3, 7], "t_solve": [0.5, 0.2, 0.9]}


def test_rows_pair_by_what_identifies_them(tmp_path):
    """The second checkout's residuals differ in the last digits and would sort the two
    TNNMG rows the other way round; they are still paired by solver, start and steps, so
    only the residual column is named, and a changed count is named as such."""
    a = checkout(tmp_path / "a", pd.DataFrame(ROWS))
    rounded = dict(ROWS, kkt_max=[2e-11, 3e-11, 3e-12], t_solve=[0.7, 0.1, 1.0])
    b = checkout(tmp_path / "b", pd.DataFrame(rounded).iloc[[2, 1, 0]])
    assert differences(a, b) == {"results/solver.csv": ["kkt_max"]}
    c = checkout(tmp_path / "c", pd.DataFrame(dict(ROWS, steps=[5, 4, 7])))
    assert differences(a, c) == {"results/solver.csv": ["steps"]}


def test_timing_only_differences_are_no_differences(tmp_path, capsys):
    a = checkout(tmp_path / "a", pd.DataFrame(ROWS))
    b = checkout(tmp_path / "b", pd.DataFrame(dict(ROWS, t_solve=[9.0, 8.0, 7.0])).iloc[::-1])
    assert main([str(a), str(b)]) == 0
    assert "0 differ" in capsys.readouterr().out
    assert main([str(a)]) == 2


def test_measured_columns_are_the_non_integer_reals():
    assert measured(pd.Series(["1e-11", "", "0.5"]))
    assert not measured(pd.Series(["3.0", "", "5.0"]))        # a count written as floats
    assert not measured(pd.Series(["cold", "warm"]))
