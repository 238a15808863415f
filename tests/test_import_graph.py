"""The package's import graph: no circles between modules, and no module imports from a layer above its own.

Every ``import`` and ``from ... import`` under ``jaxarm/`` counts, at module level and inside functions alike (only
imports under ``if TYPE_CHECKING:`` are skipped: they never run). :data:`LAYERS` is the diagram of
``docs/api/index.md`` ("The layers"), bottom to top; a new module goes into one of them.
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "jaxarm"

#: Bottom to top. An entry names a module, or a package and every module under it; the longest entry that names a
#: module places it. A module may import from its own layer and the layers below, never from one above.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("foundation", ("jaxarm.config.validate", "jaxarm.cpu_arithmetic", "jaxarm.cpu_dispatch", "jaxarm.batching")),
    ("configuration", ("jaxarm.config",)),
    ("devices and folders", ("jaxarm.parallel", "jaxarm.parallel_cli", "jaxarm.runfolder")),
    ("network, arm, task, analysis", ("jaxarm", "jaxarm.network", "jaxarm.arm", "jaxarm.task", "jaxarm.analysis",
                                      "jaxarm.record")),
    ("learning: the pieces", ("jaxarm.learning.metaparams", "jaxarm.learning.critic", "jaxarm.learning.stdp",
                              "jaxarm.learning.babbling", "jaxarm.learning.rule", "jaxarm.learning.training")),
    ("learning: the rules", ("jaxarm.learning",)),
    ("closed loop", ("jaxarm.loop",)),
    ("training", ("jaxarm.train",)),
    ("runs", ("jaxarm.run", "jaxarm.checkpoint", "jaxarm.recordfile", "jaxarm.run_centre_out", "jaxarm.control")),
    ("commands and applications", ("jaxarm.experiment", "jaxarm.paper", "jaxarm.evolve", "jaxarm.robot", "jaxarm.viz",
                                   "jaxarm.demo", "jaxarm.cli")),
]


def modules() -> dict[str, tuple[Path, bool]]:
    """Dotted name -> (file, is a package's ``__init__``) of every module under ``jaxarm/``."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        package = parts[-1] == "__init__"
        out[".".join(parts[:-1] if package else parts)] = (path, package)
    return out


def _type_checking_only(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (getattr(test, "id", None) == "TYPE_CHECKING"
                                         or getattr(test, "attr", None) == "TYPE_CHECKING")


def _imports(tree: ast.AST):
    """Every Import / ImportFrom node, at any depth, except those under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        for child in ast.iter_child_nodes(node):
            if _type_checking_only(node) and child in node.body:
                continue
            stack.append(child)


def import_graph() -> dict[str, dict[str, int]]:
    """module -> {imported package-internal module: line of the first such import}."""
    mods = modules()

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, dict[str, int]] = {}
    for name, (path, package) in mods.items():
        edges = graph.setdefault(name, {})
        for node in _imports(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [owner(a.name) for a in node.names if a.name.split(".")[0] == "jaxarm"]
            else:
                base = node.module or ""
                if node.level:
                    here = name.split(".") if package else name.split(".")[:-1]
                    base = ".".join(here[: len(here) - node.level + 1] + ([node.module] if node.module else []))
                if base.split(".")[0] != "jaxarm":
                    continue
                # ``from pkg import mod`` imports the module pkg.mod; ``from mod import name`` the module mod
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else owner(base) for a in node.names]
            for target in targets:
                if target is not None and target != name:
                    edges.setdefault(target, node.lineno)
    return graph


def layer_of(module: str) -> int | None:
    best = None
    for i, (_, entries) in enumerate(LAYERS):
        for entry in entries:
            if module == entry or module.startswith(entry + "."):
                if best is None or len(entry) > best[0]:
                    best = (len(entry), i)
    return None if best is None else best[1]


def cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each as one circle through them."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, {}):
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
            if len(component) > 1:
                found.append(_circle(graph, set(component)))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _circle(graph, component: set[str]) -> list[str]:
    """One path a -> ... -> a inside ``component`` (breadth first from its first module)."""
    start = min(component)
    parents, frontier = {start: None}, [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v]):
                if w == start:
                    path = [v]
                    while parents[path[-1]] is not None:
                        path.append(parents[path[-1]])
                    return [start] + path[::-1][1:] + [start] if len(path) > 1 else [start, v, start]
                if w in component and w not in parents:
                    parents[w] = v
                    nxt.append(w)
        frontier = nxt
    return sorted(component)


def test_every_module_has_a_layer():
    unplaced = [m for m in modules() if layer_of(m) is None]
    assert not unplaced, f"modules in no layer of LAYERS (place them, and in docs/api/index.md): {unplaced}"


def test_no_import_circles():
    found = cycles(import_graph())
    assert not found, "import circles: " + "; ".join(" -> ".join(c) for c in found)


def test_no_module_imports_from_a_layer_above_its_own():
    graph, mods = import_graph(), modules()
    upward = []
    for module, edges in sorted(graph.items()):
        for target, line in sorted(edges.items()):
            if layer_of(target) > layer_of(module):
                where = mods[module][0].relative_to(PACKAGE.parent)
                upward.append(f"{where}:{line}: {module} ({LAYERS[layer_of(module)][0]}) imports {target} "
                              f"({LAYERS[layer_of(target)][0]})")
    assert not upward, "imports from a layer above:\n" + "\n".join(upward)


def test_the_checks_see_function_level_imports_circles_and_upward_imports():
    # the graph counts an import inside a function, and the checks name what they find
    graph = import_graph()
    assert "jaxarm.record" in graph["jaxarm.loop"]          # `from jaxarm import record as rec_mod` in a method
    assert "jaxarm.network.network" not in graph["jaxarm.network.native"]   # under `if TYPE_CHECKING:` only
    toy = {"a": {"b": 1}, "b": {"c": 1}, "c": {"a": 1}, "d": {"a": 1}}
    assert cycles(toy) == [["a", "b", "c", "a"]]
    assert layer_of("jaxarm.learning.rstdp") > layer_of("jaxarm.learning.rule") > layer_of("jaxarm.network.cell")
    assert layer_of("jaxarm.train") > layer_of("jaxarm.loop") > layer_of("jaxarm.learning.registry")


def test_the_docs_diagram_lists_the_layers():
    page = (PACKAGE.parent / "docs" / "api" / "index.md").read_text()
    section = page[page.index("## The layers"):]
    for name, entries in LAYERS:
        assert name in section, name
        for entry in entries:
            assert f"{entry.removeprefix('jaxarm.') if entry != 'jaxarm' else 'jaxarm'}" in section, entry
