"""The structure: the import-linter layer contract, and no file writes in the numerics."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: Calls that write files (open in a writing mode is checked separately).
WRITERS = {"savez", "savez_compressed", "save", "savetxt", "to_csv", "to_parquet", "to_json",
           "savefig", "write_text", "write_bytes", "dump", "mkdir", "makedirs", "unlink",
           "rmtree"}


def test_import_layers_hold():
    """pyproject.toml [tool.importlinter]: data flows one way, numerics import no writers."""
    lint = Path(sys.executable).parent / "lint-imports"
    out = subprocess.run([str(lint), "--config", str(ROOT / "pyproject.toml")], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert "0 broken" in out.stdout and "3 kept" in out.stdout


def _writes(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if isinstance(f, ast.Attribute) and name in WRITERS:
                found.append(f"{path.name}:{node.lineno} {name}()")
            if name == "open":
                modes = [a.value for a in node.args[1:2] if isinstance(a, ast.Constant)]
                modes += [k.value.value for k in node.keywords
                          if k.arg == "mode" and isinstance(k.value, ast.Constant)]
                if any(set(str(m)) & set("wax+") for m in modes):
                    found.append(f"{path.name}:{node.lineno} open(..., {modes[0]!r})")
    return found


def test_no_module_under_problems_or_solvers_writes_a_file():
    files = sorted((ROOT / "problems").rglob("*.py")) + sorted((ROOT / "solvers").rglob("*.py"))
    assert len(files) > 10
    offenders = [w for f in files for w in _writes(f)]
    assert not offenders, offenders


def test_the_write_scan_can_fail(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy as np\nnp.savez('x.npz', a=1)\nopen('y', 'w')\nopen('z')\n")
    assert _writes(bad) == ["bad.py:2 savez()", "bad.py:3 open(..., 'w')"]
