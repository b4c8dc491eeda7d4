"""Resources of a scale predicted from measured scaling (workflows/planning.py)."""
from __future__ import annotations

import math

import pandas as pd
import pytest
import yaml

from workflows import planning as pr


def _config(levels_2d, levels_3d, max_nodes=None):
    config = {"scenes": {"circle_square": {"problem": "circle_square"},
                         "cube_sphere": {"problem": "cube_sphere"}},
              "contact_solution": {"scenes": {"circle_square": levels_2d,
                                              "cube_sphere": levels_3d}}}
    if max_nodes:
        config["adaptive"] = {"scenes": {"circle_square": [0]},
                              "max_nodes": {"circle_square": max_nodes}}
    return config


def _bench(directory, rule, name, seconds, mb):
    (directory / rule).mkdir(parents=True, exist_ok=True)
    pd.DataFrame([{"s": seconds, "h:m:s": "0:00:01", "max_rss": mb, "max_vms": mb}]).to_csv(
        directory / rule / f"{name}.tsv", sep="\t", index=False)


def test_known_power_laws_are_carried_one_level_on(tmp_path):
    """Time ~ N^1.5 and memory above the floor ~ N in 2D (N x4 per level), time ~ N in 3D
    (N x8): the plan finds the exponents and predicts the next levels exactly; the rule's
    exponent is its worst scene's."""
    quick, full = tmp_path / "quick", tmp_path / "full"
    floor = 300.0
    for directory, levels in ((quick, [1, 2]), (full, [1, 2, 3])):
        for lv in levels:
            _bench(directory, "contact_level", f"circle_square_L{lv}", 2.0 * 4.0 ** (1.5 * lv),
                   floor + 10.0 * 4.0 ** lv)
        for lv in levels[:-1]:
            _bench(directory, "contact_level", f"cube_sphere_L{lv}", 3.0 * 8.0 ** lv,
                   floor + 5.0 * 8.0 ** lv)
        _bench(directory, "adaptive_study", "circle_square", 10.0 if directory == quick else 80.0,
               floor + (100.0 if directory == quick else 800.0))
    measured = [(_config([1, 2], [1], 10000), quick), (_config([1, 2, 3], [1, 2], 40000), full)]
    table = pr.plan(measured, _config([1, 2, 3, 4], [1, 2, 3], 160000), floor_mb=floor)
    table = table.set_index("rule")
    row = table.loc["contact_level"]
    assert row["exponent_time"] == pytest.approx(1.5) and row["exponent_memory"] == pytest.approx(1.0)
    assert row["largest_job"] == "circle_square_L4" and row["from_job"] == "circle_square_L3"
    assert row["t_pred_s"] == pytest.approx(2.0 * 4.0 ** 6)
    assert row["mb_pred"] == pytest.approx(floor + 10.0 * 4.0 ** 4)
    assert row["runtime"] == math.ceil(2 * 2.0 * 4.0 ** 6 / 60)
    assert row["mem_mb"] == math.ceil(1.5 * (floor + 10.0 * 4.0 ** 4) / 100) * 100
    ad = table.loc["adaptive_study"]                     # by its node budget: 8x for 4x nodes
    assert ad["exponent_time"] == pytest.approx(1.5) and ad["t_pred_s"] == pytest.approx(640.0)
    text = pr.resources_yaml(table.reset_index())
    parsed = yaml.safe_load(text)["resources"]
    assert parsed["contact_level"] == {"mem_mb": int(row["mem_mb"]), "runtime": int(row["runtime"])}


def test_a_rule_measured_at_one_size_borrows_its_proxy_and_a_missing_one_is_named(tmp_path):
    quick = tmp_path / "quick"
    for lv in (1, 2):
        _bench(quick, "contact_level", f"circle_square_L{lv}", 4.0 ** lv, 300.0 + 4.0 ** lv)
    _bench(quick, "patch_test", "flat_blocks", 5.0, 400.0)
    config = _config([1, 2], [])
    config["adaptive"] = {"scenes": {}, "max_nodes": {},
                          "patch_test": {"scenes": {"flat_blocks": [0, 1]}}}
    target = _config([1, 2], [])
    target["adaptive"] = {"scenes": {}, "max_nodes": {},
                          "patch_test": {"scenes": {"flat_blocks": [0, 1, 2]}}}
    config["scenes"]["flat_blocks"] = target["scenes"]["flat_blocks"] = {"problem": "flat_blocks"}
    table = pr.plan([(config, quick)], target).set_index("rule")
    row = table.loc["patch_test"]
    assert row["fitted_on"] == "contact_level (proxy)" and row["exponent_time"] == pytest.approx(1.0)
    assert row["t_pred_s"] == pytest.approx(5.0 * 4.0)
    target["exact_reference"] = {"scenes": {"circle_square": [1]}}
    with pytest.raises(ValueError, match="rule 'exact_reference': no measured benchmark"):
        pr.plan([(config, quick)], target)


def test_the_cli_names_a_wrong_argument(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        pr.main(["--measured", f"{tmp_path}/none.yaml={tmp_path}", "--target", "x.yaml"])
    assert e.value.code == 2
    assert "CONFIG.yaml=BENCHMARK_DIR" in capsys.readouterr().err


def test_the_cli_writes_the_plan_and_prints_the_resources(tmp_path, capsys):
    quick = tmp_path / "quick"
    for lv in (1, 2):
        _bench(quick, "contact_level", f"circle_square_L{lv}", 4.0 ** lv, 300.0 + 4.0 ** lv)
    paths = {}
    for name, levels in (("quick", [1, 2]), ("huge", [1, 2, 3])):
        paths[name] = tmp_path / f"{name}.yaml"
        paths[name].write_text(yaml.safe_dump(_config(levels, [])))
    out = tmp_path / "plan.csv"
    assert pr.main(["--measured", f"{paths['quick']}={quick}", "--target", str(paths["huge"]),
                    "--out", str(out)]) == 0
    printed = yaml.safe_load(capsys.readouterr().out)["resources"]
    plan = pd.read_csv(out).set_index("rule")
    assert plan.loc["contact_level", "t_pred_s"] == pytest.approx(64.0)
    assert printed == {"contact_level": {"mem_mb": int(plan.loc["contact_level", "mem_mb"]),
                                         "runtime": 3}}
