"""The package's import graph, read from the source (ast, nothing imported): one way, no cycles.

Every `import` and `from ... import` of a module counts, at its top and inside
functions alike (an import inside a function runs too, only later), relative
ones resolved against the module's package. A name imported from a package
that is one of its modules (`from . import options`) is an edge to that module.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "taskseq"


def modules() -> dict[str, Path]:
    """Every module of `taskseq` by dotted name (a package by its `__init__.py`)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imported(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The project modules that module `name` imports."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out = set()

    def add(target: str) -> None:
        while target and target not in known:  # `taskseq.sim.state.WorldState` is module `taskseq.sim.state`
            target = target.rpartition(".")[0]
        if target and target != name:
            out.add(target)

    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "taskseq" or alias.name.startswith("taskseq."):
                    add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target != "taskseq" and not target.startswith("taskseq."):
                continue
            for alias in node.names:
                add(f"{target}.{alias.name}" if f"{target}.{alias.name}" in known else target)
    return out


def graph() -> dict[str, set[str]]:
    known = modules()
    return {name: imported(name, path, known) for name, path in known.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node, and nodes that import themselves (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in edges.get(v, ()):
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def package_graph(edges: dict[str, set[str]]) -> dict[str, set[str]]:
    """The same edges between the subpackages of `taskseq` (a module directly under it stands for itself)."""
    def top(name: str) -> str:
        return ".".join(name.split(".")[:2])

    out: dict[str, set[str]] = {}
    for source, targets in edges.items():
        out.setdefault(top(source), set()).update(top(t) for t in targets if top(t) != top(source))
    out.pop("taskseq", None)  # the root package's own __init__.py
    return out


def test_the_graph_is_read_from_the_source():
    edges = graph()
    assert "taskseq.sim.state" in edges["taskseq.sim.primitives"]  # from .state import ...
    assert "taskseq.methods.spec" in edges["taskseq.methods"]  # from .spec import ...
    assert "taskseq.stages.options" in edges["taskseq.stages"]  # from . import options as opts


def test_no_module_of_taskseq_is_in_an_import_cycle():
    found = cycles(graph())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_no_subpackage_of_taskseq_is_in_an_import_cycle():
    found = cycles(package_graph(graph()))
    assert not found, "import cycles between subpackages: " + "; ".join(" <-> ".join(c) for c in found)


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"a"}}) == [["a"]] and cycles({"a": {"b"}, "b": set()}) == []


def test_the_layers_below_the_pipeline_import_none_above_them():
    edges = graph()
    below = {
        "taskseq.runtime": {"taskseq.runtime"},  # nothing else of the project
        "taskseq.learn": {"taskseq.learn", "taskseq.features", "taskseq.sim", "taskseq.runtime"},  # not settings
        "taskseq.evaluate": None,  # checked below: never the experiments, the web app, the stages
        "taskseq.experiments": None,
    }
    for name, targets in edges.items():
        for layer, allowed in below.items():
            if name == layer or name.startswith(layer + "."):
                tops = {".".join(t.split(".")[:2]) for t in targets}
                if allowed is not None:
                    assert tops <= allowed, f"{name} imports {sorted(tops - allowed)}"
                assert not tops & {"taskseq.serve", "taskseq.stages", "taskseq.cli", "taskseq.tool_commands",
                                   "taskseq.methods", "taskseq.track"}, f"{name} imports {sorted(tops)}"
                if layer == "taskseq.evaluate":
                    assert "taskseq.experiments" not in tops, f"{name} imports the experiments"


def test_the_methods_import_nothing_of_the_pipeline_that_runs_them():
    # the specs are the method interface: the experiments, stages, web app and tracking run them, not the reverse
    for name, targets in graph().items():
        if name == "taskseq.methods" or name.startswith("taskseq.methods."):
            tops = {".".join(t.split(".")[:2]) for t in targets}
            assert not tops & {"taskseq.experiments", "taskseq.serve", "taskseq.stages", "taskseq.cli",
                               "taskseq.tool_commands", "taskseq.track", "taskseq.report"}, f"{name} imports {tops}"


def test_every_import_at_run_time_stays_in_its_package():
    """`importlib.import_module` is the import the graph above cannot read: each call must load a module of the
    caller's own package (`f"{__name__}.x"` or `f"{__package__}.x"`), never one up the layers."""
    calls = 0
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "import_module":
                calls += 1
                (arg,) = node.args
                first = arg.values[0] if isinstance(arg, ast.JoinedStr) else None
                inner = getattr(first, "value", None)
                assert isinstance(inner, ast.Name) and inner.id in ("__name__", "__package__"), \
                    f"{name}: import_module({ast.unparse(arg)}) may load a module outside its package"
    assert calls >= 2  # taskseq.methods loads its methods, the stages' command its stage
