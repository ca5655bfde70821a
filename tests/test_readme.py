"""Every ```python block of README.md runs as written, from outside the checkout.

The blocks run in a fresh interpreter with a temporary working directory, so they see the installed
package (not the checkout's files). Each block runs in a namespace of its own, so it sees nothing a
previous block defined; the blocks that change process-wide state (`jax.config`, `jax.distributed`)
get an interpreter of their own. The others share one, so that JAX is imported, and the programs
they have in common compiled, once.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
BLOCKS = re.findall(r"^```python\n(.*?)^```", README.read_text(), re.S | re.M)

# Runs the blocks given as a JSON list on stdin, each in a new namespace as a script (__main__);
# stops at the first that raises, naming it.
RUNNER = """
import json, sys, traceback
blocks = json.load(sys.stdin)
for index, source in blocks:
    try:
        exec(compile(source, f"README block {index}", "exec"), {"__name__": "__main__"})
    except BaseException:
        sys.stderr.write(f"README block {index} failed:\\n{source}\\n{traceback.format_exc()}")
        sys.exit(1)
"""


def _own_process(block: str) -> bool:
    return "jax.config" in block or "jax.distributed" in block


GROUPS = {"shared": [(i, b) for i, b in enumerate(BLOCKS) if not _own_process(b)]}
GROUPS.update({f"block-{i}": [(i, b)] for i, b in enumerate(BLOCKS) if _own_process(b)})


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 2  # the quick start and the user-written sampler
    assert sum(len(blocks) for blocks in GROUPS.values()) == len(BLOCKS)


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_readme_blocks_run_outside_the_checkout(group, tmp_path):
    # Statistical in one place: the user-written sampler's block asserts chi2_test(...).passed at the
    # default significance, FFR 1e-6 for the group that runs it ("shared").
    result = subprocess.run([sys.executable, "-c", RUNNER], input=json.dumps(GROUPS[group]), cwd=tmp_path,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]


def test_ci_runs_the_readme_test_command():
    text = README.read_text()
    command = next(line for block in re.findall(r"^```bash\n(.*?)^```", text, re.S | re.M)
                   for line in block.splitlines() if "pytest" in line)
    ci = (README.parent / ".ci" / "run").read_text().splitlines()
    assert command in ci, (command, ci)


def test_the_readme_names_the_floors_that_ci_tests():
    """The README's supported versions are pyproject.toml's floors, the ones `.ci/run` pins in its second step."""
    import tomllib

    project = tomllib.loads((README.parent / "pyproject.toml").read_text())["project"]
    floors = dict(requirement.split(">=") for requirement in project["dependencies"])
    supported = next(paragraph for paragraph in README.read_text().split("\n\n") if paragraph.startswith("Supported:"))
    assert f"Python {project['requires-python'].removeprefix('>=')}," in supported, supported
    assert f"JAX {floors['jax']} and NumPy {floors['numpy']} or newer" in supported, supported
    assert f"jaxlib {floors['jax']}" in supported, supported
    assert set(floors) == {"jax", "numpy"}, floors  # a new dependency gets its floor named in the README too
    assert "pyproject.toml" in (README.parent / ".ci" / "run").read_text()  # the pins are read from it


OPTIONAL = {"numpyro": "jaxsample[adapters]", "distrax": "jaxsample[adapters]",
            "tensorflow_probability": "jaxsample[adapters]", "matplotlib": "jaxsample[plot]"}


def test_a_block_that_needs_an_extra_says_which():
    """The README's install lines give the test or plot extra; a block importing a library only an extra
    brings names that extra, so that a reader who installed `.[plot]` knows what else to install."""
    for block in BLOCKS:
        imported = set(re.findall(r"^\s*(?:import|from)\s+([A-Za-z_]+)", block, re.M))
        for library, extra in OPTIONAL.items():
            if library in imported:
                assert extra in block, f"a README block imports {library} without naming {extra}:\n{block}"
