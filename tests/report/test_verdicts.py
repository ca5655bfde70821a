"""The report's verdict machinery on synthetic curves with known answers (no study run: pure functions).

Every curve here is deterministic (no random draws), so no test has a false-failure rate; the
statistical content is in the tolerances under test (1/sqrt(2k) per RMSE), checked against the
values they must take.
"""

import math

import numpy as np
import pytest

from jaxsample.report import convergence as C
from jaxsample.report import verdicts as V

K = 32                                   # keys: an RMSE carries 1/sqrt(64) = 12.5 %
NS = 4.0 ** np.arange(1, 10)             # 4 ... 2^18, stepping ×4 as the study does
TAU = 3e-9                               # seconds per sample


def sqrt_curve(c=2.0):
    return c / np.sqrt(NS)


def test_rmse_relative_error_is_one_over_sqrt_2k_and_rejects_bad_key_counts():
    assert V.rmse_relative_error(32) == pytest.approx(0.125)
    assert V.rmse_relative_error(8) == pytest.approx(0.25)
    with pytest.raises(ValueError, match="n_keys"):
        V.rmse_relative_error(1)
    with pytest.raises(TypeError, match="n_keys"):
        V.rmse_relative_error(4.0)


def test_time_to_target_on_a_pure_inverse_sqrt_curve_is_the_known_time():
    # RMSE = c n^-1/2 relative to an exact value 1: the target e is reached at n* = (c/e)^2, a time
    # n* τ; on log-log axes the curve is a line, so the interpolation must give it exactly.
    c = 2.0
    for target in (1e-1, 3e-2, 1e-2, 4.5e-3):  # n* = 400 ... 2e5 < 2^18
        t = V.time_to_target(NS * TAU, sqrt_curve(c), target, slope=-0.5, n_keys=K)
        assert t.bound == "="
        assert t.seconds == pytest.approx((c / target) ** 2 * TAU, rel=1e-12)
        # an error off by 1/sqrt(2k) = 12.5 % moves the crossing of a slope -1/2 by 25 %
        assert t.rel_err == pytest.approx(0.25)


def test_time_to_target_never_extrapolates():
    c = 2.0
    beyond = V.time_to_target(NS * TAU, sqrt_curve(c), 1e-4, slope=-0.5, n_keys=K)  # needs n = 4e8 > 2^18
    assert (beyond.bound, beyond.why, beyond.reached) == (">", "budget", False)
    assert beyond.seconds == pytest.approx(NS[-1] * TAU)  # a lower bound: the whole budget
    before = V.time_to_target(NS * TAU, sqrt_curve(c), 1.5, slope=-0.5, n_keys=K)  # already met at n = 4
    assert (before.bound, before.seconds) == ("<=", pytest.approx(NS[0] * TAU))


def floored_curve(floor_at=5, c=2.0):
    """c n^-1/2 down to the value it has at index `floor_at`, flat from there on."""
    return np.maximum(sqrt_curve(c), sqrt_curve(c)[floor_at])


def test_floor_is_found_at_the_first_point_that_stops_falling():
    assert V.floor_index(floored_curve(5), K) == 5
    assert V.floor_index(floored_curve(2), K) == 2
    assert V.floor_index(sqrt_curve(), K) is None
    paused = sqrt_curve()
    paused[3:6] = paused[3]  # flat for two steps, then falling again: a pause, not a floor
    assert V.floor_index(paused, K) is None


# A deterministic ±8 % wobble, within the 1/sqrt(k) = 17.7 % that a difference of two log RMSEs over
# 32 keys carries: it must neither hide a floor nor invent one on a falling curve.
WOBBLE = np.exp(0.08 * np.array([1, -1, -1, 1, 1, -1, 1, -1, -1]))


def test_floor_detection_tolerates_the_noise_the_keys_allow():
    assert V.floor_index(floored_curve(5) * WOBBLE, K) == 5
    assert V.floor_index(sqrt_curve() * WOBBLE, K) is None
    # A curve falling as n^-1/4 (0.35 per step, 0.69 over two) falls clearly with 32 keys
    # (1/sqrt(k) = 0.18 in log), but not with 2 (0.71): the tolerance is what the keys allow.
    assert V.floor_index(NS**-0.25, K) is None
    assert V.floor_index(NS**-0.25, 2) == len(NS) - 3


