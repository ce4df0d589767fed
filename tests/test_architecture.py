"""The architecture holds by itself: what docs/ARCHITECTURE.md draws is the real import graph,
and the conventions a linter cannot see are checked here.

* The layer graph in docs/ARCHITECTURE.md (the ``imports`` block) equals the graph of the
  code's imports between the layers, function-level imports included (the direction of the
  arrows is also checked by the import-linter contracts in pyproject.toml; this keeps the
  drawing true).
* No module imports another module's private (``_name``) names: a name another module needs
  is that module's API and is spelled as such.
* No module-level ``__getattr__``: a lazy attribute that papers over an import cycle is a
  cycle.
* A ``noqa`` or ``type: ignore`` names its rule and says why, so a reader can tell a reasoned
  exception from a silenced warning (ruff's RUF100 removes the ones no rule needs).
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("bench", "instruments", "procedures", "sim")
TREES = (*PACKAGES, "tests", "benchmarks")
#: the layers as drawn in docs/ARCHITECTURE.md, finest first where one contains another
LAYERS = ("bench.values", "bench.analysis", "bench.discovery", "bench.core", "bench.app", "bench.testing",
          "instruments", "procedures", "sim")


def _sources(trees: tuple[str, ...]) -> list[Path]:
    return sorted(p for tree in trees for p in (ROOT / tree).rglob("*.py") if ".venv" not in p.parts)


def _module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def _imported_modules(path: Path) -> list[tuple[int, str, list[str]]]:
    """(line, module, names) of every import in ``path``, relative ones resolved."""
    module = _module_name(path)
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    found: list[tuple[int, str, list[str]]] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            target = ".".join([*base, node.module] if node.module else base)
            found.append((node.lineno, target, [alias.name for alias in node.names]))
    return found


def _layer(module: str) -> str | None:
    return next((layer for layer in LAYERS if module == layer or module.startswith(layer + ".")), None)


def real_layer_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = defaultdict(set)
    for path in _sources(PACKAGES):
        source = _layer(_module_name(path))
        for _, target, _names in _imported_modules(path):
            layer = _layer(target)
            if source and layer and layer != source:
                graph[source].add(layer)
    return {layer: graph[layer] for layer in LAYERS}


def documented_layer_graph() -> dict[str, set[str]]:
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    block = re.search(r"```imports\n(.*?)```", text, re.S)
    assert block, "docs/ARCHITECTURE.md has no ```imports block (the layer graph)"
    graph: dict[str, set[str]] = {}
    for line in block.group(1).splitlines():
        if "->" not in line:
            continue
        source, _, targets = line.partition("->")
        names = targets.split("#")[0].strip()
        graph[source.strip()] = set() if names in ("", "(nothing)") else {t.strip() for t in names.split(",")}
    return graph


def test_the_documented_layer_graph_is_the_code_s():
    documented, real = documented_layer_graph(), real_layer_graph()
    assert set(documented) == set(LAYERS), f"the drawing lists {sorted(documented)}; the layers are {LAYERS}"
    wrong = {layer: {"drawn": sorted(documented[layer]), "imports": sorted(real[layer])}
             for layer in LAYERS if documented[layer] != real[layer]}
    assert not wrong, f"docs/ARCHITECTURE.md's import graph differs from the code: {wrong}"


def test_the_layer_graph_has_no_cycle():
    graph = real_layer_graph()
    done: set[str] = set()

    def visit(layer: str, path: tuple[str, ...]) -> None:
        assert layer not in path, f"import cycle between layers: {' -> '.join((*path, layer))}"
        if layer in done:
            return
        for target in graph.get(layer, ()):
            visit(target, (*path, layer))
        done.add(layer)

    for layer in LAYERS:
        visit(layer, ())


def test_no_module_imports_another_module_s_private_names():
    offenders = [f"{path.relative_to(ROOT)}:{line}: from {module} import {name}"
                 for path in _sources(TREES) for line, module, names in _imported_modules(path)
                 for name in names
                 if name.startswith("_") and not name.startswith("__") and module != "__future__"]
    assert not offenders, "private names imported across modules:\n" + "\n".join(offenders)


def test_no_module_level_getattr():
    offenders = [str(path.relative_to(ROOT)) for path in _sources(PACKAGES)
                 if any(isinstance(node, ast.FunctionDef) and node.name == "__getattr__"
                        for node in ast.parse(path.read_text()).body)]
    assert not offenders, f"module-level __getattr__ in {offenders}"


SUPPRESSION = re.compile(r"#\s*(noqa|type:\s*ignore)(?P<rest>.*)", re.I)
REASONED = re.compile(r"^(:\s*[A-Z]+[0-9]+(,\s*[A-Z]+[0-9]+)*|\[[a-z-]+(,\s*[a-z-]+)*\])\s*(-|—|\(|#)\s*\w+")


@pytest.mark.parametrize("tree", TREES)
def test_every_suppression_names_its_rule_and_its_reason(tree):
    offenders = []
    for path in _sources((tree,)):
        tokens = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
        for token in tokens:
            if token.type != tokenize.COMMENT:
                continue
            match = SUPPRESSION.search(token.string)
            if match and not REASONED.match(match.group("rest").strip()):
                offenders.append(f"{path.relative_to(ROOT)}:{token.start[0]}: {token.string.strip()}")
    assert not offenders, "suppressions without a rule and a reason:\n" + "\n".join(offenders)


def module_graph() -> dict[str, set[str]]:
    """Module → the project modules it imports (function-level and TYPE_CHECKING imports
    included: an import hidden in a function or behind a type check that closes a loop is a
    cycle all the same). ``from package import name`` is an edge to ``package.name`` when
    that is a module, else to the package; ``import a.b.c`` is an edge to ``a.b.c`` alone."""
    modules = {_module_name(p): p for p in _sources(PACKAGES)}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        edges: set[str] = set()
        for _, target, names in _imported_modules(path):
            if target.split(".")[0] not in PACKAGES:
                continue
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in modules]
            edges.update(subs or ([target] if target in modules else []))
            if names and len(subs) < len(names) and target in modules:
                edges.add(target)  # names that are not modules come from the package itself
        edges.discard(name)
        graph[name] = edges
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module (the cycles)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
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
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle_between_modules():
    """Not only the layers: no two modules of the project import each other, directly or
    through others — the code a cycle needs belongs in a module of its own or in the layer below."""
    cycles = strongly_connected(module_graph())
    assert not cycles, "import cycles between modules:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_the_cycle_check_finds_a_cycle():
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []
