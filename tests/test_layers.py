"""The package's structure holds (DEVELOPERS.md, "Layers"): the layers contract of pyproject.toml
(import-linter), no import cycle between modules and no import of another module's private name
(deferred imports included), and the type check of the array maths (mypy)."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "cobot_analysis"


def _module(f: Path) -> str:
    rel = f.relative_to(ROOT).with_suffix("")
    return ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)


def _imports() -> dict[str, list[tuple[str, str | None]]]:
    """Module -> the package modules it imports (with the imported name), at any depth of the code."""
    modules = {_module(f): f for f in PACKAGE.rglob("*.py")}
    found: dict[str, list[tuple[str, str | None]]] = {}
    for name, f in modules.items():
        out = found.setdefault(name, [])
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("cobot_analysis") and not node.level:
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    out.append((full, None) if full in modules else (node.module, alias.name))
            elif isinstance(node, ast.Import):
                out += [(a.name, None) for a in node.names if a.name.startswith("cobot_analysis")]
    return found


def test_the_layers_contract_is_kept():
    lint = shutil.which("lint-imports")
    if lint is None:
        pytest.skip("import-linter is not installed (pip install -e .[dev])")
    run = subprocess.run([lint, "--config", str(ROOT / "pyproject.toml")], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "0 broken" in run.stdout


def test_no_module_imports_a_private_name_of_another():
    private = [f"{m} imports {target}.{name}" for m, imps in _imports().items() for target, name in imps
               if name and name.startswith("_") and not name.startswith("__") and target != m]
    assert not private, private


def test_no_import_cycle_between_modules():
    graph = {m: {t for t, _ in imps if t != m and not (m.startswith(t + ".") or t.startswith(m + "."))}
             for m, imps in _imports().items()}
    cycles, state = [], {}

    def visit(node: str, stack: list[str]) -> None:  # depth-first search for back edges
        state[node] = 1
        for nxt in graph.get(node, ()):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt] if nxt in stack else [node, nxt])
            elif nxt not in state:
                visit(nxt, [*stack, nxt])
        state[node] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, cycles[:3]


def test_the_array_maths_type_checks():
    pytest.importorskip("mypy", reason="mypy is not installed (pip install -e .[dev])")
    run = subprocess.run([sys.executable, "-m", "mypy", "--no-incremental", "--config-file", str(ROOT / "pyproject.toml")],
                         cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:]
