"""Command-line arguments that name a scene: ``--problem P --set key=value ...``.

Shared by the workflow scripts (the rules pass a scene's problem and parameter
overrides from the config, :func:`workflows.studies.set_args`).
"""
from __future__ import annotations

import argparse

from problems.spec import ParameterError, ProblemSpec, lookup, problems


def parse_sets(items: list[str] | None) -> dict[str, str]:
    """``["key=value", ...]`` -> ``{key: value}`` (values stay strings)."""
    out: dict[str, str] = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ParameterError(f"option '--set': {item!r} is not allowed; allowed: key=value")
        if key in out:
            raise ParameterError(f"option '--set': {key!r} is given twice")
        out[key] = value.strip()
    return out


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--problem", required=True, help="registered contact problem")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scene parameter override (repeatable)")


def scene_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace):
    """``(spec, options)`` of the scene, or a clean argparse error (exit 2)."""
    try:
        spec: ProblemSpec = lookup(problems(), args.problem, "problem")
        if spec.kind != "contact":
            raise ParameterError(f"problem {spec.name!r} is not a contact problem")
        return spec, spec.options(**parse_sets(args.set))
    except ParameterError as err:
        parser.error(str(err))


def check_levels(parser: argparse.ArgumentParser, spec: ProblemSpec, levels) -> list[int]:
    try:
        return [spec.check_level(level) for level in levels]
    except ParameterError as err:
        parser.error(str(err))
