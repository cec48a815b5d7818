"""runner/ imports run one way (evaluate -> evaluate_parallel -> rollouts; no cycle, lazy
imports included) and no module takes another's private names."""

import ast
import subprocess
import sys
from pathlib import Path

RUNNER = Path(__file__).resolve().parents[2] / "bicoord_drake" / "runner"
PREFIX = "bicoord_drake.runner"


def imported(path: Path) -> list[tuple[str, str]]:
    """(runner module, name) for every ``from bicoord_drake.runner... import name`` in `path`,
    at any depth (function-level imports too); a module import gives (module, "")."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(PREFIX):
            for alias in node.names:
                if node.module == PREFIX:  # from bicoord_drake.runner import generate
                    out.append((f"{PREFIX}.{alias.name}", ""))
                else:
                    out.append((node.module, alias.name))
        elif isinstance(node, ast.Import):
            out += [(a.name, "") for a in node.names if a.name.startswith(f"{PREFIX}.")]
    return out


def graph() -> dict[str, set[str]]:
    return {
        f"{PREFIX}.{p.stem}": {m for m, _ in imported(p)} - {f"{PREFIX}.{p.stem}"}
        for p in RUNNER.glob("*.py")
        if p.stem != "__init__"
    }


def test_the_evaluation_modules_import_one_way():
    g = graph()
    assert f"{PREFIX}.rollouts" in g[f"{PREFIX}.evaluate_parallel"]
    assert f"{PREFIX}.evaluate_parallel" in g[f"{PREFIX}.evaluate"]
    assert f"{PREFIX}.evaluate" not in g[f"{PREFIX}.evaluate_parallel"]
    assert not {f"{PREFIX}.evaluate", f"{PREFIX}.evaluate_parallel"} & g[f"{PREFIX}.rollouts"]


def test_no_import_cycle_in_runner():
    g = graph()
    done: set[str] = set()

    def visit(module: str, path: tuple[str, ...]) -> None:
        assert module not in path, "import cycle: " + " -> ".join((*path, module))
        if module in done:
            return
        for dep in sorted(g.get(module, ())):
            visit(dep, (*path, module))
        done.add(module)

    for module in sorted(g):
        visit(module, ())


def test_no_private_names_cross_modules():
    scripts = RUNNER.parents[1] / "scripts"
    for path in [*RUNNER.glob("*.py"), *scripts.glob("*.py")]:
        private = [f"{m}.{n}" for m, n in imported(path) if n.startswith("_")]
        assert not private, f"{path.name} imports {private}"


def test_the_parallel_module_imports_first_in_a_fresh_interpreter():
    code = f"import {PREFIX}.evaluate_parallel; import {PREFIX}.evaluate as e; e.run_parallel"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]
