"""The package structure the docs promise (docs/architecture.md), read from the code's imports.

Every import counts, including those inside functions: a lazy import still
makes one module depend on another, and a cycle through it is still a cycle.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("geometry", "reduction", "workflow")


def _module_of(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules(root: Path) -> dict[str, Path]:
    return {_module_of(p, root): p for pkg in PACKAGES for p in (root / pkg).rglob("*.py")}


def _imports(path: Path, module: str, known: set[str]) -> set[str]:
    """Project modules that ``module`` imports (``from a import b`` counts ``a.b`` when that is
    a module, else ``a``)."""
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = module.split(".") if is_pkg else module.split(".")[:-1]
                pkg = pkg[: len(pkg) - (node.level - 1)]
                base = ".".join(pkg + ([base] if base else []))
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name != module:
                out.add(name)
    return out


def _graph(root: Path = ROOT) -> dict[str, set[str]]:
    mods = _modules(root)
    known = set(mods)
    return {m: _imports(p, m, known) for m, p in mods.items()}


def _ancestors(module: str) -> set[str]:
    parts = module.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts))}


def _upward(graph: dict[str, set[str]]) -> dict[str, list[str]]:
    """Engine modules and the application modules each imports."""
    bad = {m: sorted(d for d in deps if not d.startswith("workflow.engine"))
           for m, deps in graph.items() if m.startswith("workflow.engine")}
    return {m: d for m, d in bad.items() if d}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected sets of more than one module (Tarjan); a package importing its own
    sub-modules, or a module its package, is not a cycle."""
    graph = {m: {d for d in deps if d not in _ancestors(m) and m not in _ancestors(d)}
             for m, deps in graph.items()}
    index, low, stack, on, sccs = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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
            if len(comp) > 1:
                sccs.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sccs


def test_the_engine_imports_nothing_of_the_application():
    """workflow/engine/ may import itself and numpy/scipy/petsc4py: never the finite-element half
    (geometry/, reduction/), the scene, the pipeline, stages, reports or the application's I/O.
    The reduced model it solves and its condensation are the engine's own (engine/model.py,
    engine/condense.py)."""
    assert _upward(_graph()) == {}


def test_the_fe_half_runs_one_way():
    """geometry/ may use reduction's dolfinx calls (the worn mesh's motion is a dolfinx solve);
    reduction/ never imports geometry/, so the two packages do not lean on each other."""
    leaning = {m: sorted(d for d in deps if d.startswith("geometry"))
               for m, deps in _graph().items() if m.startswith("reduction")}
    assert {m: d for m, d in leaning.items() if d} == {}


def test_no_import_cycles():
    assert _cycles(_graph()) == []


def test_the_checks_see_a_planted_cycle_and_a_planted_application_import(tmp_path):
    pkg = tmp_path / "workflow"
    (pkg / "engine").mkdir(parents=True)
    (tmp_path / "reduction").mkdir()
    for f, text in {"__init__.py": "", "engine/__init__.py": "from . import a\n",
                    "engine/a.py": "def f():\n    from workflow import scene\n    import reduction.b\n",
                    "scene.py": "from workflow.engine.a import f\n", "../reduction/__init__.py": "",
                    "../reduction/b.py": ""}.items():
        (pkg / f).write_text(text)
    (tmp_path / "geometry").mkdir()
    graph = _graph(tmp_path)
    assert _upward(graph) == {"workflow.engine.a": ["reduction.b", "workflow.scene"]}
    assert _cycles(graph) == [["workflow.engine.a", "workflow.scene"]]
