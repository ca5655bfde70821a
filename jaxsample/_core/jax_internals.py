"""Every use the package makes of JAX's internals, in one module that imports whatever JAX is installed.

The lane interpreter (`lanes`) walks jaxprs and keys its rules on primitive objects, and
`computed_once.stored_once` is a primitive of the package's own. Those need the parts of JAX that
change between releases: `jax.extend.core` (primitive objects, literals, a primitive's bind
parameters), `jax.interpreters` (a primitive's derivative, batching and lowering rules) and, for
the primitives `jax.lax` does not export (stack, unstack, tile, mulhi), `jax._src.lax.lax`. No
other module of the package imports `jax._src` or `jax.interpreters`
(tests/_core/test_lane_fallback.py checks the source).

Importing this module never fails. A piece this JAX does not have is recorded in `MISSING` (one
line each) and its name here is None; the lanes then step aside to `jax.vmap` (see `lanes`), and
`stored_once` is the identity function instead of a primitive. `TESTED_JAX` is the range of JAX
versions the interpreter was tested with (the floor of pyproject.toml, which .ci/run tests, up to
the JAX the suite runs on); raise its top after `tests/_core` passes on a newer JAX.

`trace_platform` is the platform of the program being traced, as far as it is known at trace
time: the `jax.default_device` in effect, else `jax.default_backend()`. A program lowered for
another platform than that (ahead-of-time lowering) keeps the choice made for it.
"""

from __future__ import annotations

import jax
from jax import lax

__all__ = ["MISSING", "TESTED_JAX", "jax_version", "version_tested", "Primitive", "Literal", "primitive",
           "bind", "identity_primitive", "trace_platform"]

# The JAX versions the lane interpreter was tested with: (oldest, newest), both included.
TESTED_JAX = ((0, 8, 1), (0, 10, 2))

# What this JAX lacks of the internals below, one line each (empty: everything was found).
MISSING: list[str] = []


def jax_version() -> tuple[int, ...]:
    info = getattr(jax, "__version_info__", None)
    if info is not None:
        return tuple(int(v) for v in info[:3])
    return tuple(int("".join(c for c in part if c.isdigit()) or 0) for part in jax.__version__.split(".")[:3])


def version_tested() -> bool:
    """Whether the installed JAX lies in `TESTED_JAX`."""
    low, high = TESTED_JAX
    return low <= jax_version() <= high


try:
    from jax.extend import core as _jex_core
    from jax.extend.core import primitives as _jex_primitives
except ImportError as error:
    _jex_core = _jex_primitives = None
    MISSING.append(f"jax.extend.core ({error})")

Primitive = getattr(_jex_core, "Primitive", None)
Literal = getattr(_jex_core, "Literal", None)
for _name, _value in (("jax.extend.core.Primitive", Primitive), ("jax.extend.core.Literal", Literal)):
    if _value is None and _jex_core is not None:
        MISSING.append(_name)


def _primitive_modules():
    modules = [m for m in (_jex_primitives, lax) if m is not None]
    try:  # primitives that jax.lax does not export (stack, unstack, tile, mulhi)
        from jax._src.lax import lax as src_lax
        modules.append(src_lax)
    except ImportError:
        pass
    return modules


_MODULES = _primitive_modules()


def primitive(name: str):
    """The primitive object `<name>_p` of this JAX, or None."""
    if Primitive is None:
        return None
    for module in _MODULES:
        prim = getattr(module, name + "_p", None)
        if isinstance(prim, Primitive):
            return prim
    return None


def bind(prim, params, operands):
    """prim.bind with the parameters as `jax.core.eval_jaxpr` passes them (call primitives turn
    their jaxpr parameters into functions; older JAX returns those as a separate list)."""
    bind_params = prim.get_bind_params(params)
    if isinstance(bind_params, tuple):
        subfuns, bind_params = bind_params
        return prim.bind(*subfuns, *operands, **bind_params)
    return prim.bind(*operands, **bind_params)


def identity_primitive(name: str):
    """A primitive that returns its operands (any number, multiple results): the identity in
    evaluation, lowering and batching; its derivative passes the tangents through unchanged (the
    primitive is not on the tangent path). None, recorded in `MISSING`, where this JAX lacks the
    registration tables."""
    try:
        from jax.interpreters import ad, batching, mlir

        prim = Primitive(name)
        prim.multiple_results = True
        prim.def_impl(lambda *xs: list(xs))
        prim.def_abstract_eval(lambda *avals: list(avals))
        mlir.register_lowering(prim, lambda ctx, *xs: list(xs))
        batching.primitive_batchers[prim] = lambda args, dims: (prim.bind(*args), list(dims))

        def jvp(primals, tangents):
            tangents = [ad.instantiate_zeros(t) for t in tangents]
            return prim.bind(*primals), tangents

        ad.primitive_jvps[prim] = jvp
    except (ImportError, AttributeError, TypeError) as error:
        MISSING.append(f"a primitive of the package's own ({name}): {type(error).__name__}: {error}")
        return None
    return prim


def trace_platform() -> str:
    """The platform ('cpu', 'gpu', 'tpu', ...) of the program being traced: the default device in
    effect (`jax.default_device`), else the default backend."""
    device = getattr(jax.config, "jax_default_device", None)
    if device is not None:
        platform = device if isinstance(device, str) else getattr(device, "platform", None)
        if platform:
            return str(platform).split(":")[0].lower()
    return jax.default_backend()
