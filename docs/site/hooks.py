"""MkDocs hooks of the documentation site (mkdocs.yml, `hooks:`): what the pages show that must come
from the code at build time, so that it cannot go stale.

- Examples: every `examples/*.py` beside this file runs once per build, in this process, with
  matplotlib's Agg backend and every Python warning turned into an error. What it prints and the
  figures it leaves open become part of its page, where the page says `<!-- run: NAME.py -->`; the
  figures are written into the site as `examples/figures/NAME-K.png`. An example that raises (or
  warns) fails the build. A script named in `SHOWN_NOT_RUN` is compiled (so a syntax error fails
  the build) but not run, and a page shows it with `<!-- show: NAME.py -->`.
- Pages whose front matter says `execute: true` (the tour, the layer pages): their ```python blocks
  run in order in one namespace, as a notebook's cells would, and what each prints is shown under it;
  a block that raises or warns fails the build. A block whose first line is `# not run` is shown only.
- `<!-- samplers-table -->`: one row per sampler that `jaxsample.__all__` exports, with the measure
  its density is over, its constructor's parameters and the ranges declared with
  `jaxsample.parameter`, read from the classes and from instances built by the contract suite's
  registry (`tests/samplers/registry.py`, which a test keeps complete).
- `<!-- sources-table -->`: one row per uniform source class that `jaxsample.uniforms.__all__`
  exports: its `uniforms=` name, its constructor and default replicates, its docstring's first line.
- `<!-- public-names -->`: every name of `jaxsample.__all__`, linked to its entry in the reference
  (a module without a page under reference/ yet is named, not linked).
- `<!-- results: FILE -->`, `<!-- results: FILE#HEADING -->`: the measured results in
  `benchmarks/results/FILE` (the whole file, or the section under that heading), and
  `<!-- results-table: ... -->` only the first table there, each followed by the file it came from:
  the docs show the numbers as the benchmark wrote them, never a copy kept by hand.

Any other `<!-- run: ... -->`-style marker that names no script raises, as does a sampler missing
from the registry: the strict build fails instead of printing a page with a hole in it.
"""

from __future__ import annotations

import contextlib
import importlib.util
import inspect
import io
import logging
import posixpath
import re
import runpy
import sys
import time
import traceback
import warnings
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
EXAMPLES = HERE / "examples"
FIGURES = "examples/figures"
# Shown as code, never run here: it starts JAX's distributed runtime, which a process does once
# (tests/test_readme.py runs it, as one process, in an interpreter of its own).
SHOWN_NOT_RUN = {"estimate_many.py"}
MARKER = re.compile(r"<!--\s*(run|show):\s*([\w.-]+)\s*-->")

log = logging.getLogger("mkdocs.hooks.jaxsample")
_runs: dict[str, dict] = {}


def _import_jaxsample():
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import jaxsample
    return jaxsample


# ---------------------------------------------------------------------------------------------
# Examples
# ---------------------------------------------------------------------------------------------

def _run_example(script: Path) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.close("all")
    out = io.StringIO()
    start = time.perf_counter()
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(out):
            warnings.simplefilter("error")
            runpy.run_path(str(script), run_name="__main__")
    except BaseException as error:  # SystemExit too: an example has no business exiting
        raise PluginError(f"docs example {script.name} failed:\n{traceback.format_exc()}") from error
    seconds = time.perf_counter() - start
    figures = []
    for number in plt.get_fignums():
        figure = plt.figure(number)
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
        titles = [figure.get_suptitle()] + [axes.get_title() for axes in figure.axes]
        figures.append((buffer.getvalue(), next((t for t in titles if t), script.stem.replace("_", " "))))
    plt.close("all")
    log.info(f"example {script.name}: {seconds:.1f} s, {len(figures)} figure(s)")
    return {"source": script.read_text(), "output": out.getvalue(), "figures": figures, "seconds": seconds}


