"""A new study is one folder, ``workflows/studies/<name>/``, and its report step,
``report/<name>.py`` (docs/design.md, "Add a study"). A toy study declared in exactly these
files, in a copy of the suite, is discovered: ``snakemake -n`` at the tiny scale plans its
jobs with the resources its ``settings.yaml`` declares, its jobs run and the HTML report
shows its caption, the validation takes its config section from its folder, ``contactbench
study`` knows its command, and the docs give it its page and an entry in the studies' table
of contents."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent

#: The toy study: its folder's files and its report step, ``{path: text}``.
TOY = {
    "workflows/studies/toy_count/__init__.py": '''"""The toy_count study: grid sizes per level."""
from workflows.studies._base import Study, scenes_of

RULE = "toy_count_study"


def toy_args(config: dict, scene: str) -> str:
    """A scene's settings as arguments of the study's run step."""
    return " ".join(["--levels", *map(str, scenes_of(config, "toy_count")[scene])])


STUDY = Study(
    name="toy_count",
    summary="the number of nodes per level of a scene",
    thesis="none (a toy)",
    order=999,
    scripts={"toy_count": "workflows.studies.toy_count.run"},
    paths={"toy_runs": "results/{scene}/toy_count.csv",
           "toy_claims": "results/{scene}/toy_count_claims.csv"},
    outputs=("toy_runs", "toy_claims"),
    claims=("toy_claims",),
    heavy_rules=(RULE,),
)
''',
    "workflows/studies/toy_count/settings.yaml": '''schema:
  type: object
  additionalProperties: false
  required: [scenes]
  properties:
    scenes: {$ref: "#/definitions/scene_levels"}
scales:
  tiny:
    settings:
      scenes: {circle_square: [0, 1]}
    resources:
      toy_count_study: {mem_mb: 300, runtime: 1}
''',
    "workflows/studies/toy_count/run.py": '''"""The nodes of a uniform grid on the unit square at each level (a toy study)."""
import argparse

import pandas as pd

from workflows.io import write_csv


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--problem", required=True)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--levels", type=int, nargs="+", required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    rows = [{"scene": args.problem, "level": lv, "N": (2 ** lv + 1) ** 2} for lv in args.levels]
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
''',
    "workflows/studies/toy_count/rules.smk": '''from workflows.studies.toy_count import toy_args
rule toy_count_study:
    output: PATHS["toy_runs"]
    log: log_path("toy_count_study")
    benchmark: bench_path("toy_count_study")
    resources: **rule_resources(config, "toy_count_study")
    params: py=PY, scene=lambda w: set_args(config, w.scene),
            settings=lambda w: toy_args(config, w.scene)
    shell: "{params.py} -m workflows.studies.toy_count.run {params.scene} {params.settings} "
           "--out {output} > {log} 2>&1"

rule toy_count_report:
    input: PATHS["toy_runs"]
    output: report(PATHS["toy_claims"], caption=CAPTIONS["toy_claims"], category="{scene}")
    log: log_path("toy_count_report")
    params: py=PY
    shell: "{params.py} -m report.toy_count --runs {input} --claims {output} > {log} 2>&1"
''',
    "workflows/studies/toy_count/captions.rst": '''.. caption: toy_claims

Whether the number of nodes grows with the level on this scene.
''',
    "workflows/studies/toy_count/page.md": '''# `toy_count`: Grid sizes per level (a toy study)

The number of nodes of a uniform grid at each configured level, as a table and one claim.
''',
    "report/toy_count.py": '''"""The toy study's claim: the mesh grows with the level."""
import argparse

import pandas as pd

from workflows.io import read_csv, write_csv


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", required=True)
    parser.add_argument("--claims", required=True)
    args = parser.parse_args(argv)
    t = read_csv(args.runs)
    grows = bool((t["N"].diff().dropna() > 0).all())
    write_csv(args.claims, pd.DataFrame([{"claim": "toy_grows", "measured": float(grows),
                                          "bar": 1.0, "pass": grows}]))


if __name__ == "__main__":
    main()
''',
}


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    """A copy of the suite's tracked files with the toy study's files added."""
    copy = tmp_path_factory.mktemp("suite")
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True,
                             capture_output=True).stdout.decode().split("\0")
    for name in filter(None, tracked):
        if (ROOT / name).is_file():
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, copy / name)
    for name, text in TOY.items():
        assert not (copy / name).exists(), name          # new files only, nothing changed
        (copy / name).parent.mkdir(parents=True, exist_ok=True)
        (copy / name).write_text(text, encoding="utf-8")
    return copy


def run(suite: Path, *argv: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(suite)}
    return subprocess.run(list(argv), cwd=suite, env=env, capture_output=True, text=True,
                          timeout=600)


def test_a_study_in_its_folder_is_planned_at_the_tiny_scale(suite):
    out = run(suite, str(BIN / "snakemake"), "-n", "-p", "--forceall", "--configfile",
              "workflows/config/tiny.yaml")
    assert out.returncode == 0, (out.stdout + out.stderr)[-3000:]
    for level_file in ("results/circle_square/toy_count.csv",
                       "results/circle_square/toy_count_claims.csv"):
        assert level_file in out.stdout
    block = out.stdout.split("rule toy_count_study:")[1].split("\n\n")[0]
    assert "mem_mb=300" in block and "runtime=1" in block      # its settings.yaml's resources
    assert "--problem circle_square --levels 0 1" in out.stdout  # its section, its args


def test_its_config_section_is_validated_from_its_folder(suite, tmp_path):
    config = tmp_path / "typo.yaml"
    config.write_text("scale: tiny\nscenes: {}\ntoy_count: {scene: {circle_square: [0]}}\n")
    out = run(suite, str(BIN / "snakemake"), "-n", "--configfile", str(config))
    assert out.returncode != 0 and "'scene' was unexpected" in out.stdout + out.stderr


def test_its_command_and_its_docs_page(suite):
    out = run(suite, sys.executable, "-m", "workflows.cli", "study", "toy_count", "--help")
    assert out.returncode == 0 and "--levels" in out.stdout, out.stderr[-2000:]
    code = ("import sys; from pathlib import Path; sys.path.insert(0, 'docs/_ext'); "
            "import registry_pages; registry_pages.write_pages(Path('docs'))")
    out = run(suite, sys.executable, "-c", code)
    assert out.returncode == 0, out.stderr[-3000:]
    page = (suite / "docs/generated/studies/toy_count.md").read_text(encoding="utf-8")
    assert page.startswith("# `toy_count`: Grid sizes per level (a toy study)")
    assert "The number of nodes of a uniform grid at each" in page       # its page.md
    assert "Whether the number of nodes grows" in page                   # its caption
    assert "`contactbench study toy_count`" in page
    toctree = (suite / "docs/generated/studies/toctree.inc").read_text(encoding="utf-8")
    assert "/generated/studies/toy_count" in toctree



@pytest.mark.slow
def test_it_runs_and_its_caption_reaches_the_report(suite):
    """Its two jobs run at the tiny scale; the HTML report shows its output with the
    caption from its captions file."""
    target = "results/circle_square/toy_count_claims.csv"
    out = run(suite, str(BIN / "snakemake"), target, "--cores", "1", "--configfile",
              "workflows/config/tiny.yaml")
    assert out.returncode == 0, (out.stdout + out.stderr)[-3000:]
    claims = (suite / target).read_text(encoding="utf-8").splitlines()
    assert claims == ["claim,measured,bar,pass", "toy_grows,1.0,1.0,True"]   # 4, 9 nodes
    out = run(suite, str(BIN / "snakemake"), target, "--cores", "1", "--report",
              "report.html", "--configfile", "workflows/config/tiny.yaml")
    assert out.returncode == 0, (out.stdout + out.stderr)[-3000:]
    report = (suite / "report.html").read_text(encoding="utf-8")
    assert "Whether the number of nodes grows with the level on this scene." in report

# ----------------------------------------------------------- the declarations, one by one
def test_a_scale_file_gets_the_sections_and_resources_its_studies_declare():
    """``scale: quick`` brings in element_order's quick section and resources; a section
    or a rule's resources the file gives itself win; no scale, nothing is added."""
    from workflows.studies import STUDIES, at_scale

    declared = STUDIES["element_order"].scales["quick"]
    got = at_scale({"scale": "quick", "scenes": {}})
    assert got["element_order"] == declared.settings
    assert got["resources"]["element_order_study"] == declared.resources["element_order_study"]
    mine = {"scenes": {"circle_square": [0]}, "reference_level": {"circle_square": 1},
            "time_limit": 5}
    got = at_scale({"scale": "quick", "element_order": mine,
                    "resources": {"element_order_study": {"mem_mb": 111, "runtime": 9}}})
    assert got["element_order"] == mine
    assert got["resources"]["element_order_study"] == {"mem_mb": 111, "runtime": 9}
    assert "element_order" not in at_scale({"scenes": {}})
    assert "element_order" not in at_scale({"scale": "tiny"})     # not declared at tiny
    with pytest.raises(ValueError, match="config 'scale': 'medium' is not allowed"):
        at_scale({"scale": "medium"})


def test_the_schema_takes_each_section_from_one_place(monkeypatch, tmp_path):
    """A study's section joins the schema from its folder's ``settings.yaml``; declared in
    the schema file too, it is refused."""
    import yaml

    from workflows import studies

    schema = studies.config_schema()
    assert schema["properties"]["element_order"] == studies.STUDIES["element_order"].settings
    assert schema["properties"]["scale"]["enum"] == list(studies.SCALES)
    shared = yaml.safe_load(studies.SCHEMA.read_text())
    shared["properties"]["element_order"] = {"type": "object"}
    twice = tmp_path / "schema.yaml"
    twice.write_text(yaml.safe_dump(shared))
    monkeypatch.setattr(studies, "SCHEMA", twice)
    with pytest.raises(RuntimeError, match="'element_order' is declared in its folder and "
                                           "again"):
        studies.config_schema()


def test_a_captions_file_has_one_section_per_declared_key(tmp_path):
    from workflows.studies import STUDIES, captions_of

    study = STUDIES["element_order"]
    captions = captions_of(study)
    assert set(captions) == {"eo_claims", "eo_figure"}
    assert captions["eo_figure"].startswith("P1 (circles) against P2 (squares)")
    (tmp_path / "captions.rst").write_text(
        ".. caption: eo_claims\n\ntext\n\n.. caption: eo_typo\n\ntext\n")
    with pytest.raises(ValueError, match=r"sections \['eo_typo'\] are not allowed"):
        captions_of(study, tmp_path)
    (tmp_path / "captions.rst").write_text(".. caption: eo_claims eo_figure\n\nshared\n")
    assert captions_of(study, tmp_path) == {"eo_claims": "shared", "eo_figure": "shared"}