def test_one_flat_step_at_the_end_is_not_a_floor():
    rmse = sqrt_curve()
    rmse[-1] = rmse[-2]  # flat over the last step only: 4 % likely for a falling curve over 16 keys
    assert V.floor_index(rmse, 16) is None
    rmse[-3:] = rmse[-3]  # flat over the last two steps: a floor from the third last point
    assert V.floor_index(rmse, 16) == len(NS) - 3


def test_a_floor_cuts_the_curve_for_the_time_to_target():
    # Floored at index 5 (relative RMSE 2/sqrt(4^6) = 0.031); a noisy later point dips below the
    # 0.03 target, which must not count as reaching it.
    rmse = floored_curve(5)
    rmse[-1] *= 0.9
    assert rmse[-1] < 0.03 < rmse[5]
    floor = V.floor_index(rmse, K)
    assert floor == 5
    t = V.time_to_target(NS * TAU, rmse, 0.03, last=floor, slope=-0.5, n_keys=K)
    assert (t.bound, t.why) == (">", "floor")
    # above the floor the target is read off the part before it
    above = V.time_to_target(NS * TAU, rmse, 0.05, last=floor, slope=-0.5, n_keys=K)
    assert above.seconds == pytest.approx((2.0 / 0.05) ** 2 * TAU, rel=1e-12)


def test_slope_is_fitted_before_the_floor_with_a_standard_error_the_keys_allow():
    rmse = floored_curve(6)
    s = V.fit_slope(NS, rmse, K, stop=V.floor_index(rmse, K))
    assert (s.value, s.points, s.n_last) == (pytest.approx(-0.5, abs=1e-12), 6, NS[5])
    # an exact power law has no residuals: the error is the keys' 1/sqrt(2k) over sqrt(Σ(x - x̄)²)
    x = np.log(NS[:6])
    assert s.stderr == pytest.approx(0.125 / math.sqrt(np.sum((x - x.mean()) ** 2)))
    assert V.fit_slope(NS, rmse, K).value > -0.45  # through the floor the slope is too shallow
    # residual scatter larger than the keys allow widens the error
    s_noisy = V.fit_slope(NS, sqrt_curve() * np.exp(0.5 * np.array([1, -1, 1, -1, 1, -1, 1, -1, 1])), K)
    assert s_noisy.stderr > 2 * V.fit_slope(NS, sqrt_curve(), K).stderr
    assert math.isnan(V.fit_slope(NS, sqrt_curve(), K, n_min=NS[-1]).value)  # one point: no slope


def test_a_slope_needs_three_sizes_and_a_time_without_one_has_no_error():
    two = V.fit_slope(NS[:2], sqrt_curve()[:2], K)
    assert math.isnan(two.value) and math.isnan(two.stderr) and two.points == 2  # a line through 2 points
    three = V.fit_slope(NS[:3], sqrt_curve()[:3], K)
    assert (three.value, three.points) == (pytest.approx(-0.5, abs=1e-12), 3)
    # With no fitted slope a time is still read off the curve, but its error is unknown: the rate
    # between the two points around the crossing is not taken for one.
    t = V.time_to_target(NS * TAU, sqrt_curve(), 1e-2, slope=math.nan, n_keys=K)
    assert t.bound == "=" and t.seconds == pytest.approx(200.0**2 * TAU) and math.isnan(t.rel_err)
    assert V.format_time(t).endswith("± ? (no fitted slope)")


def test_an_unknown_error_names_no_single_winner():
    times = {"a": V.Time(1.0, "=", math.nan), "b": V.Time(3.0, "=", 0.1), "c": V.Time(2.0, "=", 0.1)}
    assert V.best(times) == ["a", "c", "b"]  # 3× apart, but with no error on a's time: not told apart
    ratio = V.speedup(times["b"], times["a"])
    assert (ratio.bound, math.isnan(ratio.rel_err), V.format_ratio(ratio)) == ("=", True, "3× ± ?")
    assert V.best({"b": times["b"], "c": times["c"]}) == ["c"]  # log 1.5 = 0.41 > 2 × 0.14: c alone


