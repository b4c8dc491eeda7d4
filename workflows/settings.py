"""Study settings' defaults, declared once: in the config schema, assembled from
``workflows/config.schema.yaml`` and each study module's ``settings`` section
(:func:`workflows.studies.config_schema`).

The Snakefile validates the config against the schema, which fills in every ``default``
(:func:`snakemake.utils.validate`, ``set_default=True``); rules and
:mod:`workflows.studies` then read the validated settings and never repeat a default.
A script run by hand takes the same defaults for its options from here
(:func:`study_defaults`, the sections of the schema file), so a default has one home;
``tests/test_settings.py`` fails if one is declared a second time.
"""
from __future__ import annotations

import functools
from pathlib import Path

import yaml

#: The config schema (its ``default`` entries are the study defaults).
SCHEMA = Path(__file__).resolve().parent / "config.schema.yaml"


@functools.lru_cache(maxsize=None)
def _schema() -> dict:
    with open(SCHEMA, encoding="utf-8") as f:
        return yaml.safe_load(f)


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


def study_defaults(study: str) -> dict:
    """``{key: default}`` of a study's settings whose section is in the schema file
    (:func:`section_defaults`)."""
    properties = _schema()["properties"]
    if study not in properties:
        raise ValueError(f"parameter 'study': {study!r} is not allowed; allowed: "
                         f"{', '.join(sorted(properties))}")
    return section_defaults(properties[study])
