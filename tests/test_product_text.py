"""Product text speaks of the suite to its users.

Code, comments, configs, captions, the README and the docs name the thesis item, the
published result or the reason a bar is what it is -- never a tracker number, a commit hash,
a date-stamped run log or a first-person account, none of which a user can look up. This
test scans every tracked product file and fails naming ``file:line``.
"""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: The product files: the front page, the docs, the packages, the workflow and its configs
#: and captions, the build files.
PRODUCT_PATHS = ("README.md", "CITATION.cff", "Makefile", "Snakefile", "pyproject.toml",
                 "docs/", "problems/", "solvers/", "workflows/", "report/", "reference/",
                 "results/README.md")

#: What product text must not contain, each with the reason a user cannot use it.
FORBIDDEN = {
    "tracker number": re.compile(r"\bissues?\s*#?\d+", re.IGNORECASE),
    # 7 to 40 hex digits with a digit and at least two letters (so 1e9, 26979e9 pass)
    "commit hash": re.compile(r"\b(?=[0-9a-f]*\d)(?=(?:[0-9]*[a-f]){2})[0-9a-f]{7,40}\b"),
    "date stamp": re.compile(r"\b(?:19|20)\d\d-[01]\d-[0-3]\d\b"),
    # "I ran", "I've", "my": not the identity "H = I - ..." nor the interpolant "(I the"
    "first person": re.compile(r"(?<![-=+*/(] )(?<![(|])\bI\s+[a-z]{2,}\b"
                               r"|\bI'(?:ve|m|d|ll)\b|\b[Mm]y\b"),
}


def product_files(root: Path = ROOT) -> list[str]:
    """The tracked product files (``git ls-files`` under :data:`PRODUCT_PATHS`)."""
    listed = subprocess.run(["git", "ls-files", "--", *PRODUCT_PATHS], cwd=root, check=True,
                            capture_output=True, text=True).stdout.split()
    return [name for name in listed if (root / name).is_file()]


def offending_lines(text: str) -> list[tuple[int, str, str]]:
    """``(line number, kind, matched text)`` for each forbidden pattern in ``text``."""
    found = []
    for number, line in enumerate(text.splitlines(), start=1):
        for kind, pattern in FORBIDDEN.items():
            match = pattern.search(line)
            if match:
                found.append((number, kind, match.group(0)))
    return found


@pytest.mark.parametrize("text, kind", [
    ("the bar of issue 13", "tracker number"),
    ("Issue 24's decision", "tracker number"),
    ("measured on a fresh clone of 35a8f49", "commit hash"),
    ("Measured 2026-11-24 on a quiet machine", "date stamp"),
    ("Then I stopped it", "first person"),
    ("I've measured", "first person"),
    ("on my machine", "first person"),
])
def test_each_pattern_catches_its_kind(text, kind):
    assert [k for _, k, _ in offending_lines(text)] == [kind]


@pytest.mark.parametrize("text", [
    "Householder frames H = I - 2 w w'/(w'w)", "T - I on the changed rows",
    "||I u_h - u_ref||_A (I the interpolation)", "p0 = 1.26979e9 Pa", "tolerance 1e-10",
    "thesis Sect. 9.3, Table 9.1", "the colour #1f77b4",
])
def test_the_suite_s_own_notation_passes(text):
    assert offending_lines(text) == []


def test_product_text_names_no_tracker_hash_date_or_first_person():
    files = product_files()
    assert "README.md" in files and any(name.startswith("solvers/") for name in files)
    problems = []
    for name in files:
        try:
            text = (ROOT / name).read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue                                          # a binary file: no prose
        problems += [f"{name}:{number}: {kind} {matched!r}"
                     for number, kind, matched in offending_lines(text)]
    assert not problems, "product text a user cannot look up:\n" + "\n".join(problems)
