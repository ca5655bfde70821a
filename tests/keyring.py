"""Keys for tests, derived from the test's own identity.

`next_key()` returns the k-th key of the test that is running now: a hash of its pytest node id
(``tests/estimators/test_estimate.py::test_float64``, parameters included) folded with k, the number
of keys that test has drawn before. A test therefore gets the same keys alone, in its file, in any
order and on any pytest-xdist worker, and two tests never share a key by accident. It reads the node
id from ``PYTEST_CURRENT_TEST``, which pytest sets for every phase of a test, so it works inside a
test and inside a function-scoped fixture; a fixture of wider scope (module, session) is set up for
whichever test asks first, so it takes a fixed key of its own (``fixed_key``) instead.
"""

from __future__ import annotations

import os
import zlib

import jax

_drawn: dict[str, int] = {}


def current_test() -> str:
    """The node id of the test pytest is running now (setup, call or teardown)."""
    current = os.environ.get("PYTEST_CURRENT_TEST")
    if not current:
        raise RuntimeError("keyring.next_key() draws a test's own keys, so it must run inside a test")
    return current.rsplit(" (", 1)[0]


def fixed_key(name: str):
    """A key named by a string: the same in every run, for fixtures shared by several tests."""
    return jax.random.key(zlib.crc32(name.encode()))


def next_key():
    """The next key of the running test (a fresh key each call, so JAX's key-reuse checker is content)."""
    node = current_test()
    count = _drawn.get(node, 0)
    _drawn[node] = count + 1
    return jax.random.fold_in(fixed_key(node), count)