def test_exact_is_detected_from_the_curve_at_every_n():
    exact = math.pi
    ulp = float(np.spacing(np.float32(exact)))
    assert V.is_exact(np.zeros(9), exact)
    assert V.is_exact(np.full(9, 0.6 * ulp), exact)          # π rounded to float32, at every n
    assert not V.is_exact(np.r_[1e3 * ulp, np.full(8, ulp)], exact)  # small only at the end: a floor
    assert not V.is_exact(sqrt_curve(), exact)


def test_speedup_carries_both_errors_and_bounds():
    slow, fast = V.Time(8.0, "=", 0.3), V.Time(2.0, "=", 0.4)
    r = V.speedup(slow, fast)
    assert (r.value, r.bound, r.rel_err) == (4.0, "=", pytest.approx(0.5))
    assert V.speedup(V.Time(8.0, ">", why="budget"), fast).bound == ">="   # the slow one never got there
    assert V.speedup(slow, V.Time(2.0, "<=")).bound == ">="
    assert V.speedup(slow, V.Time(1e-9, "exact")).bound == "?"
    assert V.format_ratio(r) == "4× ± 50 %"
    assert V.format_ratio(V.speedup(V.Time(8.0, ">", why="budget"), fast)) == "≥ 4×"


def test_best_ranks_exact_first_names_ties_and_can_be_none():
    times = {"a": V.Time(1.0, "=", 0.1), "b": V.Time(1.2, "=", 0.1), "c": V.Time(5.0, "=", 0.1),
             "d": V.Time(9.0, ">", why="budget")}
    assert V.best(times) == ["a", "b"]  # log 1.2 = 0.18 < 2 × hypot(0.1, 0.1) = 0.28: a tie; c is not
    assert V.best({**times, "z": V.Time(1e-9, "exact"), "y": V.Time(1e-9, "exact")}) == ["y", "z"]
    assert V.best({"d": times["d"]}) == []


def test_verdict_names_the_best_non_qmc_and_both_speedups():
    times = {"uniform": V.Time(100.0, "=", 0.25), "cosine": V.Time(40.0, "=", 0.25),
             "cosine+sobol": V.Time(2.0, "=", 0.1)}
    kinds = {"uniform": "plain", "cosine": "importance", "cosine+sobol": "QMC"}
    v = V.verdict(times, kinds, "uniform")
    assert v["best"] == ["cosine+sobol"] and v["best_non_qmc"] == ["cosine"]
    assert v["over_baseline"].value == pytest.approx(50.0)
    assert v["over_non_qmc"].value == pytest.approx(20.0)
    with pytest.raises(ValueError, match="baseline"):
        V.verdict(times, kinds, "nope")


def synthetic_row(strategy, kind, rmse, baseline=False, exact=1.0, ns=NS):
    return {"integrand": "synthetic", "strategy": strategy, "kind": kind, "baseline": baseline,
            "exact": exact, "ns": [int(n) for n in ns], "rmse": list(map(float, rmse)), "n_keys": K,
            "rmse_at_max": float(rmse[-1]), "bias_at_max": 0.0, "bias_z": 0.0, "bias_ulps": 0.0,
            "per_sample_variance": 1.0}


def test_add_verdicts_reads_exact_floor_slope_and_times_off_a_row():
    plain = C.add_verdicts(synthetic_row("uniform", "plain", sqrt_curve(), baseline=True), TAU)
    assert plain["floor_n"] is None and not plain["zero_variance"]
    assert plain["slope"] == pytest.approx(-0.5) and plain["slope_points"] == 6  # n >= 256 only
    assert plain["times"]["0.01"]["seconds"] == pytest.approx(200.0**2 * TAU)
    floored = C.add_verdicts(synthetic_row("sobol", "QMC", floored_curve(4, c=20.0)), TAU)
    assert floored["floor_n"] == int(NS[4])
    assert floored["times"]["0.0001"]["why"] == "floor"
    exact = C.add_verdicts(synthetic_row("cosine", "importance", np.zeros(9)), TAU)
    assert exact["zero_variance"] and {t["bound"] for t in exact["times"].values()} == {"exact"}


