"""The sampler contract, run on every entry of `registry.ENTRIES` (every exported sampler, at its
hard cases):

- normalization: ∫ pdf dμ = 1 within 1e-6, by the domain's float64 quadrature;
- chi-square: samples against the density (one family at false-failure rate 1e-6, see registry);
- inverse: inverse(warp(u)) = u, and the density is the reciprocal of the warp's Jacobian,
  |p(T(u)) sqrt(det JᵀJ) - 1| small, for every warp that is a bijection;
- samples lie in the support, with the density `pdf` gives them;
- values, densities and their forward- and reverse-mode derivatives (in the parameters, in u and
  in x) finite at the hard u in {0, 0.5, 1 - 2^-24}, in float32 and float64.

Each check names the entry it ran on; the family files keep what is particular to a sampler
(its constructors, errors, closed forms, and a wrong sampler that the chi-square test rejects).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import domains
from jaxsample.testing.sampler_checks import chi2_test, inverse_error, jacobian_error, normalization

import registry
from registry import CHI2_CASES, ENTRIES, cast_params, edge_uniforms

ENTRY_IDS = [entry.name for entry in ENTRIES]


def _case_id(case) -> str:
    def short(value):
        if isinstance(value, js.Sampler):
            return type(value).__name__
        array = np.asarray(value)
        return f"{array.item():g}" if array.size == 1 else f"{array.shape}"
    parts = [short(p) for p in case.params if not isinstance(p, (tuple, list)) or len(p) <= 3]
    return ",".join(parts) + ("-x64" if case.x64 else "")


def _precision(case, dtype="float32"):
    """(x64 flag, dtype) a case is checked in."""
    x64 = case.x64 or dtype == "float64"
    return x64, jnp.float64 if x64 else jnp.float32


def test_every_exported_sampler_is_in_the_registry():
    exported = {name for name in js.__all__ if isinstance(getattr(js, name), type)
                and issubclass(getattr(js, name), js.Sampler) and getattr(js, name) is not js.Sampler}
    listed = {type(entry.build(case)).__name__ for entry in ENTRIES for case in entry.cases if not case.x64}
    assert exported - listed == set(), f"exported samplers missing from tests/samplers/registry.py: {exported - listed}"
    assert listed - exported == set(), f"registry entries that jaxsample does not export: {listed - exported}"


@pytest.mark.parametrize("entry", ENTRIES, ids=ENTRY_IDS)
def test_normalization_within_1e_6(entry):
    for case in entry.cases:
        x64, dtype = _precision(case)
        with jax.enable_x64(x64):
            total = normalization(entry.build(case, dtype))
        assert abs(total - 1.0) < 1e-6, (entry.name, _case_id(case), total)


CHI2_ENTRIES = [entry for entry in ENTRIES if any(owner is entry for owner, _ in CHI2_CASES)]


@pytest.mark.parametrize("entry", CHI2_ENTRIES, ids=[e.name for e in CHI2_ENTRIES])
def test_chi_square_goodness_of_fit(entry):
    """Each case of the entry is one test of the family (its key: the case's index in CHI2_CASES);
    the cases of an entry run together, so that one worker compiles their sampling program once.
    FFR 1e-6 for the family (N_CHI2_TESTS = 94 cases over 45 entries, 1.1e-8 each)."""
    failed = []
    for index, (owner, case) in enumerate(CHI2_CASES):
        if owner is not entry:
            continue
        x64, dtype = _precision(case)
        with jax.enable_x64(x64):
            result = chi2_test(entry.build(case, dtype), jax.random.fold_in(jax.random.key(20261201), index),
                               **registry.chi2_settings(entry.name))
        if not result.passed:
            failed.append((_case_id(case), result))
    assert not failed, (entry.name, failed)


def _uniforms(n, dims, margin, dtype, seed):
    """n points of [margin, 1 - margin]^dims (NumPy, so that drawing them compiles nothing)."""
    u = np.random.default_rng(seed).random((n, dims))
    return jnp.asarray(margin + (1.0 - 2.0 * margin) * u, dtype)


@jax.jit
def _round_trip(sampler, u):
    """Per point: the public check's max |inverse(warp(u)) - u| (periodic coordinates modulo 1),
    and the error of the first coordinate alone."""
    return inverse_error(sampler, u), jnp.abs(sampler.inverse(sampler.warp(u))[..., 0] - u[..., 0])


_jit_jacobian_error = jax.jit(jacobian_error)

INVERTIBLE = [entry for entry in ENTRIES if entry.inverse is not None]


def _invertible_cases(entry, tolerances):
    """(case, sampler, dtype, tolerance, dtype name) for each case with an inverse and each of
    float32 and float64 that has a tolerance; the body of the loop runs in that precision."""
    for case in (c for c in entry.cases if c.inverse):
        for dtype_name, tolerance in zip(("float32", "float64"), tolerances):
            if tolerance is None or (case.x64 and dtype_name == "float32"):
                continue
            x64, dtype = _precision(case, dtype_name)
            with jax.enable_x64(x64):
                yield case, entry.build(case, dtype), dtype, tolerance, dtype_name


@pytest.mark.parametrize("entry", INVERTIBLE, ids=[e.name for e in INVERTIBLE])
def test_inverse_round_trip(entry):
    check = entry.inverse
    for case, sampler, dtype, tolerance, dtype_name in _invertible_cases(entry, (check.tol32, check.tol64)):
        u = _uniforms(check.n, sampler.uniform_dims, check.margin, dtype, 3)
        if check.edges:
            u = jnp.concatenate([u, edge_uniforms(sampler.uniform_dims, dtype)])
        error, first = (np.asarray(e) for e in _round_trip(sampler, u))
        # Where u₀ = 0 is a pole of a periodic coordinate (sin θ = 0, r = 0) the azimuth is not
        # recoverable: the warp is a bijection only off that set of measure zero, so there only
        # the first coordinate is compared.
        pole = (np.asarray(u[:, 0]) == 0) & bool(sampler.periodic_dims)
        worst = float(np.max(np.where(pole, first, error)))
        assert worst < tolerance, (entry.name, _case_id(case), dtype_name, worst)


@pytest.mark.parametrize("entry", INVERTIBLE, ids=[e.name for e in INVERTIBLE])
def test_density_is_one_over_the_jacobian_of_the_warp(entry):
    check = entry.inverse
    for case, sampler, dtype, tolerance, dtype_name in _invertible_cases(entry, (check.jacobian32, check.jacobian64)):
        # Away from the ends, where p -> 0 and J -> inf (the horizon).
        u = _uniforms(check.n, sampler.uniform_dims, check.jacobian_margin, dtype, 4)
        worst = float(np.max(np.asarray(_jit_jacobian_error(sampler, u))))
        assert worst < tolerance, (entry.name, _case_id(case), dtype_name, worst)


@jax.jit
def _samples_and_densities(sampler, u):
    x, p = sampler.warp_with_pdf(u)
    return x, p, sampler.pdf(x), sampler.log_pdf(x)


@pytest.mark.parametrize("entry", ENTRIES, ids=ENTRY_IDS)
def test_samples_lie_in_the_support_with_the_stated_density(entry):
    """20 000 warped points (the chi-square test checks those of `sample`): inside the domain, with
    a positive density, and `pdf` and `log_pdf` there agree with the density `warp_with_pdf` gives."""
    for number, case in enumerate(entry.cases):
        if not case.samples:
            continue
        x64, dtype = _precision(case)
        with jax.enable_x64(x64):
            sampler = entry.build(case, dtype)
            x, p, pdf, log_pdf = (np.asarray(a) for a in _samples_and_densities(
                sampler, _uniforms(20_000, sampler.uniform_dims, 0.0, dtype, number)))
        assert x.shape == (20_000,) + tuple(sampler.event_shape), (entry.name, x.shape)
        assert x.dtype == (dtype if np.issubdtype(x.dtype, np.floating) else np.int32), (entry.name, x.dtype)
        assert np.all(domains.contains(sampler.domain(), x)), (entry.name, _case_id(case))
        assert np.all(p > 0), (entry.name, _case_id(case))
        rtol = entry.pdf_rtol64 if x64 else entry.pdf_rtol
        np.testing.assert_allclose(pdf, p, rtol=rtol, err_msg=entry.name)
        np.testing.assert_allclose(log_pdf, np.log(p), atol=2 * rtol, err_msg=entry.name)


# ---------------------------------------------------------------------------------------------
# Finite values and derivatives at the hard cases
# ---------------------------------------------------------------------------------------------


def _integrand(x):
    """A fixed integrand touching every component of a sample (integer samples too)."""
    x = jnp.ravel(x).astype(jnp.result_type(float))
    return 1.5 + jnp.sum(x * jnp.linspace(0.3, 0.9, x.size, dtype=x.dtype))


def _split(params):
    """Floating leaves (differentiated), other array leaves (traced) and Python scalars (static)."""
    leaves, treedef = jax.tree_util.tree_flatten(params)
    kinds = tuple("float" if isinstance(leaf, (jax.Array, np.ndarray)) and jnp.issubdtype(leaf.dtype, jnp.inexact)
                  else "array" if isinstance(leaf, (jax.Array, np.ndarray)) else "static" for leaf in leaves)
    floats = [leaf for leaf, kind in zip(leaves, kinds) if kind == "float"]
    arrays = [leaf for leaf, kind in zip(leaves, kinds) if kind == "array"]
    statics = tuple(leaf for leaf, kind in zip(leaves, kinds) if kind == "static")
    return (treedef, kinds, statics), floats, arrays


def _join(layout, floats, arrays):
    treedef, kinds, statics = layout
    sources = {"float": iter(floats), "array": iter(arrays), "static": iter(statics)}
    return jax.tree_util.tree_unflatten(treedef, [next(sources[kind]) for kind in kinds])


def _along(tree):
    """A direction with every component nonzero: a NaN or inf in any partial derivative shows in
    the derivative along it, so one forward pass finds what the whole Jacobian would."""
    return jax.tree_util.tree_map(lambda a: jnp.full_like(a, 0.7), tree)


# Compilation, not execution, is the cost of these checks (one program per entry and dtype,
# whatever the parameter values). XLA's backend optimisation level may change a last bit (by
# contracting a multiply and an add), never whether a value is finite, which is all they ask; at
# level 0 the programs compile in about two thirds of the time.
@functools.partial(jax.jit, static_argnums=(0, 1), compiler_options={"xla_backend_optimization_level": 0})
def _all_derivatives(make, layout, floats, arrays, u, points):
    """Values and their forward- and reverse-mode derivatives, in the parameters and in u (or x).

    At the rows of u: warp_with_pdf's sample and density, pdf and log_pdf re-evaluated at the
    warped sample, and the estimator's value f(x)/p(x) (attached). At the fixed points: pdf and
    log_pdf. Forward mode gives the derivative of each along a direction with no zero component;
    reverse mode the gradient of their weighted sum (every term with a nonzero weight). Rows are
    independent, so the derivatives in u are per row, and a non-finite derivative in the
    parameters at any row shows in the sum over rows. Integer points (a finite set) are
    differentiated in the parameters only.
    """

    def build(floats):
        return make(*_join(layout, floats, arrays))

    def at_samples(floats, u):
        s = build(floats)
        x, p = s.warp_with_pdf(u)
        x_again = s.warp(u)
        return (js.estimators.integrand_values(_integrand, s, u), x, p, s.pdf(x_again), s.log_pdf(x_again))

    def at_points(floats, x):
        s = build(floats)
        return s.pdf(x), s.log_pdf(x)

    def weights(value, x, p, pdf, log_pdf):
        """The cotangent of sum(f/p) + 1e-3 (sum(x) + sum(p) + sum(pdf) + sum(finite log_pdf)):
        a nonzero weight on every term (an integer sample has no derivative and is left out)."""
        inexact = jnp.issubdtype(x.dtype, jnp.inexact)
        return (jnp.ones_like(value),) + ((jnp.full_like(x, 1e-3),) if inexact else ()) + (
            jnp.full_like(p, 1e-3), jnp.full_like(pdf, 1e-3), 1e-3 * jnp.isfinite(log_pdf).astype(log_pdf.dtype))

    def without_integer_sample(linear, x):
        """The linear map without its integer-sample output (transposable: float -> float)."""
        if jnp.issubdtype(x.dtype, jnp.inexact):
            return linear
        return lambda *tangents: (lambda out: (out[0],) + tuple(out[2:]))(linear(*tangents))

    # One linearization per function gives both modes: forward mode is the linear map applied to
    # the direction, reverse mode its transpose applied to the weights (what jax.grad does), so the
    # function and its derivative rules are traced once, not once per mode.
    values, linear = jax.linearize(at_samples, floats, u)
    out = {"f(x)/p(x), x, p, pdf(x), log_pdf(x) at u": values,
           "their derivatives along (params, u)": linear(*_along((floats, u))),
           "gradient of their sum in (params, u)": jax.linear_transpose(
               without_integer_sample(linear, values[1]), floats, u)(weights(*values))}
    if jnp.issubdtype(points.dtype, jnp.inexact):
        densities, linear = jax.linearize(at_points, floats, points)
        out["densities"], out["their derivatives along (params, x)"] = densities, linear(*_along((floats, points)))
        out["gradient of their sum in (params, x)"] = jax.linear_transpose(linear, floats, points)(
            (jnp.ones_like(densities[0]), jnp.isfinite(densities[1]).astype(densities[1].dtype)))
    else:
        densities, linear = jax.linearize(lambda f: at_points(f, points), floats)
        out["densities"], out["their derivatives along params"] = densities, linear(_along(floats))
        out["gradient of their sum in params"] = jax.linear_transpose(linear, floats)(
            (jnp.ones_like(densities[0]), jnp.isfinite(densities[1]).astype(densities[1].dtype)))
    return out


GRADIENT_CASES = [(entry, dtype) for entry in ENTRIES for dtype in ("float32", "float64")
                  if (dtype == "float32" or entry.gradients64)
                  and any(c.gradients and (dtype == "float64" or not c.x64) for c in entry.cases)]


@pytest.mark.parametrize("entry,dtype", GRADIENT_CASES, ids=[f"{e.name}-{d}" for e, d in GRADIENT_CASES])
def test_values_and_derivatives_are_finite_at_the_hard_cases(entry, dtype):
    for case in entry.cases:
        if not case.gradients or (case.x64 and dtype == "float32"):
            continue
        x64, dt = _precision(case, dtype)
        with jax.enable_x64(x64):
            params = cast_params(case.params, dt)
            layout, floats, arrays = _split(params)
            dims = entry.make(*params).uniform_dims
            points = np.asarray(entry.points)
            points = jnp.asarray(points, dt if np.issubdtype(points.dtype, np.floating) else jnp.int32)
            out = _all_derivatives(entry.make, layout, floats, arrays, edge_uniforms(dims, dt), points)
        where = (entry.name, _case_id(case), dtype)
        pdf_at_points, log_pdf_at_points = (np.asarray(a) for a in out.pop("densities"))
        assert np.all(np.isfinite(pdf_at_points)), (*where, "pdf at the fixed points", pdf_at_points)
        # log_pdf is -inf outside the support, never NaN.
        assert not np.any(np.isnan(log_pdf_at_points)), (*where, "log_pdf at the fixed points", log_pdf_at_points)
        value, x, pdf, pdf_again, log_pdf_again = (
            np.asarray(a) for a in out.pop("f(x)/p(x), x, p, pdf(x), log_pdf(x) at u"))
        assert not np.any(np.isnan(log_pdf_again)), (*where, "log_pdf at the samples", log_pdf_again)
        for name, leaf in (("f(x)/p(x)", value), ("x", x), ("p", pdf), ("pdf(x)", pdf_again)):
            assert np.all(np.isfinite(leaf)), (*where, name, leaf)
        for name, tree in out.items():
            for leaf in jax.tree_util.tree_leaves(tree):
                leaf = np.asarray(leaf)
                if np.issubdtype(leaf.dtype, np.inexact):
                    assert np.all(np.isfinite(leaf)), (*where, name, leaf)
        if entry.positive_at_edges:
            assert np.all(pdf > 0) and np.all(pdf_again > 0), (*where, pdf, pdf_again)
        else:  # a sample on the horizon may have density 0
            assert np.all(pdf >= 0) and np.all(pdf_again >= 0), (*where, pdf, pdf_again)