def on_files(files, config):
    _import_jaxsample()
    _runs.clear()
    for script in sorted(EXAMPLES.glob("*.py")):
        if script.name in SHOWN_NOT_RUN:
            source = script.read_text()
            compile(source, str(script), "exec")
            _runs[script.name] = {"source": source, "output": "", "figures": [], "seconds": 0.0}
            continue
        run = _runs[script.name] = _run_example(script)
        for index, (png, _) in enumerate(run["figures"], 1):
            files.append(File.generated(config, f"{FIGURES}/{script.stem}-{index}.png", content=png))
    return files


def _example_markdown(kind: str, name: str, page_uri: str) -> str:
    if name not in _runs:
        raise PluginError(f"{page_uri}: <!-- {kind}: {name} --> names no script in {EXAMPLES}")
    run = _runs[name]
    if kind == "run" and name in SHOWN_NOT_RUN:
        raise PluginError(f"{page_uri}: {name} is shown, not run: write <!-- show: {name} -->")
    parts = [f"```python title=\"{name}\"\n{run['source'].rstrip()}\n```"]
    if kind == "run":
        if run["output"].strip():
            parts.append(f"Output (run when this page was built, {run['seconds']:.1f} s):\n\n"
                         f"```text\n{run['output'].rstrip()}\n```")
        page_dir = posixpath.dirname(page_uri)
        for index, (_, title) in enumerate(run["figures"], 1):
            target = posixpath.relpath(f"{FIGURES}/{Path(name).stem}-{index}.png", page_dir or ".")
            parts.append(f"![{title}]({target})")
    return "\n\n".join(parts)


# ---------------------------------------------------------------------------------------------
# The samplers table and the public names
# ---------------------------------------------------------------------------------------------

