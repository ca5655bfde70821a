"""The point sets against dimension study (`jaxsample/report/point_set_dims.py`): its integrands'
exact integrals, checked by arguments independent of the module, and a tiny run of the study."""

import math
from fractions import Fraction

import jax.numpy as jnp
import numpy as np

from jaxsample.report import point_set_dims as P


def test_the_smooth_product_integrates_to_one_by_gauss_legendre_in_float64():
    # The integral of f over x_i with the other coordinates fixed at 0.25 is (the 1-D integral of
    # factor i) x (the other factors at 0.25, restated here from the docstring's formula); a
    # 40-point float64 Gauss-Legendre rule integrates the entire sine factor to ~1e-15, so the
    # ratio is the module's factor-i integral, which must be 1 for every i (their product, the
    # d-dimensional integral, then is 1).
    nodes, weights = np.polynomial.legendre.leggauss(40)
    t, w = 0.5 * (nodes + 1.0), 0.5 * weights
    for d in (2, 5, 32):
        for i in range(d):
            x = np.full((t.size, d), 0.25)
            x[:, i] = t
            values = np.asarray(P.smooth_product(jnp.asarray(x, jnp.float32)), np.float64)
            # the other factors at x_j = 0.25: 1 + ((π/2) sin(π/4) − 1)/j
            rest = np.prod([1.0 + (0.5 * np.pi * np.sin(0.25 * np.pi) - 1.0) / (j + 1) for j in range(d) if j != i])
            factor = float(np.sum(w * values)) / rest
            assert abs(factor - 1.0) < 1e-5, (d, i, factor)  # f is evaluated in float32
        assert abs(P.exact_integral("smooth", d) - 1.0) == 0.0


def test_the_indicator_integral_matches_closed_forms_and_a_numpy_monte_carlo():
    # d = 2: the triangle x + y < 3/4 has area (3/4)^2 / 2 = 9/32.
    assert P.indicator_threshold(2) == Fraction(3, 4)
    assert P.irwin_hall_cdf(Fraction(3, 4), 2) == Fraction(9, 32)
    # d = 1: P(U < t) = t; and the CDF at d/2 is 1/2 by symmetry, for any d.
    assert P.irwin_hall_cdf(Fraction(2, 7), 1) == Fraction(2, 7)
    for d in (3, 8, 32):
        assert P.irwin_hall_cdf(Fraction(d, 2), d) == Fraction(1, 2)
    # Every d of the study: a NumPy Monte Carlo (seeded; independent of JAX and of the formula) of
    # the module's own indicator, within 5 sigma: a false failure has probability about 6e-7 per d.
    rng = np.random.default_rng(20261203)
    n = 200_000
    for d in P.DIMS:
        x = rng.random((n, d), dtype=np.float32)
        hits = np.asarray(P.half_space_indicator(jnp.asarray(x)), np.float64)
        p = P.exact_integral("indicator", d)
        sigma = math.sqrt(p * (1 - p) / n)
        assert abs(hits.mean() - p) < 5 * sigma, (d, hits.mean(), p)
        assert 0.2 < p < 0.4, (d, p)  # the thresholds keep the probability away from 0 and 1


def test_a_tiny_study_has_its_columns_and_sobol_beats_random_on_the_smooth_product():
    ns, keys, n_time, repeats = P.study_sizes(tiny=True)
    sizes = ([2**k for k in range(4, 13, 2)], 64, n_time, repeats)
    rows = P.run_study(sizes=sizes, dims=(2,), sets=("random", "sobol"), integrands=("smooth",),
                       progress=lambda _: None)
    assert [(r["name"], r["d"], r["uniforms"]) for r in rows] == [("smooth", 2, "random"), ("smooth", 2, "sobol")]
    for r in rows:
        for key in ("slope", "slope_stderr", "ns_per_sample", "ns_per_point", "integrand_ns", "times", "extrapolated",
                    "extrapolated_seconds", "rmse", "target"):
            assert key in r, key
        assert r["ns_per_point"] > 0 and r["integrand_ns"] > 0 and math.isfinite(r["slope"])
        assert math.isclose(r["ns_per_sample"], r["ns_per_point"] + r["integrand_ns"], rel_tol=1e-9)
    by = {r["uniforms"]: r for r in rows}
    # Random's slope is -1/2 and scrambled Sobol' on a smooth 2-D product falls faster (n^-1.5,
    # Owen 1997; fitted over n = 2^8..2^12 about -1.4). Over 64 keys the slope has se ~ 1/sqrt(2*64)
    # / 1.96 ≈ 0.045. The study's keys are fixed (seeds 1200, 1201: `run_study`), so the outcome is
    # deterministic, not a draw; only a change of the point sets or of the seeds can move it. FFR for
    # fresh seeds about 1e-10 (simulated, 2000 seed pairs): random's slope had mean -0.500 and sd
    # 0.044, so (-0.8, -0.2) is 6.8 sd wide each side (1e-11), and random minus Sobol' less 0.5 had
    # mean 0.41 and sd 0.064, 6.3 sd above 0 (1e-10); none of the curves was cut by a floor. With 8
    # keys the same simulation fails 4.2 % of seed pairs.
    assert by["sobol"]["slope"] < by["random"]["slope"] - 0.5, (by["sobol"]["slope"], by["random"]["slope"])
    assert -0.8 < by["random"]["slope"] < -0.2, by["random"]["slope"]
    text = P.markdown_table(rows)
    assert "| smooth | 2 | 0.001 |" in text and "sobol slope" in text
    assert "smooth, d = 2: fastest" in P.fastest_lines(rows)
    records = P.csv_records(rows)
    assert {r["point_set"] for r in records} == {"random", "sobol"}
    # The report's section is built from these rows: heading, what was measured, the table.
    import jaxsample.report as R
    section = "".join(R.point_set_dims_section(rows))
    assert section.startswith("## Point sets against dimension") and text in section
    assert "RMSE over 64 keys at n = 16..4096" in section and "d = 2:" in section