TINY_NS = np.array(C.study_sizes(tiny=True)[0], float)  # 4 ... 2^10: two sizes from FIT_FROM_N = 256 on


def test_a_study_with_two_sizes_to_fit_draws_no_slope_and_no_verdict():
    assert np.sum(TINY_NS >= C.FIT_FROM_N) == 2
    rows = [C.add_verdicts(synthetic_row("uniform", "plain", 0.05 / np.sqrt(TINY_NS), baseline=True, ns=TINY_NS), TAU),
            C.add_verdicts(synthetic_row("cosine", "importance", 0.03 / np.sqrt(TINY_NS), ns=TINY_NS), TAU)]
    for row in rows:
        assert math.isnan(row["slope"]) and row["slope_points"] == 2
        assert C.slope_cell(row) == "— (too few sizes: 2 < 3)"
        measured = [t for t in row["times"].values() if t["bound"] == "="]
        assert measured and all(math.isnan(t["rel_err"]) for t in measured)
    assert "too few sizes" in C.markdown_table(rows)
    # 0.01 is crossed by both (n = 9 and 25), with no error on either time: no single winner
    first = C.verdict_rows(rows)[0]
    assert first["target"] == 0.01 and first["best"] == ["cosine", "uniform"]
    headline = C.headline_markdown(rows)
    assert "not told apart: uniform" in headline and "± ?" in headline and "tied within 2σ" not in headline


def test_headline_table_from_synthetic_rows():
    rows = [C.add_verdicts(synthetic_row("uniform", "plain", sqrt_curve(), baseline=True), TAU),
            C.add_verdicts(synthetic_row("cosine", "importance", sqrt_curve(0.5)), 2 * TAU),
            C.add_verdicts(synthetic_row("cosine+sobol", "QMC", 4.0 / NS), TAU)]
    verdicts = C.verdict_rows(rows)
    assert [v["target"] for v in verdicts] == [1e-2, 1e-3, 1e-4]
    # 1e-2: sobol needs n = 400, uniform 4e4 (×100), cosine 2500 at twice the cost (×12.5)
    assert verdicts[0]["best"] == ["cosine+sobol"] and verdicts[0]["best_non_qmc"] == ["cosine"]
    assert verdicts[0]["over_baseline"].value == pytest.approx(100.0)
    assert verdicts[0]["over_non_qmc"].value == pytest.approx(12.5)
    assert verdicts[2]["over_baseline"].bound == ">="  # uniform would need 4e8 samples: not reached
    table = C.headline_markdown(rows)
    assert table.count("\n") == 2 + 3
    assert "cosine+sobol (QMC)" in table and "100× ± " in table and "≥ " in table
    rows.append(C.add_verdicts(synthetic_row("exact", "importance", np.zeros(9)), TAU))
    assert all(v["best"] == ["exact"] for v in C.verdict_rows(rows))
    assert "exact at every n" in C.headline_markdown(rows)


def test_strategy_kind_comes_from_its_definition():
    strategies = C.strategies()
    for s in strategies:
        expected = ("QMC" if s.uniforms in ("sobol", "lattice", "halton")
                    else "stratified" if s.uniforms in ("stratified", "lhs")
                    else "MIS" if s.heuristic or type(s.sampler).__name__ == "Mixture"
                    else "importance" if s.importance else "plain")
        assert s.kind == expected and s.kind in V.KINDS, s
    assert {s.kind for s in strategies} == set(V.KINDS)
    integrands = {s.integrand for s in strategies}
    assert all(sum(s.baseline for s in strategies if s.integrand == i) == 1 for i in integrands)
    assert C.Strategy("x", "y", None, "sobol").kind == "QMC"
    # every point set of the library appears, with the kind its construction gives it
    assert {s.uniforms for s in strategies} == {"random", "sobol", "stratified", "lattice", "halton", "lhs"}
    assert [C.Strategy("x", "y", None, u).kind for u in ("lattice", "halton", "lhs")] == ["QMC", "QMC", "stratified"]
    assert C.Strategy("x", "y", None, importance=True).kind == "importance"
    assert C.Strategy("x", "y", None).kind == "plain"