def _registry():
    spec = importlib.util.spec_from_file_location("jaxsample_docs_registry", ROOT / "tests" / "samplers" / "registry.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def _public_samplers(js):
    return [(name, getattr(js, name)) for name in js.__all__
            if isinstance(getattr(js, name), type) and issubclass(getattr(js, name), js.Sampler)
            and getattr(js, name) is not js.Sampler]


def _summary(cls) -> str:
    doc = inspect.getdoc(cls) or ""
    first = doc.split("\n\n")[0].replace("\n", " ").strip()
    return first.replace("|", "\\|")


def _built_from_samplers(cls) -> str | None:
    """The constructor argument that holds the samplers whose measure this one takes (`base`,
    `proposal`, `components`), if any. A microfacet `distribution` is not one: the normals it
    shapes are always directions, over solid angle."""
    for name, argument in inspect.signature(cls).parameters.items():
        annotation = str(argument.annotation)
        if "Sampler" in annotation or name in ("components",):
            return name
    return None


def _range_text(spec) -> str:
    if not spec.bounded:
        return "any real" if spec.rank == 0 else f"real, rank {spec.rank}"
    text = spec.describe().replace("inf", "∞").replace("e+0", "e").replace("e-0", "e-")
    return text if spec.rank == 0 else f"{text}, rank {spec.rank}"


def samplers_table() -> str:
    js = _import_jaxsample()
    from jaxsample._core.pytree import parameters
    registry = _registry()
    instances: dict[type, list] = {}
    for entry in registry.ENTRIES:
        for case in entry.cases:
            if case.x64:
                continue
            sampler = entry.build(case)
            instances.setdefault(type(sampler), []).append(sampler)
    rows = ["| sampler | what it samples | measure | parameters and their ranges | u dims | inverse |",
            "|---|---|---|---|---|---|"]
    for name, cls in _public_samplers(js):
        built = instances.get(cls)
        if not built:
            raise PluginError(f"samplers table: {name} has no entry in tests/samplers/registry.py")
        declared = parameters(cls)
        held = _built_from_samplers(cls)
        measures = sorted({str(s.measure) for s in built})
        if isinstance(cls.__dict__.get("measure"), str) or (held is None and len(measures) == 1):
            measure = measures[0] if len(measures) == 1 else ", ".join(measures)
        else:
            measure = f"that of `{held}`"
        cells = []
        for argument, info in inspect.signature(cls).parameters.items():
            if argument in declared:
                text = f"`{argument}` ∈ {_range_text(declared[argument])}"
            elif argument == "method" or info.annotation in ("str", str):
                seen = sorted({str(getattr(s, argument)) for s in built if hasattr(s, argument)},
                              key=lambda v: v != info.default)  # the default first
                cells.append(f"`{argument}`: " + " / ".join(
                    f"`{v}`" + (" (default)" if v == info.default else "") for v in seen))
                continue
            else:
                text = f"`{argument}`"
            if info.default is not inspect.Parameter.empty and info.default is not None:
                text += f" (default {info.default!r})"
            cells.append(text)
        # Declared parameters the constructor does not take by that name (UniformCone's stable form).
        for argument, spec in declared.items():
            if argument not in inspect.signature(cls).parameters and spec.bounded and not spec.static:
                if any(argument in str(info) for info in inspect.signature(cls).parameters.values()):
                    continue
                if argument in vars(built[0]) and not argument.startswith(("pmf", "cdf", "alias", "marginal", "conditional")):
                    cells.append(f"stored as `{argument}` ∈ {_range_text(spec)}")
        dims = sorted({int(s.uniform_dims) for s in built})
        inverse = sorted({"yes" if s.has_inverse else "no" for s in built}, reverse=True)
        rows.append(f"| [`{name}`][jaxsample.samplers.{name}] | {_summary(cls)} | {measure} | "
                    f"{'<br>'.join(cells) or '—'} | {', '.join(map(str, dims))} | "
                    f"{' / '.join(inverse) if len(inverse) == 1 else 'by method'} |")
    return "\n".join(rows)


def sources_table() -> str:
    js = _import_jaxsample()
    uniforms = js.uniforms
    rows = ["| source | `uniforms=` | constructor | default replicates | what it is |", "|---|---|---|---|---|"]
    for name in uniforms.__all__:
        cls = getattr(uniforms, name)
        if not (isinstance(cls, type) and issubclass(cls, uniforms.Source)) or cls is uniforms.Source:
            continue
        source = cls()
        if uniforms.as_source(source.name).__class__ is not cls:
            raise PluginError(f"sources table: uniforms={source.name!r} does not give a {name}")
        rows.append(f"| [`{name}`][jaxsample.uniforms.{name}] | `\"{source.name}\"` | `{name}{inspect.signature(cls)}` | "
                    f"{source.replicates} | {_summary(cls)} |")
    return "\n".join(rows)


def public_names(files) -> str:
    js = _import_jaxsample()
    modules, samplers, others = [], [], []
    pages = {file.src_uri for file in files}
    for name in js.__all__:
        value = getattr(js, name)
        if inspect.ismodule(value):
            page = f"reference/{'numerics' if name == 'quadrature' else name}.md"
            modules.append(f"[`{name}`][{value.__name__}]" if page in pages else f"`{name}`")
        elif isinstance(value, type) and issubclass(value, js.Sampler):
            samplers.append(f"[`{name}`][jaxsample.samplers.{name}]")
        else:
            home = "samplers" if value.__module__.startswith("jaxsample._core") else value.__module__.split(".")[1]
            others.append(f"[`{name}`][jaxsample.{home}.{name}]")
    return (f"**Samplers:** {', '.join(samplers)}.\n\n**Estimators, gradients and the pieces for your own "
            f"sampler:** {', '.join(others)}.\n\n**Modules:** {', '.join(modules)}.")


# ---------------------------------------------------------------------------------------------
# Measured results, read from benchmarks/results/
# ---------------------------------------------------------------------------------------------

RESULTS = ROOT / "benchmarks" / "results"
RESULTS_MARKER = re.compile(r"<!--\s*results(-table)?:\s*([\w.-]+)(?:#([^>]*?))?\s*-->")
HEADING = re.compile(r"(#+)\s+(.*?)\s*$")


def results_markdown(table_only: bool, name: str, section: str | None, page_uri: str) -> str:
    """The text of benchmarks/results/NAME (or of its section headed SECTION, up to the next heading
    of the same level), or only the first table in it, followed by the file it came from. Its
    headings are moved down two levels, to sit under the page's own; the file's title is named in
    the source line."""
    path = RESULTS / name
    marker = f"<!-- results{'-table' if table_only else ''}: {name}{'#' + section if section else ''} -->"
    if not path.is_file():
        raise PluginError(f"{page_uri}: {marker} names no file in benchmarks/results/")
    lines = path.read_text().splitlines()
    title = next((m.group(2) for line in lines if (m := HEADING.match(line)) and len(m.group(1)) == 1), name)
    if section:
        section = section.strip()
        start = next((i for i, line in enumerate(lines) if (m := HEADING.match(line)) and m.group(2) == section), None)
        if start is None:
            raise PluginError(f"{page_uri}: {marker}: benchmarks/results/{name} has no heading {section!r}")
        level = len(HEADING.match(lines[start]).group(1))
        end = next((i for i in range(start + 1, len(lines))
                    if (m := HEADING.match(lines[i])) and len(m.group(1)) <= level), len(lines))
        body = lines[start + 1:end]
    else:
        body = [line for line in lines if not ((m := HEADING.match(line)) and len(m.group(1)) == 1)]
    if table_only:
        first = next((i for i, line in enumerate(body) if line.startswith("|")), None)
        if first is None:
            raise PluginError(f"{page_uri}: {marker}: no table there")
        end = next((i for i in range(first, len(body)) if not body[i].startswith("|")), len(body))
        body = body[first:end]
    lines, body = body, []
    for line in lines:
        if line.startswith("|") and body and body[-1].strip() and not body[-1].startswith("|"):
            body.append("")  # a table right under a line of text is a table in the file's eyes, not Markdown's
        body.append("##" + line if HEADING.match(line) else line)
    where = f"`benchmarks/results/{name}`" + (f", section \u201c{section}\u201d" if section else "")
    return "\n".join(body).strip() + f"\n\nSource: {where}; the file's title: {title}.\n"


# ---------------------------------------------------------------------------------------------
# Pages whose code blocks run
# ---------------------------------------------------------------------------------------------

BLOCK = re.compile(r"^```python\n(.*?)^```\n", re.S | re.M)


def _execute_blocks(markdown: str, uri: str) -> str:
    import matplotlib
    matplotlib.use("Agg")
    namespace = {"__name__": "__main__"}
    start = time.perf_counter()
    count = 0

    def run(match):
        nonlocal count
        source = match.group(1)
        if source.startswith("# not run"):
            return f"```python\n{source.split(chr(10), 1)[1]}```\n"
        count += 1
        out = io.StringIO()
        try:
            with warnings.catch_warnings(), contextlib.redirect_stdout(out):
                warnings.simplefilter("error")
                exec(compile(source, f"{uri}, code block {count}", "exec"), namespace)
        except BaseException as error:
            raise PluginError(f"{uri}: code block {count} failed:\n{source}\n{traceback.format_exc()}") from error
        shown = f"```python\n{source}```\n"
        if out.getvalue().strip():
            shown += f"\n```text\n{out.getvalue().rstrip()}\n```\n"
        return shown

    markdown = BLOCK.sub(run, markdown)
    log.info(f"{uri}: {count} code block(s) run in {time.perf_counter() - start:.1f} s")
    return markdown


def on_page_markdown(markdown, page, config, files):
    uri = page.file.src_uri
    if page.meta.get("execute"):
        markdown = _execute_blocks(markdown, uri)
    markdown = MARKER.sub(lambda m: _example_markdown(m.group(1), m.group(2), uri), markdown)
    if "<!-- samplers-table -->" in markdown:
        markdown = markdown.replace("<!-- samplers-table -->", samplers_table())
    if "<!-- public-names -->" in markdown:
        markdown = markdown.replace("<!-- public-names -->", public_names(files))
    if "<!-- sources-table -->" in markdown:
        markdown = markdown.replace("<!-- sources-table -->", sources_table())
    markdown = RESULTS_MARKER.sub(lambda m: results_markdown(bool(m.group(1)), m.group(2), m.group(3), uri), markdown)
    leftover = re.search(r"<!--\s*(run|show|samplers-table|sources-table|public-names|results)\b[^>]*-->", markdown)
    if leftover:
        raise PluginError(f"{uri}: marker not understood: {leftover.group(0)}")
    return markdown
