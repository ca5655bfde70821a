"""`estimate_guaranteed`: the transforms it reads, the ordering of the coefficients, the bound's
coverage on integrands in the cone, the necessary conditions outside it, and its worded errors.

The coverage tests are not statistical: for an integrand in the cone the bound holds for every
shift, so a single violation is a bug, not chance. Measured margins over 16 keys at atol 1e-3 and
1e-5 (`benchmarks/results/guaranteed-rule-cpu-2core-2026-12-05.md`): the largest error / bound is
0.010 (lattice) and 0.042 (Sobol') on the 3-d exponential, 0.025 and 0.37 on the sphere integrand.
"""

import dataclasses
import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import uniforms as U
from jaxsample.estimators import guaranteed as G

BOX3 = js.UniformBox(jnp.zeros(3), jnp.ones(3))
EXP3 = (np.e - 1.0) ** 3


def _exp3(x):
    return jnp.prod(jnp.exp(x))


def _rev(i: int, m: int) -> int:
    return int(format(i, f"0{m}b")[::-1], 2)


def test_lattice_coefficients_are_the_dft_over_the_rule_in_natural_order():
    """Values given in radical-inverse order (point i is lattice point k = rev_m(i)); the transform
    is (1/N) sum_k values[rev_m(k)] exp(-2 pi i k kappa / N), checked against the definition."""
    m, n = 5, 32
    values = np.random.default_rng(0).normal(size=(n, 3))
    natural = np.array([values[_rev(k, m)] for k in range(n)])
    kappa = np.arange(n)
    direct = np.exp(-2j * np.pi * np.outer(kappa, np.arange(n)) / n) @ natural / n
    np.testing.assert_allclose(G.lattice_coefficients(values), direct, atol=1e-12)


def test_a_fourier_mode_on_the_lattice_is_one_coefficient_at_h_dot_z():
    """cos(2 pi h.x) on the shifted lattice (no tent) has |y~| = 1/2 at kappa = +-h.z mod N and 0
    elsewhere: the points, their order and the transform agree with the rule's structure."""
    m, dims, h = 8, 3, np.array([1, 2, -1])
    source = U.Lattice(replicates=2, tent=False)
    points = np.asarray(source.block(U.seed_from_key(jax.random.key(3)), 0, 2 << m, dims, jnp.float32))
    x = points[0::2].astype(np.float64)                  # replicate 0, in its own order
    values = np.cos(2 * np.pi * x @ h)[:, None]
    magnitude = np.abs(G.lattice_coefficients(values))[:, 0]
    z = U.lattice_generating_vector(dims).astype(np.int64)
    at = {int(h @ z) % (1 << m), int(-h @ z) % (1 << m)}
    for kappa in range(1 << m):
        assert magnitude[kappa] == pytest.approx(0.5 if kappa in at else 0.0, abs=1e-5), kappa


def test_net_coefficients_are_the_walsh_hadamard_transform():
    n = 32
    values = np.random.default_rng(1).normal(size=(n, 2))
    signs = np.array([[(-1) ** bin(k & i).count("1") for i in range(n)] for k in range(n)])
    np.testing.assert_allclose(G.net_coefficients(values), signs @ values / n, atol=1e-12)


def test_a_walsh_function_on_the_scrambled_net_is_one_coefficient():
    """(-1)^(first digit of x_1) on a digitally shifted LMS Sobol' net: the first digit of x_1 is
    bit 0 of the index xor a shift bit, so the only coefficient is kappa = 1, of size 1."""
    m = 7
    source = U.Sobol(replicates=2, scramble="lms")
    points = np.asarray(source.block(U.seed_from_key(jax.random.key(5)), 0, 2 << m, 2, jnp.float32))
    values = np.where(points[0::2, 0] < 0.5, 1.0, -1.0)[:, None]
    magnitude = np.abs(G.net_coefficients(values))[:, 0]
    assert magnitude[1] == pytest.approx(1.0)
    assert np.all(np.delete(magnitude, 1) < 1e-12)


def test_reorder_swaps_aliased_pairs_where_the_later_is_larger():
    """A hand-worked case with N = 8. Level 2 compares positions (1, 5), (2, 6), (3, 7): |y~| = 1 vs
    3 and 2 vs 8 swap, 5 vs 4 does not -> [0, 5, 2, 7, 4, 1, 6, 3]. Level 1 compares (1, 3):
    |y~_5| = 3 vs |y~_7| = 8 swap, and so do their aliases (5, 7) -> [0, 7, 2, 5, 4, 3, 6, 1]."""
    magnitude = np.array([9, 1, 5, 2, 0, 3, 4, 8], dtype=float)[:, None]
    order = G.reorder(np.arange(8)[:, None], magnitude, [2, 1])
    assert list(order[:, 0]) == [0, 7, 2, 5, 4, 3, 6, 1]


