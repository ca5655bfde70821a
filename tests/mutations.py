"""A curated mutation check: does the suite catch the defects its tests exist for?

    python tests/mutations.py               # every mutation, then the table; exit 1 if any survives
    python tests/mutations.py --only NAME   # one mutation (repeatable)
    python tests/mutations.py --list        # the records, without running anything
    python tests/mutations.py --no-baseline # skip the unmutated run of the selected tests
    python tests/mutations.py --only NAME --tests ARG...    # run chosen pytest arguments instead (last)

Each record is a small, deliberate break of the library: (file, exact old text, new text, the
pytest node ids or files that must catch it). For each one the repository's `jaxsample/`,
`tests/`, `benchmarks/` and `pyproject.toml` are copied into a temporary folder, the copy's file
is edited, and `python -m pytest -q -x <tests>` runs there with the copy first on `PYTHONPATH`
and as the working directory, so that the copy is what gets imported (checked on every run: the
imported `jaxsample.__file__` must lie inside the copy). The mutation is *caught* when pytest
reports failing tests (exit status 1); *survived* when they all pass (0); anything else (the old
text not found exactly `count` times, a collection error, no tests selected, a timeout) is an
ERROR, which counts as a failure too. Before the mutations, the union of the selected tests runs
once on an unmutated copy: a selection that fails without a mutation proves nothing.

The old texts are short, one-line snippets, so that the records survive unrelated edits; when a
file changes under a record, the run says ERROR for it rather than skipping it silently.
Not part of the README's test command: it runs the selected tests once per mutation (minutes).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COPIED = ("jaxsample", "tests", "benchmarks", "pyproject.toml")
TIMEOUT_S = 1200


@dataclasses.dataclass(frozen=True)
class Mutation:
    name: str
    file: str            # relative to the repository root
    old: str             # must occur exactly `count` times; every occurrence is replaced
    new: str
    tests: tuple         # pytest arguments: node ids, files, or "-k", "EXPR"
    why: str
    count: int = 1


M = Mutation
MUTATIONS = [
    # ---- survivors of the first audit, each killed by a test written for it ----
    M("cone-from-angle", "jaxsample/samplers/cone.py",
      "one_minus_cos_theta_max=2.0 * jnp.sin(0.5 * jnp.asarray(theta_max)) ** 2",
      "one_minus_cos_theta_max=jnp.sin(0.5 * jnp.asarray(theta_max)) ** 2",
      ("tests/samplers/test_directional.py::test_cone_constructors_match_their_closed_forms",
       "tests/estimators/test_gradients.py::test_pathwise_gradient_matches_the_exact_derivative"),
      "from_angle builds half the cap: h = sin²(θ/2)"),
    M("cone-from-solid-angle", "jaxsample/samplers/cone.py",
      "jnp.minimum(jnp.asarray(solid_angle) * INV_2PI, 2.0)",
      "jnp.minimum(jnp.asarray(solid_angle) * INV_2PI * 0.5, 2.0)",
      ("tests/samplers/test_directional.py::test_cone_constructors_match_their_closed_forms",
       "tests/estimators/test_gradients.py::test_pathwise_gradient_matches_the_exact_derivative"),
      "from_solid_angle builds h = Ω/4π"),
    M("mis-counts", "jaxsample/estimators/mis.py",
      "weights = heuristic_weights([n_k * p_k for n_k, p_k in zip(counts, pdfs)], exponent)",
      "weights = heuristic_weights([p_k for n_k, p_k in zip(counts, pdfs)], exponent)",
      ("tests/estimators/test_mis_and_variance_reduction.py::"
       "test_balance_heuristic_with_unequal_counts_is_exact_for_the_count_weighted_mixture",
       "tests/estimators/test_mis_and_variance_reduction.py::test_mis_weights_are_the_count_weighted_heuristic_on_the_same_samples"),
      "MIS weights ignore the sample counts (they still sum to 1)"),
    M("mis-stderr", "jaxsample/estimators/mis.py",
      "stderr = safe_sqrt(sum(p.stderr * p.stderr for p in parts))",
      "stderr = 3.0 * safe_sqrt(sum(p.stderr * p.stderr for p in parts))",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[mis]",),
      "estimate_mis stderr 3x too large"),
    M("ratio-stderr", "jaxsample/estimators/variance_reduction.py",
      "linear_var = jnp.maximum(var_y - 2.0 * ratio * cov + ratio * ratio * var_z, 0.0)",
      "linear_var = jnp.maximum(var_y + ratio * ratio * var_z, 0.0)",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[ratio]",),
      "the ratio estimator's delta-method variance drops its covariance term"),
    M("replicated-stderr", "jaxsample/estimators/engine.py",
      "stderr = safe_sqrt(jnp.sum(spread * spread, axis=0) / (replicates - 1) / replicates)",
      "stderr = 4.0 * safe_sqrt(jnp.sum(spread * spread, axis=0) / (replicates - 1) / replicates)",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[sobol]",
       "tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[stratified]"),
      "Sobol'/stratified stderr 4x too large"),
    M("shade-heuristic", "jaxsample/scene/direct.py",
      'exponent = 1 if heuristic == "balance" else 2',
      "exponent = 1",
      ("tests/scene/test_scene.py::test_shade_mis_weights_are_the_documented_heuristic_on_the_same_samples",),
      "shade uses the balance heuristic where the power heuristic is documented"),
    M("sobol-shared-seed", "jaxsample/uniforms/sources.py",
      "words = philox4x32((replicate, dim, jnp.full_like(dim, _STREAM_SCRAMBLE)",
      "words = philox4x32((replicate, 0 * dim, jnp.full_like(dim, _STREAM_SCRAMBLE)",
      ("tests/uniforms/test_uniforms.py",),
      "one Owen-scramble seed shared by all dimensions"),
    # ---- every error bar's calibration test, each against an error bar of its own path ----
    M("random-stderr-x3", "jaxsample/estimators/engine.py",
      "stderr = safe_sqrt(variance / n)",
      "stderr = 3.0 * safe_sqrt(variance / n)",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[random]",),
      "the plain estimator's stderr 3x too large"),
    M("antithetic-stderr-x3", "jaxsample/estimators/variance_reduction.py",
      "return est.per_evaluation(n)",
      "return Estimate(**{**vars(est.per_evaluation(n)), \"stderr\": 3.0 * est.stderr})",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[antithetic]",),
      "the antithetic estimator's stderr 3x too large"),
    M("control-variate-stderr-plain", "jaxsample/estimators/variance_reduction.py",
      "variance = jnp.maximum(var_y - coefficient * cov, 0.0)",
      "variance = var_y",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[control-variate]",),
      "the control variate reports plain MC's stderr (2.5x too large here)"),
    M("shade-stderr-per-evaluation", "jaxsample/scene/direct.py",
      "return est.per_evaluation(n)",
      "return Estimate(**{**vars(est.per_evaluation(n)), \"stderr\": est.stderr / 2.0 ** 0.5})",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[shade-mis]",),
      "shade's MIS stderr counts n evaluations as n independent terms instead of n/2 pairs"),
    M("leave-one-out-stderr", "jaxsample/estimators/gradients.py",
      "stderr=est.stderr[0]",
      "stderr=est.stderr[1]",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[expectation-leave-one-out]",),
      "the leave-one-out expectation reports the stderr of another streamed component"),
    # ---- defects of the kind the suite already caught ----
    M("sphere-density-1pct", "jaxsample/samplers/sphere.py",
      "return jnp.full(x.shape[:-1], INV_4PI, dtype=jnp.result_type(x, float))",
      "return jnp.full(x.shape[:-1], 1.01 * INV_4PI, dtype=jnp.result_type(x, float))",
      ("tests/samplers/test_contract.py", "-k", "normalization_within and UniformSphere"),
      "a density constant off by 1 %"),
    M("phong-warp-n-plus-one", "jaxsample/samplers/phong.py",
      "return jnp.log1p(-u0) / (self.exponent + 1.0)",
      "return jnp.log1p(-u0) / (self.exponent + 2.0)",
      ("tests/samplers/test_contract.py", "-k", "chi_square_goodness and PhongLobe"),
      "n for n + 1 in the Phong warp"),
    M("phong-warp-2pct", "jaxsample/samplers/phong.py",
      "return jnp.log1p(-u0) / (self.exponent + 1.0)",
      "return jnp.log1p(-u0) / (1.02 * self.exponent + 1.0)",
      ("tests/samplers/test_contract.py", "-k", "chi_square_goodness and PhongLobe"),
      "the Phong warp's exponent 2 % off: the chi-square tests at the suite's sample size"),
    M("triangle-light-jacobian", "jaxsample/scene/triangle_light.py",
      "pdf = safe_div(distance2, self.triangle.area * jnp.abs(cos_light))",
      "pdf = safe_div(distance2, self.triangle.area)",
      ("tests/scene/test_scene.py::test_triangle_light_density_is_the_area_to_solid_angle_jacobian",),
      "a missing Jacobian factor (|cos θ_l| of the area-to-solid-angle map)"),
    M("disk-polar-sqrt", "jaxsample/samplers/disk.py",
      "r = safe_sqrt(u[..., 0])",
      "r = u[..., 0]",
      ("tests/samplers/test_contract.py", "-k", "UniformDisk-polar"),
      "a missing square root in a warp (the polar disk's radius)"),
    M("stderr-sqrt", "jaxsample/estimators/engine.py",
      "stderr = safe_sqrt(variance / n)",
      "stderr = variance / n",
      ("tests/estimators/test_estimate.py::test_unbiased_cosine_and_uniform_and_fails_when_biased",),
      "a missing square root in the stderr"),
    M("mis-weight-swapped", "jaxsample/estimators/mis.py",
      "weight = weights[i]",
      "weight = weights[len(weights) - 1 - i]",
      ("tests/estimators/test_mis_and_variance_reduction.py::test_mis_weights_are_the_count_weighted_heuristic_on_the_same_samples",),
      "MIS weights of the two techniques swapped (still unbiased: they sum to 1; a survivor before)"),
    M("score-sample-not-detached", "jaxsample/estimators/gradients.py",
      "x = jax.lax.stop_gradient(sampler.warp(u))",
      "x = sampler.warp(u)",
      ("tests/estimators/test_gradients.py::test_pathwise_and_score_gradients_of_an_expectation_are_unbiased",),
      "the score function's sample is not detached (pathwise term added)", count=2),
    M("half-detached", "jaxsample/estimators/plain.py",
      "x, pdf = _detach(mode, x, pdf)",
      "x, _ = _detach(mode, x, pdf)",
      ("tests/estimators/test_gradients.py::test_detached_gradient_is_exactly_zero_for_every_sample_and_in_estimate",),
      "detached mode stops the sample's gradient but not its density's"),
    M("antithetic-not-reflected", "jaxsample/estimators/variance_reduction.py",
      "lambda u: 0.5 * (one(u) + one(1.0 - u))",
      "lambda u: 0.5 * (one(u) + one(u))",
      ("tests/estimators/test_mis_and_variance_reduction.py::test_antithetic_reduces_variance_and_stays_unbiased",),
      "antithetic pairs that are copies, not reflections"),
    M("control-variate-sign", "jaxsample/estimators/variance_reduction.py",
      "mean = est.mean[0] - coefficient * (est.mean[1] - g_integral)",
      "mean = est.mean[0] + coefficient * (est.mean[1] - g_integral)",
      ("tests/estimators/test_mis_and_variance_reduction.py::test_control_variate_reduces_variance_and_stays_unbiased",
       "tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[control-variate]"),
      "the control variate's correction with the wrong sign (a noise-sized error that survived the "
      "bias check; the calibration test's spread sees it)"),
    M("owen-scramble-no-seed", "jaxsample/uniforms/sobol.py",
      "x = reversed_x + seed",
      "x = reversed_x + 0 * seed",
      ("tests/uniforms/test_uniforms.py",),
      "the Owen scramble ignores its seed (every key gives the same points)"),
    M("phong-density-constant", "jaxsample/samplers/phong.py",
      "return x, (n + 1.0) * INV_2PI * jnp.exp(n * log_cos)",
      "return x, (n + 1.01) * INV_2PI * jnp.exp(n * log_cos)",
      ("tests/estimators/test_estimate.py::test_grad_attached_exact_and_detached_zero",),
      "the Phong sampler's density constant off (n + 1.01 for n + 1): the exact attached gradients"),
    M("exponential-rate-2pct", "jaxsample/samplers/exponential.py",
      "return -jnp.log1p(-u[..., 0]) / self.rate",
      "return -jnp.log1p(-u[..., 0]) / (1.02 * self.rate)",
      ("tests/samplers/test_contract.py", "-k", "chi_square_goodness and Exponential"),
      "an exponential warp's rate 2 % off: the chi-square tests at the suite's sample size"),
    M("doublefloat-drops-error", "jaxsample/_core/doublefloat.py",
      "hi, lo = two_sum(s, e + x[1] + y[1])",
      "hi, lo = two_sum(s, x[1] + y[1])",
      ("tests/_core/test_doublefloat.py",),
      "double-float addition drops the rounding error of hi + hi"),
    M("shade-mis-weight-swapped", "jaxsample/scene/direct.py",
      "weight = mis_weight(pdf, light_pdf, exponent) if weighted else 1.0",
      "weight = mis_weight(light_pdf, pdf, exponent) if weighted else 1.0",
      ("tests/scene/test_scene.py::test_shade_mis_weights_are_the_documented_heuristic_on_the_same_samples",),
      "shade's MIS weight of the BRDF sample swapped (unbiased, so bias checks cannot see it)"),
    M("shade-light-mixture-pdf", "jaxsample/scene/direct.py",
      "return sum(light.pdf(self.point, wi) for light in self.lights) / len(self.lights)",
      "return sum(light.pdf(self.point, wi) for light in self.lights)",
      ("tests/scene/test_scene.py::test_every_strategy_is_unbiased",),
      "the light-selection probability 1/K missing from the light density"),
    # ---- the per-point engine and the sources' fast paths (issue 12) ----
    M("lanes-dot-drops-a-term", "jaxsample/_core/lanes.py",
      "for c in range(1, k):",
      "for c in range(1, k - 1):",
      ("tests/_core/test_lanes.py",),
      "a dot product on lanes forgets its last product (x @ a sums two of three components)"),
    M("lanes-reduce-drops-a-term", "jaxsample/_core/lanes.py",
      "for t in terms[1:]:",
      "for t in terms[1:-1]:",
      ("tests/_core/test_lanes.py",),
      "a reduction on lanes forgets its last element (jnp.sum(x * a) off by one component)"),
    M("sobol-lanes-without-high-bits", "jaxsample/uniforms/sources.py",
      "jnp.asarray(table[:, j])[:, None] ^ high[j]",
      "jnp.asarray(table[:, j])[:, None]",
      ("tests/_core/test_lanes.py::test_source_lanes_are_the_block_points",),
      "every chunk of Sobol' points repeats the first chunk's low-index points"),
    M("stratified-lanes-wrong-index", "jaxsample/uniforms/sources.py",
      "_u32(offset) + _u32(g) * blocks + _u32(q), per_replicate, dtype)",
      "_u32(offset) + blocks + _u32(q), per_replicate, dtype)",
      ("tests/_core/test_lanes.py::test_source_lanes_are_the_block_points",),
      "stratified groups index points as if each Philox block held one point (wrong cells)"),
    M("computed-once-swaps-a-pair", "jaxsample/_core/computed_once.py",
      "for i, half in ((a, jnp.real(p)), (b, jnp.imag(p))):",
      "for i, half in ((a, jnp.imag(p)), (b, jnp.real(p))):",
      ("tests/_core/test_lanes.py::test_computed_once_returns_the_values_bit_for_bit",
       "tests/_core/test_lanes.py::test_sample_is_the_warp_of_the_stream"),
      "the packed values come back in the wrong order"),
    M("sample-wrong-interleave", "jaxsample/samplers/base.py",
      "results.append(jnp.stack(parts, axis=1).reshape((chunk,) + layout[0][k][2]))",
      "results.append(jnp.stack(parts, axis=0).reshape((chunk,) + layout[0][k][2]))",
      ("tests/_core/test_lanes.py::test_sample_is_the_warp_of_the_stream",),
      "sample() returns the groups one after the other instead of interleaved (not the stream order)"),
    # ---- gradients with error bars (issue 15) ----
    M("gradient-stderr-x3", "jaxsample/estimators/gradient_errors.py",
      "stderr=unravel(est.stderr)",
      "stderr=unravel(3.0 * est.stderr)",
      ("tests/estimators/test_gradient_errors.py",),
      "the gradient's standard error three times too large (intervals cover too often)"),
    M("gradient-of-the-wrong-thing", "jaxsample/estimators/gradient_errors.py",
      "return point_value(f, s, row)",
      "return point_value(f, s, row) * (1.0 + 0.01 * theta[0])",
      ("tests/estimators/test_gradient_errors.py",),
      "the per-sample gradient is not that of the estimate's value"),
    M("until-loose-tolerance", "jaxsample/estimators/until.py",
      "met = jnp.all(stderr <= tolerance)",
      "met = jnp.all(stderr <= 2.0 * tolerance)",
      ("tests/estimators/test_until.py",),
      "estimate_until stops before its standard error meets the tolerance"),
    M("until-sobol-not-at-nets", "jaxsample/estimators/until.py",
      "return (per & (per - 1)) == 0",
      "return per > 0",
      ("tests/estimators/test_until.py",),
      "estimate_until stops Sobol' points between nets"),
    M("measure-valued-independent-pair", "jaxsample/samplers/phong.py",
      "log_cos_product = log_cos + self._log_cos_from_u(u[..., 2])",
      "log_cos_product = self._log_cos_from_u(u[..., 2])",
      ("tests/estimators/test_gradient_errors.py",),
      "the measure-valued pair draws cos θ' from p_n instead of the product of two draws (biased)"),
    # ---- the sampler contract (issue 13: one suite over every sampler) ----
    M("contract-gradient-nan-at-zero", "jaxsample/_core/numerics.py",
      "return root, jnp.where(positive, 0.5 * dx / jnp.where(positive, root, 1.0), 0.0)",
      "return root, 0.5 * dx / root",
      ("tests/samplers/test_contract.py", "-k", "finite_at_the_hard_cases and (UniformDisk-polar or Cone)"),
      "safe_sqrt's derivative unguarded at 0: inf and NaN at the disk's centre and the cone's pole"),
    M("contract-phong-inverse", "jaxsample/samplers/phong.py",
      "u0 = -jnp.expm1((self.exponent + 1.0) * log_cos)",
      "u0 = -jnp.expm1((self.exponent + 1.01) * log_cos)",
      ("tests/samplers/test_contract.py", "-k", "inverse_round_trip and PhongLobe"),
      "the Phong inverse's exponent 1 % off (the warp and the density are right)"),
    M("contract-phong-density-from-u", "jaxsample/samplers/phong.py",
      "return x, (n + 1.0) * INV_2PI * jnp.exp(n * log_cos)",
      "return x, (n + 1.0) * INV_2PI * jnp.exp((n + 0.01) * log_cos)",
      ("tests/samplers/test_contract.py", "-k", "samples_lie and PhongLobe"),
      "the density warp_with_pdf computes from u disagrees with pdf(x) (normalization cannot see it)"),
    M("contract-transformed-determinant", "jaxsample/samplers/transformed.py",
      "return jnp.where(ok, base_density * jnp.exp(-jnp.where(ok, log_det, 0.0)), 0.0)",
      "return jnp.where(ok, base_density * jnp.exp(jnp.where(ok, log_det, 0.0)), 0.0)",
      ("tests/samplers/test_contract.py", "-k", "Transformed-exponential-map and (normalization or jacobian)"),
      "the change of variables multiplies by |det J| instead of dividing"),
    M("contract-disk-quadrature", "jaxsample/checks/domains.py",
      "weights = 0.5 * np.multiply.outer(ws, wphi).ravel()",
      "weights = 0.5 * np.multiply.outer(ws, 1.1 * wphi).ravel()",
      ("tests/samplers/test_contract.py", "-k", "chi_square_goodness and UniformDisk-polar"),
      "the disk's chi-square cells expect 10 % too many samples"),
    M("sampler-imports-check-geometry", "jaxsample/samplers/phong.py",
      "from .domain import Directions",
      "from ..checks.domains import Directions",
      ("tests/checks/test_frame_and_checks.py::test_importing_a_sampler_does_not_import_the_checks_geometry",),
      "a sampler imports the checks' quadrature and binning again"),
    M("quadrature-bounds-unchecked", "jaxsample/quadrature.py",
      "concrete = concrete_value(value)  # float64, or None when traced (then it cannot be checked)",
      "concrete = None",
      ("tests/test_quadrature.py",),
      "concrete bounds are treated as traced: reversed or infinite bounds are no longer rejected"),
]


def copy_tree(destination: Path) -> None:
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache", "results")
    for name in COPIED:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, destination / name, ignore=ignore)
        else:
            shutil.copy2(source, destination / name)


def environment(copy: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(copy) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env.pop("XLA_FLAGS", None)
    return env


def imported_from(copy: Path, env: dict) -> str:
    out = subprocess.run([sys.executable, "-c", "import jaxsample; print(jaxsample.__file__)"], cwd=copy,
                         env=env, capture_output=True, text=True, timeout=300)
    return out.stdout.strip()


def run_pytest(copy: Path, tests) -> tuple[int, str]:
    env = environment(copy)
    where = imported_from(copy, env)
    if not where.startswith(str(copy)):
        return -1, f"the copy is not what gets imported: jaxsample from {where!r}"
    command = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *tests]
    try:
        out = subprocess.run(command, cwd=copy, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return -1, f"timed out after {TIMEOUT_S} s"
    return out.returncode, (out.stdout + out.stderr)[-3000:]


def apply(copy: Path, mutation: Mutation) -> str | None:
    """Edit the copy; an error message if the old text is not there exactly `count` times."""
    path = copy / mutation.file
    if not path.exists():
        return f"{mutation.file} does not exist"
    text = path.read_text()
    found = text.count(mutation.old)
    if found != mutation.count:
        return f"old text found {found} times in {mutation.file}, expected {mutation.count}: {mutation.old!r}"
    path.write_text(text.replace(mutation.old, mutation.new))
    return None


def union_of_tests(mutations) -> list[list[str]]:
    """The selections, grouped so that each "-k" expression stays with its own files."""
    plain, keyed = [], []
    for m in mutations:
        if "-k" not in m.tests:
            plain.append(list(m.tests))
        elif list(m.tests) not in keyed:
            keyed.append(list(m.tests))
    merged = sorted({t for group in plain for t in group})
    return ([merged] if merged else []) + keyed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", action="append", metavar="NAME", help="run only this mutation (repeatable)")
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    parser.add_argument("--no-baseline", action="store_true", help="skip the unmutated run of the selections")
    parser.add_argument("--tests", nargs=argparse.REMAINDER, metavar="ARG",
                        help="(last) run these pytest arguments instead of each record's own selection")
    args = parser.parse_args(argv)

    names = [m.name for m in MUTATIONS]
    assert len(set(names)) == len(names), "mutation names must be unique"
    if args.list:
        for m in MUTATIONS:
            print(f"{m.name:28s} {m.file:34s} {m.why}\n{'':28s} tests: {' '.join(m.tests)}")
        return 0
    selected = MUTATIONS
    if args.only:
        unknown = sorted(set(args.only) - set(names))
        if unknown:
            parser.error(f"unknown mutation(s): {', '.join(unknown)}; see --list")
        selected = [m for m in MUTATIONS if m.name in args.only]
    if args.tests:
        selected = [dataclasses.replace(m, tests=tuple(args.tests)) for m in selected]

    failures = 0
    with tempfile.TemporaryDirectory(prefix="jaxsample-mutations-") as tmp:
        tmp = Path(tmp)
        if not args.no_baseline:
            baseline = tmp / "baseline"
            copy_tree(baseline)
            for tests in union_of_tests(selected):
                start = time.time()
                code, output = run_pytest(baseline, tests)
                print(f"baseline (unmutated) {' '.join(tests)}: exit {code} in {time.time() - start:.0f} s", flush=True)
                if code != 0:
                    print(output)
                    print("ERROR: the selected tests fail without any mutation; nothing below would mean anything.")
                    return 2
        rows = []
        for m in selected:
            copy = tmp / m.name
            copy_tree(copy)
            start = time.time()
            error = apply(copy, m)
            if error is None:
                code, output = run_pytest(copy, m.tests)
                if code == 1:
                    verdict = "caught"
                elif code == 0:
                    verdict = "SURVIVED"
                else:
                    verdict, error = "ERROR", f"pytest exit {code}: {output[-1500:]}"
            else:
                verdict = "ERROR"
            seconds = time.time() - start
            failures += verdict != "caught"
            rows.append((m.name, m.file, verdict, seconds))
            print(f"{m.name:28s} {verdict:8s} {seconds:6.0f} s", flush=True)
            if error:
                print(f"    {error}")
            shutil.rmtree(copy, ignore_errors=True)

    print()
    print(f"| {'mutation':28s} | {'file':34s} | {'result':8s} | {'time':>6s} |")
    print(f"|{'-' * 30}|{'-' * 36}|{'-' * 10}|{'-' * 8}|")
    for name, file, verdict, seconds in rows:
        print(f"| {name:28s} | {file:34s} | {verdict:8s} | {seconds:5.0f}s |")
    caught = sum(r[2] == "caught" for r in rows)
    print(f"\n{caught} of {len(rows)} mutations caught; {len(rows) - caught} survived or errored.")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
