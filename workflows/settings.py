"""Study settings' defaults, declared once: in ``workflows/config.schema.yaml``.

The Snakefile validates the config against the schema, which fills in every ``default``
(:func:`snakemake.utils.validate`, ``set_default=True``); rules and
:mod:`workflows.studies` then read the validated settings and never repeat a default.
A script run by hand takes the same defaults for its options from here
(:func:`study_defaults`), so a default has one home; ``tests/test_settings.py`` fails
if one is declared a second time.
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


def study_defaults(study: str) -> dict:
    """``{key: default}`` of a study's settings that have one in the schema (nested
    objects as dicts of their own defaults, where the object itself has none)."""
    def defaults(node: dict) -> dict:
        out = {}
        for key, spec in (node.get("properties") or {}).items():
            if "default" in spec:
                out[key] = spec["default"]
            elif spec.get("type") == "object" and defaults(spec):
                out[key] = defaults(spec)
        return out

    properties = _schema()["properties"]
    if study not in properties:
        raise ValueError(f"parameter 'study': {study!r} is not allowed; allowed: "
                         f"{', '.join(sorted(properties))}")
    return defaults(properties[study])