# ---- a second implementation, written as loops, to hold the vectorized one to ----------------

def _loop_rule(coefficients_by_m: dict, m_min: int, lag: int = 4):
    """One column (one replicate, one component) of the rule as plain loops: the ordering kept as
    a list and swapped pair by pair, the bound fudge(m) S~(m - lag) and the cone's running
    bounds, at every m in `coefficients_by_m`. Returns (bounds, holds) per m."""
    fudge = lambda k: 5.0 * 2.0 ** -k
    omega_hat = lambda k: fudge(k) / ((1 + fudge(lag)) * 2.0 ** -lag)
    kappa, low, up, bounds, holds = None, {}, {}, [], []
    for m in sorted(coefficients_by_m):
        a, n = np.abs(coefficients_by_m[m]), 1 << m
        if kappa is None:
            kappa, levels = list(range(n)), range(m - 1, 0, -1)
        else:
            kappa, levels = kappa + [k + n // 2 for k in kappa], range(m - 1, max(m - lag, 1) - 1, -1)
        for level in levels:
            half = 1 << level
            for p in range(1, half):
                if a[kappa[p + half]] > a[kappa[p]]:
                    for q in range(p, n, 2 * half):
                        kappa[q], kappa[q + half] = kappa[q + half], kappa[q]

        def total(level):
            return sum(a[kappa[i]] for i in range(1 << (level - 1), 1 << level))

        bounds.append(fudge(m) * total(m - lag))
        for level in range(m_min - lag, m + 1):
            w = omega_hat(m - level) * 2.0 ** -(m - level)
            low[level] = max(low.get(level, -math.inf), total(level) / (1 + w))
            if w < 1:
                up[level] = min(up.get(level, math.inf), total(level) / (1 - w))
        holds.append(all(low[level] <= up.get(level, math.inf) for level in low))
    return bounds, holds


def test_the_orderings_and_bounds_equal_the_loops_on_tied_coefficients():
    """`_Cone.update` (every column at once) against `_loop_rule` (one column, loops) on synthetic
    coefficients for m = 6 .. 10 in 40 columns: magnitudes drawn from {0, 1, 2, 3} (ties, which
    are never swapped) and from an exponential law (no ties, so that the first ordering's lowest
    level, which compares the largest survivors of all the others, decides something)."""
    rng = np.random.default_rng(3)
    m_min, m_max, width = 6, 10, 40
    for draw in (lambda shape: rng.integers(0, 4, size=shape).astype(float), lambda shape: rng.exponential(size=shape)):
        coefficients = {m: draw((1 << m, width)) for m in range(m_min, m_max + 1)}
        cone = G._Cone(m_min, m_max, width)
        got = [cone.update(coefficients[m], m) for m in range(m_min, m_max + 1)]
        for column in range(width):
            bounds, holds = _loop_rule({m: coefficients[m][:, column] for m in coefficients}, m_min)
            np.testing.assert_allclose([b[column] for b, _ in got], bounds, rtol=1e-12)
            assert [bool(h[column]) for _, h in got] == holds


def _loop_estimate(f, sampler, source, transform, key, m_min, m_max, atol):
    """The whole estimator from the source's points (warped here, f/p in float64), replicate by
    replicate and column by column with `_loop_rule`: (m, mean, bound, in_cone) where it stops."""
    replicates, n = source.replicates, source.replicates << m_max
    u = source.block(U.seed_from_key(key), 0, n, sampler.uniform_dims, jnp.float32)
    x, pdf = sampler.warp_with_pdf(u)
    y = np.asarray(jax.vmap(f)(x), dtype=np.float64).reshape(n, -1) / np.asarray(pdf, np.float64)[:, None]
    columns, agreed = {}, True
    for m in range(m_min, m_max + 1):
        part = y[: replicates << m].reshape(1 << m, replicates, -1)
        means, bounds, holds = part.mean(axis=0), np.zeros(part.shape[1:]), True
        for (r, c), _ in np.ndenumerate(bounds):
            columns.setdefault((r, c), {})[m] = transform(part[:, r, c][:, None])[:, 0]
            column_bounds, column_holds = _loop_rule(columns[(r, c)], m_min)
            bounds[r, c], holds = column_bounds[-1], holds and column_holds[-1]
        agreed = agreed and bool(np.all(np.max(means - bounds, axis=0) <= np.min(means + bounds, axis=0)))
        if np.all(bounds.mean(axis=0) <= atol) or m == m_max:
            return m, means.mean(axis=0), bounds.mean(axis=0), holds and agreed


BOX1, BOX2 = js.UniformBox(jnp.zeros(1), jnp.ones(1)), js.UniformBox(jnp.zeros(2), jnp.ones(2))


def _spike(x):
    return jnp.exp(-jnp.sum((x - 0.3) ** 2) / (2 * 0.05 ** 2))


@pytest.mark.parametrize("case", ["sobol: smooth and step", "lattice: 3-d exponential",
                                  "lattice: spike, early disagreement"])
def test_matches_the_rule_written_as_loops(case):
    """The vectorized rule (orderings of every column at once, the replicates' bounds averaged, the
    cone checked in every column and the replicates compared at every m) equals a loop-by-loop
    transcription on the same values: points, bound (to the float32 rounding of the mean that
    the returned bound includes), in_cone. The three cases: a Sobol' vector integrand whose
    second component (a step) fails the cone from m = 12 while the first does not; a smooth
    lattice case; a spike whose replicates disagree only at the first m (and agree at the last)."""
    (sampler, f, uniforms, source, transform), key, m_min, m_max, atol = {
        "sobol: smooth and step": ((BOX1, lambda x: jnp.stack([jnp.exp(x[0]), (x[0] < 0.3).astype(jnp.float32)]),
                                    "sobol", U.Sobol(replicates=2, scramble="lms"), G.net_coefficients),
                                   0, 8, 13, 1e-5),
        "lattice: 3-d exponential": ((BOX3, _exp3, "lattice", U.Lattice(replicates=2), G.lattice_coefficients),
                                     1, 8, 14, 1e-4),
        "lattice: spike, early disagreement": ((BOX2, _spike, "lattice", U.Lattice(replicates=2),
                                               G.lattice_coefficients), 2, 6, 7, 1e-9),
    }[case]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", js.estimators.UnreliableEstimateWarning)
        est = js.estimate_guaranteed(f, sampler, jax.random.key(key), max_n=2 << m_max, min_n=2 << m_min, atol=atol,
                                     uniforms=uniforms)
    m, mean, bound, in_cone = _loop_estimate(f, sampler, source, transform, jax.random.key(key), m_min, m_max, atol)
    assert int(est.n_used) == 2 << m
    np.testing.assert_allclose(np.asarray(est.mean), mean, rtol=1e-6)
    rounding = np.spacing(np.abs(mean).astype(np.float32)).astype(np.float64)
    assert np.all(np.asarray(est.error_bound) >= bound * (1 - 1e-6))
    assert np.all(np.asarray(est.error_bound) <= bound * (1 + 1e-6) + rounding)
    assert bool(est.in_cone) == in_cone
    assert in_cone == (case == "lattice: 3-d exponential")


def test_mean_and_stderr_are_those_of_estimate_on_the_same_points():
    """The engine's `estimate` over the same n_used points of the same source is an independent
    path to the mean and to the replicate stderr (std of the R replicate means, ddof 1, / sqrt R).
    In float64: in float32 the engine floors its stderr at a few ulps of the mean, which the
    lattice's replicate spread here is below."""
    source = U.Lattice(replicates=4)
    with jax.enable_x64(True):
        box = js.UniformBox(jnp.zeros(3, jnp.float64), jnp.ones(3, jnp.float64))
        est = js.estimate_guaranteed(_exp3, box, jax.random.key(7), max_n=4 << 16, atol=1e-4, uniforms=source,
                                     dtype=jnp.float64)
        plain = js.estimate(_exp3, box, jax.random.key(7), int(est.n_used), uniforms=source, dtype=jnp.float64)
        assert est.mean.dtype == jnp.float64
        np.testing.assert_allclose(float(est.mean), float(plain.mean), rtol=1e-12)
        np.testing.assert_allclose(float(est.stderr), float(plain.stderr), rtol=1e-6)


def test_tolerance_is_met_only_below_the_integrals_smallest_size():
    """bound <= max(atol, rtol (|mean| - bound)): at |mean| = 1, bound 0.1, rtol 0.1 the integral
    may be as small as 0.9, whose tolerance 0.09 the bound exceeds."""
    assert not G.tolerance_met(np.array([1.0]), np.array([0.1]), 0.0, 0.1)
    assert G.tolerance_met(np.array([1.0]), np.array([0.09]), 0.0, 0.1)
    assert G.tolerance_met(np.array([1.0, 5.0]), np.array([0.1, 0.1]), 0.1, 0.0)
    assert not G.tolerance_met(np.array([1.0, 5.0]), np.array([0.1, 0.2]), 0.1, 0.0)


def test_rounding_the_mean_widens_the_bound():
    mean64 = np.array([1.0 + 1e-8, -3.0])
    mean, bound = G.rounded(mean64, np.array([0.0, 1e-9]), np.float32)
    assert mean.dtype == np.float32 and bound.dtype == np.float32
    assert np.all(np.abs(mean64 - mean.astype(np.float64)) <= bound.astype(np.float64))
    assert float(bound[1]) >= 1e-9


def test_float32_results_keep_their_guarantee_at_a_tight_tolerance():
    """At atol 1e-6 the float32 mean's own rounding (about 1e-7 here) is a real part of its error:
    the returned bound includes it (without it the bound here is about a tenth of the error)."""
    exact = 2 * np.pi * (np.e - 1 / np.e)
    est = js.estimate_guaranteed(lambda w: jnp.exp(w[2]), js.UniformSphere(), jax.random.key(4), max_n=1 << 20,
                                 atol=1e-6, uniforms="sobol")
    assert abs(float(est.mean) - exact) <= float(est.error_bound)


@dataclasses.dataclass
class _Scaled:
    scale: float

    def __call__(self, x):
        return self.scale * x[0]


def test_the_compiled_program_is_reused_per_integrand_object_only():
    """An unhashable callable works; two callables that are equal as values but distinct objects get
    their own programs (never a stale one)."""
    one = js.estimate_guaranteed(_Scaled(1.0), BOX3, jax.random.key(0), max_n=1 << 14, atol=1e-3)
    three = js.estimate_guaranteed(_Scaled(3.0), BOX3, jax.random.key(0), max_n=1 << 14, atol=1e-3)
    assert float(one.mean) == pytest.approx(0.5, abs=1e-3) and float(three.mean) == pytest.approx(1.5, abs=3e-3)


@pytest.mark.parametrize("uniforms", ["lattice", "sobol"])
def test_the_bound_covers_the_error_of_smooth_integrands_for_every_key(uniforms):
    """The 3-d exponential (integral (e - 1)^3) and exp(z) over the sphere (2 pi (e - 1/e)): for
    each of 12 keys the error is within the bound, the bound within the tolerance, and the
    necessary conditions hold. Not statistical: one miss is a bug (module docstring)."""
    cases = [(BOX3, _exp3, EXP3), (js.UniformSphere(), lambda x: jnp.exp(x[2]), 2 * np.pi * (np.e - 1 / np.e))]
    for sampler, f, exact in cases:
        for k in range(12):
            est = js.estimate_guaranteed(f, sampler, jax.random.key(k), max_n=1 << 20, atol=1e-4, uniforms=uniforms)
            assert bool(est.converged) and bool(est.in_cone)
            assert abs(float(est.mean) - exact) <= float(est.error_bound) <= 1e-4
            low, high = est.interval()
            assert float(low) <= exact <= float(high)


def test_tighter_tolerances_use_more_points_and_a_relative_tolerance_scales_with_the_integral():
    used = [int(js.estimate_guaranteed(_exp3, BOX3, jax.random.key(0), max_n=1 << 20, atol=tol).n_used)
            for tol in (1e-2, 1e-4)]
    assert used[0] < used[1]
    rel = js.estimate_guaranteed(_exp3, BOX3, jax.random.key(0), max_n=1 << 20, rtol=1e-4)
    assert float(rel.error_bound) <= 1e-4 * (abs(float(rel.mean)) - float(rel.error_bound))
    assert abs(float(rel.mean) - EXP3) <= 1e-4 * EXP3


def test_a_budget_too_small_is_reported_not_hidden():
    est = js.estimate_guaranteed(_exp3, BOX3, jax.random.key(0), max_n=2 << 10, atol=1e-9)
    assert not bool(est.converged) and int(est.n_used) == 2 << 10
    assert float(est.error_bound) > 1e-9


def test_outside_the_cone_the_result_says_so_and_warns():
    """A step at 0.3 on a Sobol' net (its Walsh coefficients do not decay in order) and a spike of
    width 0.01 on the lattice (the replicates' intervals disagree): in_cone is False for every key,
    with an UnreliableEstimateWarning; a smooth integrand gives neither."""
    step = (js.UniformBox(jnp.zeros(1), jnp.ones(1)), lambda x: (x[0] < 0.3).astype(jnp.float32), "sobol")
    spike = (js.UniformBox(jnp.zeros(2), jnp.ones(2)),
             lambda x: jnp.exp(-jnp.sum((x - 0.3) ** 2) / (2 * 0.01 ** 2)), "lattice")
    for sampler, f, uniforms in (step, spike):
        for k in range(4):
            with pytest.warns(js.estimators.UnreliableEstimateWarning, match="cone"):
                est = js.estimate_guaranteed(f, sampler, jax.random.key(k), max_n=1 << 18, atol=1e-4, uniforms=uniforms)
            assert not bool(est.in_cone)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert bool(js.estimate_guaranteed(_exp3, BOX3, jax.random.key(0), max_n=1 << 18, atol=1e-3).in_cone)


def test_pytree_and_complex_values_get_a_bound_per_component():
    def f(x):
        return {"pair": jnp.stack([x[0], x[0] * x[1]]), "wave": jnp.exp(2j * jnp.pi * x[2] * 0.25)}

    est = js.estimate_guaranteed(f, BOX3, jax.random.key(1), max_n=1 << 18, atol=1e-4)
    wave = (np.exp(0.5j * np.pi) - 1) / (0.5j * np.pi)
    np.testing.assert_allclose(np.asarray(est["pair"].mean), [0.5, 0.25], atol=1e-4)
    assert est["pair"].error_bound.shape == (2,)
    assert abs(complex(est["wave"].mean) - wave) <= abs(complex(est["wave"].error_bound))
    assert bool(est["wave"].converged)


def test_a_source_with_more_replicates_averages_their_bounds():
    """Eight replicates: the bound (the mean of eight per-replicate bounds) still covers, and it
    needs at least the points two replicates need (each replicate's rule is smaller)."""
    est = js.estimate_guaranteed(_exp3, BOX3, jax.random.key(2), max_n=8 << 18, atol=1e-4,
                                 uniforms=U.Lattice(replicates=8))
    two = js.estimate_guaranteed(_exp3, BOX3, jax.random.key(2), max_n=2 << 18, atol=1e-4)
    assert est.replicates == 8 and bool(est.converged)
    assert abs(float(est.mean) - EXP3) <= float(est.error_bound) <= 1e-4
    assert int(est.n_used) >= int(two.n_used)


@pytest.mark.parametrize("kwargs, match", [
    (dict(uniforms="sobol", max_n=1 << 12), None),
    (dict(uniforms=U.Sobol(replicates=2), max_n=1 << 12), "scramble='lms'"),
    (dict(uniforms=U.Sobol(replicates=2, scramble="lms", padding=True), max_n=1 << 12), "padding"),
    (dict(uniforms="halton", max_n=1 << 12), "'uniforms'"),
    (dict(max_n=3 << 10), "'max_n' must be R 2"),
    (dict(max_n=1 << 12, min_n=2 << 3), "at least 2"),
    (dict(max_n=1 << 12, min_n=3 << 5), "'min_n' must be R 2"),
])
def test_worded_errors(kwargs, match):
    call = dict(atol=1e-3)
    call.update(kwargs)
    if match is None:
        js.estimate_guaranteed(_exp3, BOX3, jax.random.key(0), **call)
        return
    with pytest.raises(ValueError, match=match):
        js.estimate_guaranteed(_exp3, BOX3, jax.random.key(0), **call)


def test_no_tolerance_a_nan_integrand_a_batch_and_tracing_are_refused():
    key = jax.random.key(0)
    with pytest.raises(ValueError, match="'rtol' or 'atol'"):
        js.estimate_guaranteed(_exp3, BOX3, key, max_n=1 << 12)
    with pytest.raises(ValueError, match="non-finite"):
        js.estimate_guaranteed(lambda x: jnp.log(x[0] - 0.5), BOX3, key, max_n=1 << 12, atol=1e-3)
    with pytest.raises(ValueError, match="unbatched"):
        js.estimate_guaranteed(lambda x: x[2], js.UniformCone(jnp.array([0.1, 0.5])), key, max_n=1 << 12, atol=1e-3)
    with pytest.raises(TypeError, match="cannot run under jit"):
        jax.jit(lambda c: js.estimate_guaranteed(lambda x: x[2], js.UniformCone(c), key, max_n=1 << 12,
                                                 atol=1e-3).mean)(0.5)
    with pytest.raises(TypeError, match="closes over a value being traced"):
        jax.grad(lambda c: js.estimate_guaranteed(lambda x: c * x[0], BOX3, key, max_n=1 << 12, atol=1e-3).mean)(1.0)
    with pytest.raises(ValueError, match="'atol' must be a finite number"):
        js.estimate_guaranteed(_exp3, BOX3, key, max_n=1 << 12, atol=True)
    assert bool(js.estimate_guaranteed(_exp3, BOX3, jax.random.key(1), max_n=1 << 12, atol=np.float32(1e-2)).converged)
