"""The package's import graph, read from its source: its cycles and its upward edges.

    python tests/import_graph.py        # the counts, then every cycle and every upward edge

Every module under `jaxsample/` is parsed with `ast`; every `import` and `from ... import` in it,
at module level or inside a function or class body, relative or absolute, becomes an edge to the
`jaxsample` module it names. `from package import name` is an edge to `package.name` where that is
a module and to `package` otherwise. Importing `package.module` also runs `package/__init__.py`,
but that edge is not drawn: within a package every submodule would otherwise sit in a cycle with
its `__init__`, and across packages it adds nothing the `__init__`'s own edges do not already
show. Imports of other libraries (numpyro, distrax, tfp, matplotlib among them) are not edges.

Layers, bottom first (`LAYERS`), as docs/design.md numbers them ("data flows down, never back
up"), each folder at the layer of what it holds:

1. numerics: `_core/` and `numerics.py` (its public re-export);
2. uniform sources: `uniforms/`;
3. samplers: `samplers/`, and `edges/` (regions and the integrands that declare their jumps:
   geometry built on `samplers.frame` that the estimators read);
4. estimators: `estimators/`, the gradient estimators (design.md's layer 5) included: they live in
   the same folder and package;
6. checks: `testing/`, `domains.py` (the checks' geometry) and `quadrature.py` (deterministic
   quadrature baselines);
7. scene: `scene/`;
then the public front, `jaxsample/__init__.py` (which re-exports the layers above) and `adapters/`
(conversions to other libraries' distributions, loaded on first use); 8. the report, which uses
the public front; and `__main__.py`, the command line that runs the report.

An edge is upward when a module imports a module of a higher layer; edges within one layer are
allowed as long as they make no cycle. A cycle is a strongly connected component of more than one
module; the elementary cycles inside the components are counted too (one component can hold many).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PACKAGE = "jaxsample"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE

LAYERS = (           # bottom first; a module belongs to the longest of these prefixes it has
    ("numerics", ("jaxsample._core", "jaxsample.numerics")),
    ("uniform sources", ("jaxsample.uniforms",)),
    ("samplers", ("jaxsample.samplers", "jaxsample.edges")),
    ("estimators", ("jaxsample.estimators",)),
    ("checks", ("jaxsample.testing", "jaxsample.domains", "jaxsample.quadrature")),
    ("scene", ("jaxsample.scene",)),
    ("public front", ("jaxsample", "jaxsample.adapters")),
    ("report", ("jaxsample.report",)),
    ("command line", ("jaxsample.__main__",)),
)
_RANK = {prefix: rank for rank, (_, prefixes) in enumerate(LAYERS) for prefix in prefixes}


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file under the package."""
    modules = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def _resolve_base(module: str, is_package: bool, level: int, name: str | None) -> str:
    """The absolute dotted name `from <level dots><name> import ...` refers to inside `module`."""
    if level == 0:
        return name or ""
    parts = module.split(".")
    if not is_package:
        parts = parts[:-1]
    if level > 1:
        parts = parts[: len(parts) - (level - 1)]
    base = ".".join(parts)
    return f"{base}.{name}" if name else base


def imports_of(module: str, path: Path, modules: dict[str, Path]) -> set[tuple[str, int]]:
    """(imported jaxsample module, line) for every import statement anywhere in the file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve_base(module, is_package, node.level, node.module)
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                targets.append(sub if sub in modules else base)
        for target in targets:
            # `import jaxsample.a.b` names jaxsample.a.b; keep the longest prefix that is a module
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != module and target.split(".")[0] == PACKAGE:
                found.add((target, node.lineno))
    return found


def graph(root: Path = ROOT) -> dict[str, dict[str, int]]:
    """module -> {imported module: first line that imports it}."""
    modules = module_files(root)
    edges = {}
    for module, path in modules.items():
        out = {}
        for target, line in sorted(imports_of(module, path, modules)):
            out.setdefault(target, line)
        edges[module] = out
    return edges


def layer(module: str) -> int:
    """The rank of a module's layer in `LAYERS` (0 at the bottom)."""
    prefix = module
    while prefix not in _RANK:
        if "." not in prefix:
            raise KeyError(f"{module} has no layer in LAYERS")
        prefix = prefix.rpartition(".")[0]
    return _RANK[prefix]


def layer_name(module: str) -> str:
    return LAYERS[layer(module)][0]


def cycles(edges: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
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
                components.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return sorted(components)


def cycle_edges(edges: dict[str, dict[str, int]]) -> list[tuple[str, str, int]]:
    """The edges that lie inside a cycle: both ends in one strongly connected component."""
    component_of = {m: i for i, c in enumerate(cycles(edges)) for m in c}
    return sorted((a, b, line) for a, out in edges.items() for b, line in out.items()
                  if a in component_of and component_of[a] == component_of.get(b))


def upward_edges(edges: dict[str, dict[str, int]]) -> list[tuple[str, str, int]]:
    """(importer, imported, line) where the importer's layer is below the imported module's."""
    return sorted((a, b, line) for a, out in edges.items() for b, line in out.items() if layer(a) < layer(b))


def elementary_cycles(edges: dict[str, dict[str, int]]) -> list[list[str]]:
    """Every elementary cycle (no module twice), each listed from its smallest module."""
    found = []
    for component in cycles(edges):
        members = set(component)
        for start in component:      # cycles whose smallest module is `start`
            path = [start]

            def extend(v):
                for w in sorted(edges[v]):
                    if w == start:
                        found.append(list(path))
                    elif w in members and w > start and w not in path:
                        path.append(w)
                        extend(w)
                        path.pop()

            extend(start)
    return found


def report(edges: dict[str, dict[str, int]]) -> str:
    """The counts, then every cycle, the edges inside it and every upward edge."""
    found_cycles, found_upward = cycles(edges), upward_edges(edges)
    lines = [f"{len(edges)} modules, {sum(map(len, edges.values()))} import edges: "
             f"{len(found_cycles)} strongly connected components ({len(elementary_cycles(edges))} elementary "
             f"cycles), {len(found_upward)} upward edges"]
    for component in found_cycles:
        lines.append("cycle: " + " ".join(component))
        lines += [f"  {a} -> {b}  (line {line})" for a, b, line in cycle_edges(edges) if a in component]
    lines += [f"upward: {a} ({layer_name(a)}) -> {b} ({layer_name(b)})  (line {line})"
              for a, b, line in found_upward]
    return "\n".join(lines)


def main() -> int:
    edges = graph()
    print(report(edges))
    return 1 if cycles(edges) or upward_edges(edges) else 0


if __name__ == "__main__":
    sys.exit(main())
