"""Each study's settings declared once. Defaults live in the config schema
(:mod:`workflows.settings`); the Snakefile's validation fills them in; no rule, no helper
in :mod:`workflows.studies` and no script's option declares one of them again."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from snakemake.utils import validate

from workflows.settings import section_defaults, study_defaults
from workflows.studies import config_schema, load_config, schema_file
from workflows.studies.adaptive import adaptive_args

ROOT = Path(__file__).resolve().parent.parent
STUDIES_DIR = ROOT / "workflows" / "studies"
#: The files that read the validated settings: the Snakefile, the studies' declarations and
#: their rules (their run steps take options: :func:`test_no_step_option_repeats_a_schema_default`).
WORKFLOW_FILES = [ROOT / "Snakefile", *sorted(STUDIES_DIR.glob("*.py")),
                  *sorted(STUDIES_DIR.glob("*/__init__.py")), *sorted(STUDIES_DIR.glob("*/rules.smk")),
                  *sorted((ROOT / "workflows").glob("*.smk"))]
#: ``.get("key", <something that is not an empty container or None>)``: a default
GET_DEFAULT = r"""\.get\(\s*["']{key}["']\s*,(?!\s*(?:\{{\}}|\[\]|\(\)|None\b))"""


def _settings() -> dict:
    """``{study: (keys with a schema default, required keys)}``."""
    schema = config_schema()
    out = {}
    for study, spec in schema["properties"].items():
        if spec.get("type") == "object" and spec.get("properties"):
            out[study] = (set(section_defaults(spec)), set(spec.get("required", ())))
    return out


def test_the_schema_declares_defaults():
    """The adaptive study's optional settings have their defaults in the schema (the
    example: theta once in the YAML, the schema, the study module and argparse)."""
    d = study_defaults("adaptive")
    assert d["theta"] == 0.5 and d["min_marked"] == 0.0 and d["tol"] == 1e-8
    assert d["stabilisation"] == {"alpha": 1.0, "penalty": 1.0} and d["time_limit"] == 120.0
    with pytest.raises(ValueError, match="parameter 'study': 'nope' is not allowed"):
        study_defaults("nope")


@pytest.mark.parametrize("study", sorted(_settings()))
def test_no_workflow_file_repeats_a_default(study):
    """A key with a schema default, or one the schema requires, is read as ``config[...][k]``
    after validation; ``.get(k, default)`` would be a second declaration."""
    defaulted, required = _settings()[study]
    for path in WORKFLOW_FILES:
        text = path.read_text()
        for key in sorted(defaulted | required):
            hit = re.search(GET_DEFAULT.format(key=re.escape(key)), text)
            assert hit is None, f"{path.name}: {hit.group(0)!r} repeats the default of {study}.{key}"


def test_no_step_option_repeats_a_schema_default():
    """A run step's option for a setting with a schema default takes it from
    :func:`workflows.settings.study_defaults`, never as a literal (the test set's ``levels``
    reaches its step as the chosen levels, ``--levels``)."""
    studies = {s for s, (defaulted, _) in _settings().items() if defaulted}
    assert studies == {"adaptive", "floor_bandwidth", "test_set"}
    for study in sorted(studies):
        defaults = study_defaults(study)
        keys = {k for k, v in defaults.items() if not isinstance(v, dict)} | \
            {k for v in defaults.values() if isinstance(v, dict) for k in v}
        keys -= {"levels"} if study == "test_set" else set()
        text = (STUDIES_DIR / study / "run.py").read_text()
        for key in sorted(keys):
            flag = "--" + key.replace("_", "-")
            calls = re.findall(r'add_argument\(\s*"' + re.escape(flag) + r'"[^)]*\)', text)
            assert calls, f"{study}/run.py has no option {flag}"
            for call in calls:
                assert not re.search(r"default=\s*[-0-9.\"'\[(]", call), \
                    f"{study}/run.py: {flag} declares a literal default"


def test_validation_fills_the_defaults_in():
    """The Snakefile's validation (snakemake.utils.validate, set_default) puts the schema's
    defaults into a config that leaves them out, and the rules read them from there."""
    config = load_config(ROOT / "workflows" / "config" / "quick.yaml")
    for key in ("theta", "min_marked", "tol", "time_limit", "stabilisation"):
        config["adaptive"].pop(key, None)
    with schema_file() as schema:
        validate(config, schema)
    ad = config["adaptive"]
    assert (ad["theta"], ad["min_marked"], ad["tol"], ad["time_limit"]) == (0.5, 0.0, 1e-8, 120.0)
    assert ad["stabilisation"] == {"alpha": 1.0, "penalty": 1.0}
    config["scenes"] = {**config.get("scenes", {}), "circle_square": {"problem": "circle_square"},
                        "cube_sphere": {"problem": "cube_sphere"}}
    args = adaptive_args(config, "circle_square")
    assert "--theta 0.5" in args and "--tol 1e-08" in args and "--alpha 1.0" in args
