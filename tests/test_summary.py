"""The summary page at the top of the HTML report (report/summary.py): items, claims with
pass/miss, the thesis's items with their status, provenance disagreements, resources."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from report import summary
from workflows.io import META, write_csv
from workflows.studies import HEAVY_RULES, PATHS, THESIS_ITEMS


def test_parse_items_names_the_bad_item():
    assert summary.parse_items(["hertz@circle_square=a.csv", "laplace_rates@-=b.csv"]) == [
        ("hertz", "circle_square", "a.csv"), ("laplace_rates", None, "b.csv")]
    for bad in ("hertz=a.csv", "nokey@x=a.csv", "hertz@x="):
        with pytest.raises(ValueError, match="--items"):
            summary.parse_items([bad])


def _hertz(path, devs):
    write_csv(path, pd.DataFrame({"level": range(1, len(devs) + 1), "a_over_h": 5.0,
                                  "dev_a_moment": devs, "dev_p0_moment": devs}))


def test_claims_are_judged_from_the_outputs(tmp_path):
    good, bad = tmp_path / "good.csv", tmp_path / "bad.csv"
    _hertz(good, [0.2, 0.01])            # within the 5 % bar and falling
    _hertz(bad, [0.01, 0.2])             # outside the bar and rising
    items = summary.parse_items([f"hertz@circle_square={good}", f"hertz@cube_sphere={bad}"])
    claims = summary.collect_claims(items)
    assert set(claims["study"]) == {"contact_solution"}
    assert (claims[claims.scene == "circle_square"]["result"] == "pass").all()
    assert (claims[claims.scene == "cube_sphere"]["result"] == "miss").all()
    assert len(claims) == 8                # a and p0: the bar and the trend, per scene


def test_thesis_rows_cover_every_item_with_its_status(tmp_path):
    items = [("ap_table", "circle_square", "results/circle_square/augmented_projection_table.csv")]
    rows = summary.thesis_rows(items, "quick")
    assert len(rows) == len(THESIS_ITEMS)
    table_9_1 = rows[rows.thesis == "Table 9.1"].iloc[0]
    assert table_9_1.status == "regenerated" and "augmented_projection" in table_9_1.output
    table_9_3 = rows[rows.thesis == "Table 9.3"].iloc[0]
    assert table_9_3.status == "not in this configuration"
    assert table_9_3.output.endswith("not at the quick scale (a larger one regenerates it)")
    assert set(rows.status) <= {"regenerated", "not regenerated", "not in this configuration"}


def test_provenance_disagreement_is_reported(tmp_path):
    paths = []
    for k, commit in enumerate(("abc", "abc", "def+dirty")):
        p = tmp_path / f"r{k}.csv"
        p.write_text("x\n1\n")
        (tmp_path / f"r{k}.csv{META}").write_text(json.dumps(
            {"provenance": {"commit": commit, "created": f"2026-11-2{k}T00:00:00"}}))
        paths.append(str(p))
    newest, varying = summary.read_provenance(paths)
    assert newest["commit"] == "def+dirty"
    assert varying["commit"] == {"abc": 2, "def+dirty": 1}


def test_resources_per_rule_and_study(tmp_path):
    for rule, name, s, rss in (("contact_level", "a_L1", 2.0, 100.0),
                               ("contact_level", "a_L2", 5.0, 300.0),
                               ("patch_test", "flat", 1.0, 50.0)):
        (tmp_path / rule).mkdir(exist_ok=True)
        (tmp_path / rule / f"{name}.tsv").write_text(
            "s\th:m:s\tmax_rss\tmax_vms\n" f"{s}\t0:00:0{int(s)}\t{rss}\t1.0\n")
    res = summary.resources(str(tmp_path)).set_index("rule")
    assert res.loc["contact_level", "jobs"] == 2
    assert res.loc["contact_level", "wall_s_total"] == 7.0
    assert res.loc["contact_level", "max_rss_mb"] == 300.0
    assert res.loc["patch_test", "study"] == HEAVY_RULES["patch_test"] == "adaptive"
    assert summary.resources(str(tmp_path / "none")).empty


def test_main_writes_page_and_claims(tmp_path):
    hertz = tmp_path / "hertz.csv"
    _hertz(hertz, [0.2, 0.01])
    html, claims = tmp_path / "s.html", tmp_path / "c.csv"
    summary.main(["--items", f"hertz@circle_square={hertz}", "--scale", "tiny",
                  "--html", str(html), "--claims", str(claims)])
    text = html.read_text()
    assert "4 pass" in text and "0 miss" in text and "Table 9.1" in text
    assert "No benchmark files found" in text
    assert len(pd.read_csv(claims)) == 4


def test_main_rejects_a_bad_item(tmp_path, capsys):
    with pytest.raises(SystemExit) as err:
        summary.main(["--items", "nokey@x=y.csv", "--html", str(tmp_path / "s.html"),
                      "--claims", str(tmp_path / "c.csv")])
    assert err.value.code == 2 and "--items" in capsys.readouterr().err
    assert not (tmp_path / "s.html").exists()
    assert "summary_html" in PATHS


def _boards():
    """leaderboards.csv of a run: one frictionless board with a reference and a solver
    declining the class."""
    import pandas as pd
    rows = [("ranked", 1, "osqp", 2, 2, 1.0, 1.0, True, ""),
            ("ranked", 2, "scs", 1, 0, 0.5, np.inf, False, "1 inaccurate (energy_bound)"),
            ("reference", np.nan, "pdas", 2, 2, 1.0, 0.5, False, ""),
            ("declined", np.nan, "tresca_exact", np.nan, np.nan, np.nan, np.nan, False, "")]
    return pd.DataFrame([{"problem_class": "frictionless", "size_class": "small",
                          "preset": "mid", "standing": st, "rank": r, "solver": s,
                          "problems": 2, "verified": v, "skipped": 0, "plain_verified": pv,
                          "correct_share": c, "median_ratio": m, "sgm_time": 0.1,
                          "spread": 0.05, "not_verified": nv, "fastest": f, "shift": 0.01,
                          "independent_agreement": 1e-9 if st == "reference" else np.nan,
                          "note": "a frictionless problem" if st == "declined" else "",
                          "time_limit": 20.0, "load": "taken alone"}
                         for st, r, s, v, pv, c, m, f, nv in rows])


def test_the_summary_shows_one_leaderboard_per_class_with_the_references_apart():
    from report.leaderboard import leaderboard, leaderboards_html
    board = leaderboard(_boards())
    assert list(board["rank"]) == [1, 2, "baseline"]
    assert list(board["solver"]) == ["osqp (fastest verified)", "scs", "pdas (exact reference)"]
    assert list(board["verified"]) == ["2 of 2", "1 of 2", "2 of 2"]
    page = "".join(leaderboards_html(_boards()))
    assert "fastest verified <b>osqp</b>" in page and "taken alone" in page
    assert "exact reference pdas within 1e-09 of the closest independent" in page
    assert "Declined the class (not ranked): tresca_exact: a frictionless problem" in page
    assert "shift 0.01 s" in page and "time limit 20 s" in page


def test_tables_put_the_thesis_beside_ours_and_explain_empty_cells():
    import pandas as pd

    from report.summary import beside_thesis
    from report.tables import EMPTY_THESIS, cell_text, table_html
    frame = pd.DataFrame({"level": [0, 1], "N": [10, 40], "n_outer": [7, 8], "t": [1.0, 2.0],
                          "thesis_nodes": [None, 42], "thesis_n_outer": [None, 19]})
    assert list(beside_thesis(frame, keep=("level",)).columns) == [
        "level", "N", "thesis_nodes", "n_outer", "thesis_n_outer"]
    assert "-" not in cell_text(1e-9) and cell_text(float("nan")) == ""
    html = table_html(beside_thesis(frame), name="x")
    assert html.count(f'title="{EMPTY_THESIS}"') == 2 and EMPTY_THESIS in html


def test_failures_link_each_failing_scene_to_its_rows():
    import pandas as pd

    from report.leaderboard import failure_anchor, failures
    from report.tables import table_html
    by_scene = pd.DataFrame({"preset": ["mid", "low", "low", "low"],
                             "solver": ["pdas", "osqp", "osqp", "pdas"],
                             "scene": ["roll_stack", "cube_sphere", "circle_square", "flat"],
                             "runs": [2, 2, 2, 2], "converged": [0, 1, 2, 2],
                             "inaccurate": [2, 1, 0, 0]})
    fails = failures(by_scene)
    assert list(fails["scene"]) == ["cube_sphere", "roll_stack"]     # converged < runs only
    page = table_html(fails, name="failures",
                              row_id=lambda r: failure_anchor(r["scene"]))
    assert page.count("id='failures-cube_sphere'") == 1 and "id='failures-roll_stack'" in page


def test_tables_read_their_headers_and_sort_minus_signs_as_numbers():
    from report.tables import header_text, sort_value, table_html
    assert header_text("thesis_n_outer_1e-03") == "thesis n outer 1e\u201103"
    assert sort_value("\u22120.5") == "-0.5" and sort_value(-2) == "-2.0"
    assert sort_value("3 of 3") is None and sort_value(True) is None
    html = table_html(pd.DataFrame({"n_outer": [-1.5, 2.0], "note": ["a", "b"]}), name="h")
    assert ">n outer</th>" in html and "_" not in html.split("<tr>")[1]
    assert 'data-v="-1.5"' in html and "\u22121.5" in html


def test_the_thesis_value_sits_beneath_ours_and_items_name_their_scene():
    from report.summary import beside_thesis, item_path, thesis_mates
    from report.tables import table_html
    frame = beside_thesis(pd.DataFrame({"level": [1], "N": [4237], "thesis_nodes": [4226],
                                        "kappa_S": [34.8], "thesis_kappa_S": [21.2]}))
    assert thesis_mates(frame) == {"N": "thesis_nodes", "kappa_S": "thesis_kappa_S"}
    html = table_html(frame, name="t", below=thesis_mates(frame))
    assert html.count("<th") == 3 and "4237<br><span class='under'>4226</span>" in html
    for item in THESIS_ITEMS:
        if item.key is not None:
            assert "{" not in item_path(item), item
    rows = summary.thesis_rows([], "tiny")
    assert not rows["output"].str.contains("{", regex=False).any()


def test_a_csv_table_is_a_page_of_its_own(tmp_path, monkeypatch):
    from report import tables
    from workflows import table_pages
    from workflows.table_pages import Shown, page_path, shown_pages, shown_table
    monkeypatch.setattr(table_pages, "TABLE_PAGES", {})
    path = shown_table("results/{scene}/x_table.csv", caption="c.rst", category="{scene}",
                       subcategory="tables of {scene}")
    assert path == "results/{scene}/x_table.csv" and page_path(path) == "results/{scene}/x_table.html"
    assert shown_pages(["results/cs/y.csv", "results/cs/x_table.csv"]) == [
        ("results/cs/x_table.csv", "results/cs/x_table.html",
         Shown("c.rst", "cs", "tables of cs"))]     # the wildcards filled, other CSVs not shown
    frames = [pd.DataFrame({"level": [0, 1], "err_energy": [1e-3, -2e-4]}),
              pd.DataFrame({"solver": ["tnnmg"], "time_s": [0.5]})]
    csvs = [tmp_path / f"t{i}.csv" for i in range(2)]
    for csv, frame in zip(csvs, frames):
        write_csv(csv, frame)
    pages = [tmp_path / f"t{i}.html" for i in range(2)]
    tables.main(["--csv", *map(str, csvs), "--html", *map(str, pages)])
    first, second = (page.read_text() for page in pages)
    assert first.startswith("<!DOCTYPE html>") and "err energy" in first and "cbSort" in first
    assert "tnnmg" in second and "tnnmg" not in first     # each page its own table


def test_table_pages_need_one_page_per_table(tmp_path, capsys):
    from report import tables
    with pytest.raises(SystemExit):
        tables.main(["--csv", "a.csv", "b.csv", "--html", str(tmp_path / "a.html")])
    assert "--html: 1 pages for 2 tables" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())                   # nothing written

