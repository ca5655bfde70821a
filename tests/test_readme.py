"""The README's code runs as written, from outside the checkout, and so does the code of the docs
pages that hold the manual it points to.

Every ```python block of README.md runs; so do the blocks of the docs pages in `PAGES` (the manual
the README hands on to: the layer pages that hold the examples of each layer) and the example
scripts the docs show without running (`SHOWN`). They run in a fresh interpreter with a temporary
working directory, so they see the installed package (not the checkout's files), and `.ci/run` runs
this file on the oldest supported versions too. A README block runs in a namespace of its own, so it
sees nothing a previous block defined; a docs page's blocks run in order in one namespace, as the
site's build runs them (docs/site/hooks.py), except a block whose first line is `# not run`. The
units that change process-wide state (`jax.config`, `jax.distributed`) get an interpreter of their
own; the others share one, so that JAX is imported, and the programs they have in common compiled,
once.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
SITE = ROOT / "docs" / "site"
PAGES = ("samplers.md", "estimators.md", "gradients.md", "scene.md", "adapters.md")
SHOWN = ("examples/estimate_many.py",)  # docs/site/hooks.py's SHOWN_NOT_RUN: the build never runs it


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)


BLOCKS = python_blocks(README.read_text())
# (name, blocks run in order in one namespace)
UNITS = ([(f"README block {i}", [block]) for i, block in enumerate(BLOCKS)]
         + [(f"docs/site/{page}",
             [b for b in python_blocks((SITE / page).read_text()) if not b.startswith("# not run")])
            for page in PAGES]
         + [(f"docs/site/{script}", [(SITE / script).read_text()]) for script in SHOWN])

# Runs the units given as a JSON list on stdin, each in a new namespace as a script (__main__);
# stops at the first block that raises, naming it.
RUNNER = """
import json, sys, traceback
for name, blocks in json.load(sys.stdin):
    namespace = {"__name__": "__main__"}
    for index, source in enumerate(blocks):
        try:
            exec(compile(source, f"{name}, block {index}", "exec"), namespace)
        except BaseException:
            sys.stderr.write(f"{name}, block {index} failed:\\n{source}\\n{traceback.format_exc()}")
            sys.exit(1)
"""


def _own_process(blocks: list[str]) -> bool:
    return any("jax.config" in block or "jax.distributed" in block for block in blocks)


GROUPS = {"shared": [unit for unit in UNITS if not _own_process(unit[1])]}
GROUPS.update({name: [(name, blocks)] for name, blocks in UNITS if _own_process(blocks)})


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 2  # the quick start and the user-written sampler
    assert all(blocks for _, blocks in UNITS), [name for name, blocks in UNITS if not blocks]
    assert sum(len(units) for units in GROUPS.values()) == len(UNITS)


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_readme_blocks_run_outside_the_checkout(group, tmp_path):
    # Statistical in one place: the user-written sampler's README block asserts chi2_test(...).passed at
    # the default significance, FFR 1e-6 for the group that runs it ("shared").
    result = subprocess.run([sys.executable, "-c", RUNNER], input=json.dumps(GROUPS[group]), cwd=tmp_path,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]


def test_ci_runs_the_readme_test_command():
    text = README.read_text()
    command = next(line for block in re.findall(r"^```bash\n(.*?)^```", text, re.S | re.M)
                   for line in block.splitlines() if "pytest" in line)
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert command in ci, (command, ci)


def test_the_readme_names_the_floors_that_ci_tests():
    """The README's supported versions are pyproject.toml's floors, the ones `.ci/run` pins in its second step."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    floors = dict(requirement.split(">=") for requirement in project["dependencies"])
    supported = next(paragraph for paragraph in README.read_text().split("\n\n") if paragraph.startswith("Supported:"))
    assert f"Python {project['requires-python'].removeprefix('>=')}," in supported, supported
    assert f"JAX {floors['jax']} and NumPy {floors['numpy']} or newer" in supported, supported
    assert f"jaxlib {floors['jax']}" in supported, supported
    assert set(floors) == {"jax", "numpy"}, floors  # a new dependency gets its floor named in the README too
    assert "pyproject.toml" in (ROOT / ".ci" / "run").read_text()  # the pins are read from it


OPTIONAL = {"numpyro": "jaxsample[adapters]", "distrax": "jaxsample[adapters]",
            "tensorflow_probability": "jaxsample[adapters]", "matplotlib": "jaxsample[plot]"}


def test_a_block_that_needs_an_extra_says_which():
    """The README's install lines give the test or plot extra; a block (of the README or of the manual's
    pages) importing a library only an extra brings names that extra, so that a reader who installed
    `.[plot]` knows what else to install."""
    for name, blocks in UNITS:
        for block in blocks:
            imported = set(re.findall(r"^\s*(?:import|from)\s+([A-Za-z_]+)", block, re.M))
            for library, extra in OPTIONAL.items():
                if library in imported:
                    assert extra in block, f"a block of {name} imports {library} without naming {extra}:\n{block}"
