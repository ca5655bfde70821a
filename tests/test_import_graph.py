"""The package's imports follow its layers downward and make no cycle, function-level imports included.

The bug this catches: a module that imports a higher layer or closes a cycle, most often by an
import written inside a function so that the module still loads (the compiled entry in `_core`
importing `estimators.diagnostics` when it is called; `uniforms/sources.py` importing the point
sets that subclass its `Source`). Such an import works until the day the order of loading changes,
and it means a layer cannot be read, tested or reused without the ones above it. The graph comes
from the source (`import_graph.py`, which also prints it: `python tests/import_graph.py`); the
layers are design.md's, listed in `import_graph.LAYERS`.
"""

import textwrap

import import_graph


def test_the_package_has_no_import_cycle():
    edges = import_graph.graph()
    assert import_graph.cycles(edges) == [], import_graph.report(edges)


def test_no_module_imports_a_layer_above_its_own():
    edges = import_graph.graph()
    assert import_graph.upward_edges(edges) == [], import_graph.report(edges)


def test_every_module_has_a_layer():
    for module in import_graph.graph():
        import_graph.layer(module)


def _package(root, files):
    for name, text in files.items():
        path = root / "jaxsample" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))
    return root / "jaxsample"


def test_the_reader_sees_function_level_relative_and_absolute_imports(tmp_path):
    """A lazy upward import and a cycle closed inside a function are found; imports of other
    libraries are not edges."""
    root = _package(tmp_path, {
        "__init__.py": "from . import estimators\n",
        "_core/__init__.py": "",
        "_core/entry.py": """
            import numpy

            def entry():
                from ..estimators.diagnostics import warn
                return warn
            """,
        "estimators/__init__.py": "from .result import Estimate\n",
        "estimators/result.py": """
            from .._core import entry

            class Estimate:
                def reliable(self):
                    import jaxsample.estimators.diagnostics as d
                    return d
            """,
        "estimators/diagnostics.py": """
            def warn(result):
                from .result import Estimate
                return isinstance(result, Estimate)
            """,
        "report/__init__.py": "import jaxsample\nimport matplotlib\n",
    })
    edges = import_graph.graph(root)
    entry, diagnostics, result = ("jaxsample._core.entry", "jaxsample.estimators.diagnostics",
                                  "jaxsample.estimators.result")
    assert edges[entry] == {diagnostics: 5}
    assert edges[result] == {entry: 2, diagnostics: 6}
    assert edges["jaxsample.report"] == {"jaxsample": 1}
    assert import_graph.cycles(edges) == [[entry, diagnostics, result]]
    assert import_graph.elementary_cycles(edges) == [[entry, diagnostics, result], [diagnostics, result]]
    assert import_graph.upward_edges(edges) == [(entry, diagnostics, 5)]


def test_the_layers_go_up_in_design_md_order():
    order = [import_graph.layer(m) for m in ("jaxsample._core.entry", "jaxsample.uniforms.sources",
                                             "jaxsample.samplers.base", "jaxsample.estimators.engine",
                                             "jaxsample.domains", "jaxsample.scene.direct", "jaxsample",
                                             "jaxsample.report.paths", "jaxsample.__main__")]
    assert order == sorted(order) and len(set(order)) == len(order)
