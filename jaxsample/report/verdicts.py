"""Verdicts from measured error curves: time to reach an error, floors, slopes, "exact".

Pure NumPy functions of one strategy's measured curve — sample counts n_i, the RMSE over k
independent keys at each n_i, and the time each n_i costs — and of a set of such curves. The
convergence study (`convergence.py`) measures the curves; the report prints what these return.

The uncertainty that k keys allow: an RMSE over k keys is the root of a mean of k squared errors;
for roughly Gaussian errors the mean square has relative standard deviation sqrt(2/k), so the RMSE
has about 1/sqrt(2k) (the delta method: d log r = ½ d log r²). Every tolerance below is in units of
it, so a study over more keys draws finer distinctions.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import numpy as np

TARGETS = (1e-2, 1e-3, 1e-4)  # relative RMSE = RMSE / |exact value|
EXACT_ULPS = 4                # "exact": RMSE within this many float32 ulps of the exact value at every n
FLOOR_Z = 1.0                 # a fall smaller than this many standard deviations is no fall
FLOOR_CONFIRM = 2             # ... when it holds for this many later points
TIE_Z = 2.0                   # a runner-up within this many standard deviations of the best is a tie
MIN_SLOPE_POINTS = 3          # a slope is fitted to at least this many sizes; through fewer there is none
QMC = "QMC"
KINDS = ("plain", "importance", "MIS", "stratified", QMC)


def rmse_relative_error(n_keys: int) -> float:
    """Relative standard deviation of an RMSE taken over `n_keys` independent keys: 1/sqrt(2k)."""
    if isinstance(n_keys, bool) or not isinstance(n_keys, (int, np.integer)):
        raise TypeError(f"n_keys must be an int; got {type(n_keys).__name__}")
    if n_keys < 2:
        raise ValueError(f"n_keys must be >= 2 (a spread needs two keys); got {n_keys}")
    return 1.0 / math.sqrt(2.0 * n_keys)


def _curve(ns: Sequence[float], rmse: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    ns, rmse = np.asarray(ns, float), np.asarray(rmse, float)
    if ns.ndim != 1 or ns.shape != rmse.shape or ns.size == 0:
        raise ValueError(f"ns and rmse must be 1-d of one non-zero length; got shapes {ns.shape}, {rmse.shape}")
    if not np.all(np.diff(ns) > 0) or ns[0] <= 0:
        raise ValueError("ns must be positive and strictly increasing")
    if not np.all(np.isfinite(rmse)) or np.any(rmse < 0):
        raise ValueError("rmse must be finite and >= 0")
    return ns, rmse


def is_exact(rmse: Sequence[float], exact: float, ulps: float = EXACT_ULPS) -> bool:
    """True when the RMSE is zero or within `ulps` float32 ulps of the exact value at every n:
    the strategy has zero variance, and what is left is the rounding of a float32 result."""
    rmse = np.asarray(rmse, float)
    if rmse.size == 0:
        raise ValueError("rmse must not be empty")
    ulp = float(np.spacing(np.float32(abs(exact))))
    return bool(np.all(rmse <= ulps * ulp))


def floor_index(rmse: Sequence[float], n_keys: int, z: float = FLOOR_Z, confirm: int = FLOOR_CONFIRM) -> int | None:
    """Index of the first point from which the RMSE stops falling with n, or None.

    Point i starts a floor when no later point lies significantly below it: for every j > i,
    log r_i - log r_j < z · sd, with sd = sqrt(2)/sqrt(2k) = 1/sqrt(k) the standard deviation of a
    difference of two log RMSEs over k keys (taken as independent; prefix estimates on one key are
    positively correlated, which makes the difference smaller). At least `confirm` later points
    must show it: one flat step is within what the keys allow for a falling curve.

    Rates (z = 1, confirm = 2, n stepping ×4 so that plain Monte Carlo falls by log 2 per step): a
    curve falling as n^-1/2 is taken for a floor only if it falls less than sd over two steps,
    probability Φ(1 - 2 sqrt(k) log 2): 3e-6 for k = 16, 4e-12 for k = 32 (with one confirming
    point it would be Φ(1 - sqrt(k) log 2): 4 % for k = 16, the rate that made this two). A flat
    curve escapes at a point with probability 1 - Φ(1)^2 ≈ 30 %, and is then caught a point later.
    The last `confirm` points cannot start a floor: there is too little after them to tell.
    """
    rmse = np.asarray(rmse, float)
    sd = math.sqrt(2.0) * rmse_relative_error(n_keys)
    log_r = np.log(np.maximum(rmse, np.finfo(float).tiny))
    for i in range(len(log_r) - confirm):
        if np.all(log_r[i] - log_r[i + 1:] < z * sd):
            return i
    return None


@dataclasses.dataclass(frozen=True)
class Slope:
    value: float   # d log RMSE / d log n, least squares
    stderr: float  # its standard error (see fit_slope)
    points: int    # how many points the fit used
    n_first: float
    n_last: float


def fit_slope(ns: Sequence[float], rmse: Sequence[float], n_keys: int, stop: int | None = None,
              n_min: float = 0.0) -> Slope:
    """Least-squares slope of log RMSE against log n over the points with n >= n_min and index < stop.

    Its standard error is sigma / sqrt(Σ (x - x̄)²), with sigma the larger of the residual scatter
    and the 1/sqrt(2k) every log RMSE carries: the fit's error is never claimed smaller than the keys
    allow. NaN (value, stderr and n range; `points` says how many there were) with fewer than
    MIN_SLOPE_POINTS points: a line through two points fits them exactly, leaving no residual to
    tell a rate from the keys' noise, so the report draws no slope, and no verdict, from them.
    """
    ns, rmse = _curve(ns, rmse)
    stop = len(ns) if stop is None else stop
    use = (np.arange(len(ns)) < stop) & (ns >= n_min) & (rmse > 0)
    x, y = np.log(ns[use]), np.log(rmse[use])
    if x.size < MIN_SLOPE_POINTS:
        return Slope(math.nan, math.nan, int(x.size), math.nan, math.nan)
    sxx = float(np.sum((x - x.mean()) ** 2))
    slope = float(np.sum((x - x.mean()) * (y - y.mean())) / sxx)
    residual = y - (y.mean() + slope * (x - x.mean()))
    sigma = rmse_relative_error(n_keys)
    sigma = max(sigma, math.sqrt(float(np.sum(residual**2)) / (x.size - 2)))
    return Slope(slope, sigma / math.sqrt(sxx), int(x.size), float(ns[use][0]), float(ns[use][-1]))


@dataclasses.dataclass(frozen=True)
class Time:
    """Seconds to reach a target error. `bound`: "=" measured (interpolated), "<=" reached already at
    the first point (an upper bound), ">" not reached (seconds is the whole budget, a lower bound),
    "exact" zero variance (seconds is the cost of the first point). `rel_err`: relative standard
    deviation of an "=" time, NaN when unknown (no fitted slope); `why`: for ">", "budget" or "floor"."""
    seconds: float
    bound: str
    rel_err: float = math.nan
    why: str = ""

    @property
    def reached(self) -> bool:
        return self.bound in ("=", "<=", "exact")


def time_to_target(seconds: Sequence[float], rel_rmse: Sequence[float], target: float,
                   last: int | None = None, slope: float = math.nan, n_keys: int = 2) -> Time:
    """Time for the curve (seconds_i, rel_rmse_i) to reach `target`, read off on log-log axes.

    The first crossing among points 0..last (`last`: the floor's first point, or the end) is
    interpolated linearly in (log seconds, log error) between the two measured points around it;
    never extrapolated past `last` ("not reached", a lower bound of the whole budget) nor before
    the first point (reached there: an upper bound). The interpolated time's relative error is
    the error's 1/sqrt(2k) divided by |slope| (the fitted d log RMSE / d log n, `fit_slope`): an
    error off by δ moves the crossing by δ/|slope|. Without a fitted, falling slope (NaN: too few
    sizes to fit one) the error is NaN, unknown: the rate between the two points around the
    crossing is not used in its place.
    """
    t, e = _curve(seconds, rel_rmse)
    if not target > 0:
        raise ValueError(f"target must be > 0; got {target}")
    end = len(t) - 1 if last is None else last
    if not 0 <= end < len(t):
        raise ValueError(f"last must index the curve (0..{len(t) - 1}); got {last}")
    if e[0] <= target:
        return Time(float(t[0]), "<=")
    for j in range(1, end + 1):
        if e[j] <= target:
            log_e0, log_e1 = math.log(e[j - 1]), math.log(max(e[j], np.finfo(float).tiny))
            fraction = (math.log(target) - log_e0) / (log_e1 - log_e0)
            log_t = math.log(t[j - 1]) + fraction * (math.log(t[j]) - math.log(t[j - 1]))
            rate = slope if math.isfinite(slope) and slope < 0 else math.nan
            return Time(math.exp(log_t), "=", rmse_relative_error(n_keys) / abs(rate))
    return Time(float(t[-1]), ">", why="floor" if end < len(t) - 1 else "budget")


@dataclasses.dataclass(frozen=True)
class Ratio:
    """a / b with its relative standard deviation; `bound`: "=", ">=" (a lower bound), "<=", or "?"."""
    value: float
    rel_err: float
    bound: str


def speedup(slow: Time, fast: Time) -> Ratio:
    """slow.seconds / fast.seconds. The relative errors of two independent times add in quadrature
    (NaN, unknown, when either is). A time that is a bound makes the ratio one: "not reached" by the
    slower strategy, or reached at the first point by the faster one, gives a lower bound; the
    reverse an upper bound."""
    if fast.bound == "exact" or slow.bound == "exact" or not fast.reached:
        return Ratio(math.nan, math.nan, "?")
    value = slow.seconds / fast.seconds
    lower = slow.bound == ">" or fast.bound == "<="
    upper = slow.bound == "<="
    if lower and upper:
        return Ratio(value, math.nan, "?")
    if lower or upper:
        return Ratio(value, math.nan, ">=" if lower else "<=")
    return Ratio(value, math.hypot(slow.rel_err, fast.rel_err), "=")


def _rank_key(time: Time) -> tuple:
    order = {"exact": 0, "<=": 1, "=": 1, ">": 2}[time.bound]
    return (order, time.seconds)


def best(times: dict[str, Time]) -> list[str]:
    """The names that reach the target first (several when they are exact, or tied within TIE_Z
    standard deviations of the best time, or not told apart from it because the error of their
    ratio is unknown); [] when none reaches it. The first name is the best."""
    reached = {name: t for name, t in times.items() if t.reached}
    if not reached:
        return []
    exact = sorted(name for name, t in reached.items() if t.bound == "exact")
    if exact:
        return exact
    ranked = sorted(reached, key=lambda name: _rank_key(reached[name]))
    top = reached[ranked[0]]
    tied = [ranked[0]]
    for name in ranked[1:]:
        ratio = speedup(reached[name], top)
        # "<=" or "?": the runner-up's time is only an upper bound, so it may be the faster one; an
        # unknown error (no fitted slope) cannot separate the two either.
        if ratio.bound in ("<=", "?") or (ratio.bound == "=" and math.log(ratio.value) < TIE_Z * ratio.rel_err):
            tied.append(name)
        elif ratio.bound == "=" and math.isnan(ratio.rel_err):
            tied.append(name)
    return tied


def verdict(times: dict[str, Time], kinds: dict[str, str], baseline: str) -> dict:
    """The verdict at one target for one integrand: the best strategy (and any tied with it), its
    time, its speed-up over `baseline` and over the best strategy whose kind is not QMC."""
    if baseline not in times:
        raise ValueError(f"baseline {baseline!r} is not among the strategies {sorted(times)}")
    winners = best(times)
    non_qmc = best({name: t for name, t in times.items() if kinds[name] != QMC})
    out = {"best": winners, "best_non_qmc": non_qmc}
    if winners:
        out["time"] = times[winners[0]]
        out["over_baseline"] = speedup(times[baseline], times[winners[0]])
    if winners and non_qmc:
        out["over_non_qmc"] = speedup(times[non_qmc[0]], times[winners[0]])
        out["non_qmc_time"] = times[non_qmc[0]]
    return out


def format_seconds(seconds: float) -> str:
    for scale, unit in ((1.0, "s"), (1e-3, "ms"), (1e-6, "µs"), (1e-9, "ns")):
        if seconds >= scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds / 1e-9:.2g} ns"


def format_time(time: Time) -> str:
    if time.bound == "exact":
        return "exact"
    if time.bound == ">":
        return "not reached (floor)" if time.why == "floor" else f"not reached in {format_seconds(time.seconds)}"
    if time.bound == "<=":
        return f"≤ {format_seconds(time.seconds)}"
    if math.isnan(time.rel_err):
        return f"{format_seconds(time.seconds)} ± ? (no fitted slope)"
    return f"{format_seconds(time.seconds)} ± {100 * time.rel_err:.0f} %"


def format_ratio(ratio: Ratio) -> str:
    if ratio.bound == "?":
        return "—"
    text = f"{ratio.value:.3g}×"
    if ratio.bound == ">=":
        return "≥ " + text
    if ratio.bound == "<=":
        return "≤ " + text
    if math.isnan(ratio.rel_err):
        return f"{text} ± ?"
    return f"{text} ± {100 * ratio.rel_err:.0f} %"
