"""Public estimators run as one compiled program, also when they are called outside `jax.jit`.

Called eagerly without it, an estimator's Python code runs op by op: every small operation around
its loop (turning the key into seed words, merging the tail chunk, the double-float finish) is a
program of its own, compiled on first use, and `jax.grad` of an eager `estimate` compiles 158 of
them (6 s on 2 cores) where one forward and one backward program do. `compiled_entry` wraps a
public function in `jax.jit`: the arguments that fix the program (the integrand, `n`, the source,
the mode, the mesh, ...) are static, everything else (samplers, parameters, keys) is traced, so a
second call with the same integrand and new parameter values or keys reuses the program. Every
public estimator is such an entry: `estimate`, `expectation`, `estimate_mis`, `estimate_ratio`,
`estimate_antithetic`, `estimate_control_variate`, `estimate_grad`, `expectation_grad`,
`estimate_until`, `scene.shade` and `scene.shade_grad`.

What it returns goes through every check registered with `check_results_with`: the estimators'
result module registers `warn_if_unreliable`, so an unreliable estimate returned by an eager call
emits an `UnreliableEstimateWarning`. Inside an enclosing `jit`, `vmap` or `grad` nothing changes
(a nested `jit` is inlined, and no value can be inspected). The checks are registered, not
imported: this module is the bottom layer, and the results they check are defined above it. A call
whose static arguments cannot be hashed (a traced `n`, an unhashable callable) or whose traced
arguments are not arrays or numbers runs the function as written, so that its own checks give their
usual messages (a string given where a number may also go, such as `baseline="leave_one_out"`, is
static for that call, not a reason to run uncompiled).
"""

from __future__ import annotations

import functools
import inspect
from typing import Callable

import jax
import numpy as np

from .keys import as_key

__all__ = ["compiled_entry", "array_leaves", "check_results_with"]

_ARRAY_LEAVES = (jax.Array, np.ndarray, np.generic, bool, int, float, complex)

# check(result, owner) for what every entry returns, in the order registered.
_RESULT_CHECKS: list[Callable] = []


def check_results_with(check: Callable) -> Callable:
    """Register `check(result, owner)` to run on the value every compiled entry returns (`owner`: the
    entry's name); a check that warns uses `stacklevel=3` to point at the entry's caller."""
    _RESULT_CHECKS.append(check)
    return check


def array_leaves(tree, *, concrete: bool = False) -> bool:
    """Whether every leaf of `tree` is an array or a number (what `jax.jit` can trace), and, with
    `concrete`, none of them a tracer (the call is made outside any transformation)."""
    return all(isinstance(leaf, _ARRAY_LEAVES) and not (concrete and isinstance(leaf, jax.core.Tracer))
               for leaf in jax.tree_util.tree_leaves(tree))


def _hashable(value) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True


def compiled_entry(*static: str, tuples: tuple[str, ...] = (), check: Callable | None = None) -> Callable:
    """Decorator: run the function under `jax.jit` with the arguments named in `static` static.

    `tuples`: static arguments that may be given as lists (sample counts per sampler); they are
    passed on as tuples. The argument named `key`, when there is one, goes through the key rule
    (`keys.as_key`) first, so a wrong key gets the same message as without compilation.
    `check(arguments)`, given the bound arguments by name, runs before anything is traced: the
    checks that need concrete values (a zero-length vector, a point inside a light) see them there.
    """

    def wrap(fn: Callable) -> Callable:
        signature = inspect.signature(fn)
        jitted = {frozenset(): jax.jit(fn, static_argnames=static)}

        def compiled(text_arguments: frozenset):
            # A string where a number may also go (`baseline="leave_one_out"` or a constant) picks
            # the program, so it is static for that call; a number there stays traced.
            if text_arguments not in jitted:
                jitted[text_arguments] = jax.jit(fn, static_argnames=tuple(static) + tuple(sorted(text_arguments)))
            return jitted[text_arguments]

        @functools.wraps(fn)
        def entry(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            arguments = bound.arguments
            for name in tuples:
                if isinstance(arguments.get(name), list):
                    arguments[name] = tuple(arguments[name])
            if "key" in arguments:
                arguments["key"] = as_key(arguments["key"], fn.__name__)
            if check is not None:
                check(arguments)
            text = frozenset(name for name, value in arguments.items()
                             if name not in static and isinstance(value, str))
            dynamic = [value for name, value in arguments.items() if name not in static and name not in text]
            if (all(_hashable(arguments[name]) for name in static if name in arguments)
                    and array_leaves(dynamic)):
                result = compiled(text)(*bound.args, **bound.kwargs)
            else:
                result = fn(*bound.args, **bound.kwargs)
            for check_result in _RESULT_CHECKS:
                check_result(result, fn.__name__)
            return result

        return entry

    return wrap
