"""Every ```python block of README.md runs as written, from outside the checkout.

Each block runs in its own interpreter with a temporary working directory, so it sees the installed
package (not the checkout's files) and nothing a previous block defined.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
BLOCKS = re.findall(r"^```python\n(.*?)^```", README.read_text(), re.S | re.M)


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 2  # the quick start and the user-written sampler


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_block_runs_outside_the_checkout(index, tmp_path):
    result = subprocess.run([sys.executable, "-c", BLOCKS[index]], cwd=tmp_path, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, f"README block {index}:\n{BLOCKS[index]}\n{result.stderr[-3000:]}"


def test_ci_runs_the_readme_test_command():
    text = README.read_text()
    command = next(line for block in re.findall(r"^```bash\n(.*?)^```", text, re.S | re.M)
                   for line in block.splitlines() if "pytest" in line)
    ci = (README.parent / ".ci" / "run").read_text().splitlines()
    assert command in ci, (command, ci)
