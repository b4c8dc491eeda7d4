"""The structure: the import-linter layer contract, and no file writes in the numerics (a
scratch file in a temporary folder, removed with it, aside)."""
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
    assert "0 broken" in out.stdout and "5 kept" in out.stdout


def _scratch(tree: ast.AST) -> set[int]:
    """The ids of the nodes inside a ``with tempfile.TemporaryDirectory(...)`` block: a
    scratch file there (a problem handed to a solver's own process) is removed with its
    folder when the block ends, however it ends, and is no file the numerics write."""
    inside = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.With) and any(
                isinstance(item.context_expr, ast.Call)
                and ast.unparse(item.context_expr.func) == "tempfile.TemporaryDirectory"
                for item in node.items):
            inside |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return inside


def _writes(path: Path) -> list[str]:
    found = []
    tree = ast.parse(path.read_text())
    scratch = _scratch(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and id(node) not in scratch:
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
    bad.write_text("import numpy as np\nnp.savez('x.npz', a=1)\nopen('y', 'w')\nopen('z')\n"
                   "with tempfile.TemporaryDirectory() as d:\n    Path(d, 'p').write_bytes(b'')\n"
                   "Path('q').write_bytes(b'')\n"
                   "with tempfile.TemporaryFile() as f:\n    Path('r').write_text('')\n")
    assert _writes(bad) == ["bad.py:2 savez()", "bad.py:3 open(..., 'w')",
                            "bad.py:7 write_bytes()", "bad.py:9 write_text()"]


# ------------------------------------------------------------ import graph of the numerics
def _graph():
    import grimp

    return grimp.build_graph("problems", "solvers", "reference")


def _cycles(graph, prefixes: tuple[str, ...]) -> list[list[str]]:
    """The import cycles among the modules under ``prefixes`` (one per strongly connected
    component of more than one module, or a module importing itself)."""
    modules = sorted(m for m in graph.modules if m.startswith(prefixes))
    edges = {m: sorted(i for i in graph.find_modules_directly_imported_by(m) if i in modules)
             for m in modules}
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):                                    # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in edges[v]:
                out.append(sorted(comp))

    for m in modules:
        if m not in index:
            visit(m)
    return out


def test_no_import_cycle_in_problems_or_solvers():
    assert _cycles(_graph(), ("problems", "solvers")) == []


def test_the_cycle_check_can_fail():
    class Fake:
        modules = {"solvers.a", "solvers.b", "solvers.c"}

        @staticmethod
        def find_modules_directly_imported_by(m):
            return {"solvers.a": {"solvers.b"}, "solvers.b": {"solvers.a"}, "solvers.c": set()}[m]

    assert _cycles(Fake, ("solvers",)) == [["solvers.a", "solvers.b"]]


def test_no_solver_module_imports_another_or_is_imported_from_below():
    """benchopt's rule: a solver is one module and never imports another solver; the
    layers below the solvers (the verification, base, the kernels of solvers.kernels)
    import no solver module."""
    from solvers.interface import solvers

    graph = _graph()
    solver_modules = {spec.solve.__module__ for spec in solvers().values()
                      if spec.solve.__module__.startswith("solvers.")}
    assert len(solver_modules) >= 4
    above = {"solvers.interface", "solvers.reference"}
    for m in solver_modules:
        imported = graph.find_modules_directly_imported_by(m)
        assert not imported & (solver_modules - {m}), (m, imported & solver_modules)
        assert not imported & above, (m, imported & above)
    helpers = {m for m in graph.modules if m.startswith("solvers.")} - solver_modules - above
    for h in helpers:
        assert not graph.find_modules_directly_imported_by(h) & solver_modules, h


def test_every_study_is_one_folder_and_one_report_step():
    """A study's files sit in its folder, ``workflows/studies/<name>/`` (declaration,
    settings, run steps, rules, captions, page), and its report step is
    ``report/<name>.py``; its rules run nothing else, and the summary page names no study."""
    import re

    from workflows.studies import STUDIES

    shared = {"report.summary", "workflows.cli"}      # the summary page; the export command
    for name, study in STUDIES.items():
        folder = ROOT / "workflows" / "studies" / name
        assert study.folder == folder, name
        for part in ("__init__.py", "settings.yaml", "rules.smk", "captions.rst", "page.md"):
            assert (folder / part).is_file(), (name, part)
        assert all(m.startswith(f"workflows.studies.{name}.") for m in study.scripts.values())
        rules = (folder / "rules.smk").read_text()
        steps = set(re.findall(r"-m ([\w.]+)", rules))
        allowed = {f"report.{name}", *study.scripts.values()}
        assert steps <= allowed | shared, (name, steps - allowed)
        assert not re.search(r"workflows\.studies\.(?!_base\b)(?!" + name + r"\b)\w+", rules), name
    assert {p.stem for p in (ROOT / "workflows").glob("*.smk")} == {"summary"}
    summary = (ROOT / "report" / "summary.py").read_text()
    named = [n for n in STUDIES if re.search(rf"\b{n}\b", summary)]
    assert not named, named


def test_the_studies_are_independent_of_each_other(tmp_path):
    """No study's folder imports another study's folder, nor its report step another's
    (an import-linter independence contract over every registered study)."""
    from workflows.studies import STUDIES

    modules = [f"workflows.studies.{n}" for n in STUDIES]
    modules += [f"report.{n}" for n in STUDIES if (ROOT / "report" / f"{n}.py").is_file()]
    assert len(modules) >= 2 * len(STUDIES) - 1
    config = tmp_path / "independence.toml"
    config.write_text("[tool.importlinter]\n"
                      'root_packages = ["problems", "solvers", "workflows", "report", '
                      '"reference"]\ninclude_external_packages = true\n\n'
                      "[[tool.importlinter.contracts]]\n"
                      'name = "Studies are independent of each other"\n'
                      'type = "independence"\n'
                      "modules = [" + ", ".join(f'"{m}"' for m in modules) + "]\n")
    lint = Path(sys.executable).parent / "lint-imports"
    out = subprocess.run([str(lint), "--config", str(config)], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0 and "1 kept" in out.stdout, out.stdout[-3000:] + out.stderr[-2000:]
