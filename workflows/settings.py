"""Study settings' defaults, declared once: in the config schema, assembled from
``workflows/config.schema.yaml`` (what the studies share) and each study's section schema
(``workflows/studies/<name>/settings.yaml``; :func:`workflows.studies.config_schema`).

The Snakefile validates the config against the schema, which fills in every ``default``
(:func:`snakemake.utils.validate`, ``set_default=True``); rules and
:mod:`workflows.studies` then read the validated settings and never repeat a default.
A step run by hand takes the same defaults for its options from here
(:func:`study_defaults`, the study's section schema), so a default has one home;
``tests/test_settings.py`` fails if one is declared a second time.
"""
from __future__ import annotations

from pathlib import Path

from workflows.yaml_io import read_yaml

#: The config schema (its ``default`` entries are the study defaults).
SCHEMA = Path(__file__).resolve().parent / "config.schema.yaml"


def section_defaults(section: dict) -> dict:
    """``{key: default}`` of a config section's schema: the settings that have one
    (nested objects as dicts of their own defaults, where the object itself has none)."""
    out = {}
    for key, spec in (section.get("properties") or {}).items():
        if "default" in spec:
            out[key] = spec["default"]
        elif spec.get("type") == "object" and section_defaults(spec):
            out[key] = section_defaults(spec)
    return out


#: The studies' folders (``<name>/settings.yaml`` holds a study's section schema).
STUDIES_DIR = Path(__file__).resolve().parent / "studies"


def study_defaults(study: str) -> dict:
    """``{key: default}`` of a study's settings (:func:`section_defaults` of the schema in
    its folder's ``settings.yaml``)."""
    path = STUDIES_DIR / study / "settings.yaml"
    if not path.is_file():
        known = sorted(p.parent.name for p in STUDIES_DIR.glob("*/settings.yaml"))
        raise ValueError(f"parameter 'study': {study!r} is not allowed; allowed: "
                         f"{', '.join(known)}")
    with open(path, encoding="utf-8") as f:
        return section_defaults(read_yaml(f).get("schema") or {})
