"""A test's keys come from its own identity, never from state shared across tests.

Keys drawn from a module-level iterator (``KEYS = iter(...)`` over split keys, then ``next(KEYS)``)
make a test's numbers depend on which tests of its module ran before it on the same worker: a
statistical test then passes in one order and fails in another. `tests/keyring.py` derives each
test's keys from its node id instead; these tests hold the suite to that.
"""

import ast
from pathlib import Path

import jax
import numpy as np

import keyring

TESTS = Path(__file__).resolve().parent
SHARED_STATE_CALLS = {"iter", "count", "cycle", "islice"}


def _called_name(node: ast.Call) -> str:
    func = node.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def module_level_iterators(source: str) -> list[str]:
    """The module-level names bound to an iterator or generator: state that every test of the module
    would advance."""
    found = []
    for statement in ast.parse(source).body:
        if not isinstance(statement, (ast.Assign, ast.AnnAssign)) or statement.value is None:
            continue
        value = statement.value
        shared = isinstance(value, ast.Call) and _called_name(value) in SHARED_STATE_CALLS
        if shared or isinstance(value, ast.GeneratorExp):
            targets = statement.targets if isinstance(statement, ast.Assign) else [statement.target]
            found += [ast.unparse(t) for t in targets]
    return found


def test_the_scan_finds_a_shared_iterator():
    source = ("import itertools, jax\nKEYS = iter(list(jax.random.split(jax.random.key(0), 8)))\n"
              "SEEDS = itertools.count(1000)\nGEN = (k for k in range(3))\nN = 1 << 14\n"
              "CASES = [c for c in range(4) if any(d > c for d in range(3))]\n")
    assert module_level_iterators(source) == ["KEYS", "SEEDS", "GEN"]


def test_no_test_module_draws_keys_from_a_shared_iterator():
    offenders = {}
    for path in sorted(TESTS.rglob("*.py")):
        names = module_level_iterators(path.read_text())
        if names:
            offenders[str(path.relative_to(TESTS))] = names
    assert not offenders, f"module-level iterators shared by the tests of a module: {offenders}; " \
                          "draw keys with keyring.next_key() instead"


def test_a_tests_keys_do_not_depend_on_what_ran_before(monkeypatch):
    """The same node id gives the same keys whether another test drew keys before it or not, and two
    node ids (or two draws of one test) give different keys."""
    def draws(order):
        keyring._drawn.clear()
        out = {}
        for node in order:
            monkeypatch.setenv("PYTEST_CURRENT_TEST", f"{node} (call)")
            out[node] = [np.asarray(jax.random.key_data(keyring.next_key())) for _ in range(2)]
        return out

    forward, backward = draws(["a.py::t1", "a.py::t2"]), draws(["a.py::t2", "a.py::t1"])
    keyring._drawn.clear()
    for node in forward:
        for a, b in zip(forward[node], backward[node]):
            np.testing.assert_array_equal(a, b)
    assert not np.array_equal(forward["a.py::t1"][0], forward["a.py::t1"][1])
    assert not np.array_equal(forward["a.py::t1"][0], forward["a.py::t2"][0])
