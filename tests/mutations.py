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
      'exponent = heuristic_exponent("shade", heuristic, beta)',
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
      "mean=mean_g + correction))",
      "mean=mean_g + correction, stderr=est.stderr[1]))",
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
      "the score function's sample is not detached (pathwise term added)"),
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
    M("lanes-max-tie-rule-undone", "jaxsample/_core/lanes.py",
      "outs.append(chooser(*terms) if chooser is not None and inexact else _chained(combine, terms))",
      "outs.append(_chained(combine, terms))",
      ("tests/_core/test_fast_path.py::test_max_and_min_follow_jax_derivative_at_ties",
       "tests/_core/test_fast_path.py::test_the_issue_example_at_a_three_way_tie"),
      "jnp.max on lanes differentiated as a pairwise max chain: tied terms weighted 1/4, 1/4, 1/2, not vmap's 1/3 each"),
    M("lanes-rule-errors-swallowed", "jaxsample/_core/lanes.py",
      "result = rule(self, eqn, lanes)",
      "try:\n            result = rule(self, eqn, lanes)\n        except (TypeError, ValueError):\n"
      "            result = NotImplemented",
      ("tests/_core/test_fast_path.py::test_an_error_inside_a_rule_propagates",),
      "a bug inside a lane rule is hidden by a silent vmap fallback (right values, slow, unseen)"),
    M("lanes-jit-calls-not-inlined", "jaxsample/_core/lanes.py",
      '_INLINED = _keyed({"jit": "jaxpr", ',
      "_INLINED = _keyed({",
      ("tests/_core/test_fast_path.py::test_user_programs_stay_on_the_fast_path",),
      "jnp.clip, jnp.where, jnp.linalg.norm, jnp.cross (jit-ed functions) fall back to vmap: right values, 10x slower"),
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
      "return dataclasses.replace(jax.tree_util.tree_map(unravel, est), gradient=True)",
      "return dataclasses.replace(jax.tree_util.tree_map(unravel, est), gradient=True, stderr=unravel(3.0 * est.stderr))",
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
      "return (steps & (steps - 1)) == 0",
      "return steps > 0",
      ("tests/estimators/test_until.py",),
      "estimate_until stops Sobol' points between nets"),
    M("measure-valued-independent-pair", "jaxsample/samplers/phong.py",
      "log_cos_product = log_cos + self._log_cos_from_u(u[..., 2])",
      "log_cos_product = self._log_cos_from_u(u[..., 2])",
      ("tests/estimators/test_gradient_errors.py",),
      "the measure-valued pair draws cos θ' from p_n instead of the product of two draws (biased)"),
    # ---- issue 14: keys, batches, names, invalid input ----
    M("legacy-key-other-stream", "jaxsample/uniforms/philox.py",
      "return jax.random.wrap_key_data(key)",
      "return jax.random.fold_in(jax.random.wrap_key_data(key), 1)",
      ("tests/samplers/test_keys_batches_names.py::test_a_legacy_key_draws_exactly_the_stream_of_the_typed_key_it_holds",
       "tests/estimators/test_batched_and_invalid.py::test_every_estimator_takes_a_legacy_key_as_the_typed_key_it_holds"),
      "a legacy PRNGKey draws a different stream from the typed key it holds"),
    M("batch-members-share-points", "jaxsample/samplers/base.py",
      "return apply_point(sampler, method, u.reshape(full + (sampler.uniform_dims,)))",
      "return apply_point(sampler, method, jnp.broadcast_to(u[:1], u.shape).reshape(full + (sampler.uniform_dims,)))",
      ("tests/samplers/test_keys_batches_names.py::test_each_batch_member_warps_its_own_stream_points",),
      "batched sample() feeds every member the same uniform point"),
    # ---- the pytree idiom and the parameter declarations (tests/samplers/test_declarations.py) ----
    M("declared-range-not-checked-on-assignment", "jaxsample/_core/pytree.py",
      "            spec.check(type(self).__name__, name, value)",
      "            pass",
      ("tests/samplers/test_declarations.py", "-k", "outside or users_declared"),
      "a declared parameter's range is never checked: PhongLobe(-1.0) builds a lobe with a negative density"),
    M("declared-range-ignored-when-traced", "jaxsample/samplers/base.py",
      "        return declared_ranges_hold(self)",
      "        return None",
      ("tests/samplers/test_declarations.py", "-k", "outside or users_declared"),
      "a traced parameter outside its declared range returns finite numbers instead of NaN"),
    M("open-bound-taken-as-closed", "jaxsample/_core/pytree.py",
      "        return in_range(value, self.low, self.high, low_open=self.low_open, high_open=self.high_open)",
      "        return in_range(value, self.low, self.high)",
      ("tests/samplers/test_declarations.py", "-k", "outside"),
      "a cone of h = 0 (an empty cap) or a rate of 0 passes the traced check and divides by zero"),
    M("undeclared-attributes-dropped-from-the-tree", "jaxsample/_core/pytree.py",
      "    if extra:",
      "    if False:",
      ("tests/samplers/test_declarations.py", "-k", "subclass_keeps"),
      "a subclass's own attribute set in its __init__ disappears after a flatten/unflatten round trip"),
    M("declared-rank-ignored", "jaxsample/samplers/base.py",
      "    declared = {name: spec.rank for name, spec in parameters(obj).items()}",
      "    declared = {}",
      ("tests/samplers/test_declarations.py", "-k", "users_declared"),
      "a batch of a user's declared parameter is taken whole: batch_shape () and one distribution"),
    M("samplers-not-frozen", "jaxsample/_core/pytree.py",
      "        if vars(self).get(_FROZEN):",
      "        if False:",
      ("tests/samplers/test_declarations.py", "-k", "frozen"),
      "UniformCone's parameters can be reassigned after construction, past its checks"),
    M("checked-mark-set-on-the-users-object", "jaxsample/samplers/base.py",
      "    if result is sampler:\n        leaves, treedef",
      "    if False:\n        leaves, treedef",
      ("tests/samplers/test_declarations.py", "-k", "checked_copy"),
      "checking marks the user's own sampler, changing its tree structure (a recompile) after first use"),
    M("domain-measure-wrong", "jaxsample/samplers/domain.py",
      '    event_shape = (3,)\n    measure = "solid angle"',
      '    event_shape = (3,)\n    measure = "area"',
      ("tests/samplers/test_declarations.py", "-k", "domain"),
      "a user's directional sampler that states no measure is said to be over area"),
    M("invalid-traced-parameter-not-poisoned", "jaxsample/samplers/base.py",
      "            return leaf * (1 + poison.astype(leaf_dtype))\n        return leaf",
      "            return leaf\n        return leaf",
      ("tests/samplers/test_keys_batches_names.py", "-k", "traced_invalid"),
      "an invalid traced parameter gives finite values and gradients"),
    M("invalid-parameter-outputs-not-poisoned", "jaxsample/samplers/base.py",
      "return _poison_outputs(method(sampler, point, *args, **kwargs), poison)",
      "return method(sampler, point, *args, **kwargs)",
      ("tests/samplers/test_declarations.py", "-k", "outside"),
      "a density written where(inside, ..., 0) reports 0, not NaN, for an invalid traced parameter"),
    M("mis-measures-unchecked", "jaxsample/estimators/mis.py",
      "if len(measures) != 1:",
      "if False:",
      ("tests/estimators/test_batched_and_invalid.py::test_mis_refuses_samplers_of_different_event_shapes_or_measures",),
      "estimate_mis adds densities over different measures"),
    M("batched-estimate-reordered", "jaxsample/estimators/plain.py",
      "lambda leaf: leaf.reshape(batch + leaf.shape[1:]), result)",
      "lambda leaf: leaf[::-1].reshape(batch + leaf.shape[1:]), result)",
      ("tests/estimators/test_batched_and_invalid.py::test_a_batched_estimate_is_vmap_over_the_batch",),
      "a batched Estimate's members are not in the batch's order"),
    M("string-parameter-accepted", "jaxsample/_core/params.py",
      'if kind not in "iuf":',
      "if False:",
      ("tests/samplers/test_keys_batches_names.py", "-k", "not_a_number"),
      "a string parameter is accepted at construction and fails later"),
    # ---- the report's verdicts: time to a given error (issue 17) ----
    M("verdict-interpolation-takes-the-later-point", "jaxsample/report/verdicts.py",
      "log_t = math.log(t[j - 1]) + fraction * (math.log(t[j]) - math.log(t[j - 1]))",
      "log_t = math.log(t[j])",
      ("tests/report/test_verdicts.py::test_time_to_target_on_a_pure_inverse_sqrt_curve_is_the_known_time",),
      "the time to a target is the next measured point's, not the log-log interpolation"),
    M("verdict-interpolation-linear-axes", "jaxsample/report/verdicts.py",
      "fraction = (math.log(target) - log_e0) / (log_e1 - log_e0)",
      "fraction = (target - e[j - 1]) / (e[j] - e[j - 1])",
      ("tests/report/test_verdicts.py::test_time_to_target_on_a_pure_inverse_sqrt_curve_is_the_known_time",),
      "the crossing is interpolated on linear error axes instead of log-log"),
    M("verdict-time-error-ignores-slope", "jaxsample/report/verdicts.py",
      "return Time(math.exp(log_t), \"=\", rmse_relative_error(n_keys) / abs(rate))",
      "return Time(math.exp(log_t), \"=\", rmse_relative_error(n_keys))",
      ("tests/report/test_verdicts.py::test_time_to_target_on_a_pure_inverse_sqrt_curve_is_the_known_time",),
      "a time's error is the RMSE's 1/sqrt(2k), not divided by |slope| (2x too small at n^-1/2)"),
    M("verdict-rmse-error-1-over-sqrt-k", "jaxsample/report/verdicts.py",
      "return 1.0 / math.sqrt(2.0 * n_keys)",
      "return 1.0 / math.sqrt(n_keys)",
      ("tests/report/test_verdicts.py::test_rmse_relative_error_is_one_over_sqrt_2k_and_rejects_bad_key_counts",),
      "an RMSE over k keys said to carry 1/sqrt(k) instead of 1/sqrt(2k)"),
    M("verdict-extrapolates-past-the-floor", "jaxsample/report/verdicts.py",
      "    for j in range(1, end + 1):",
      "    for j in range(1, len(t)):",
      ("tests/report/test_verdicts.py::test_a_floor_cuts_the_curve_for_the_time_to_target",),
      "a noisy point past the floor counts as reaching a target below the floor"),
    M("verdict-floor-any-later-point", "jaxsample/report/verdicts.py",
      "if np.all(log_r[i] - log_r[i + 1:] < z * sd):",
      "if np.any(log_r[i] - log_r[i + 1:] < z * sd):",
      ("tests/report/test_verdicts.py::test_floor_is_found_at_the_first_point_that_stops_falling",),
      "a floor where any later point (not every one) fails to fall: floors everywhere"),
    M("verdict-floor-one-step", "jaxsample/report/verdicts.py",
      "FLOOR_CONFIRM = 2 ",
      "FLOOR_CONFIRM = 1 ",
      ("tests/report/test_verdicts.py::test_one_flat_step_at_the_end_is_not_a_floor",),
      "one flat step (4 % likely for a falling curve over 16 keys) taken for a floor"),
    M("verdict-floor-no-tolerance", "jaxsample/report/verdicts.py",
      "sd = math.sqrt(2.0) * rmse_relative_error(n_keys)",
      "sd = 0.0 * rmse_relative_error(n_keys)",
      ("tests/report/test_verdicts.py::test_floor_detection_tolerates_the_noise_the_keys_allow",),
      "floor detection ignores the keys' uncertainty: a floor with noise is missed"),
    M("verdict-exact-at-any-n", "jaxsample/report/verdicts.py",
      "return bool(np.all(rmse <= ulps * ulp))",
      "return bool(np.any(rmse <= ulps * ulp))",
      ("tests/report/test_verdicts.py::test_exact_is_detected_from_the_curve_at_every_n",),
      "\"exact\" when the RMSE is at rounding level at one n (a floored strategy), not at every n"),
    M("verdict-slope-error-from-residuals-only", "jaxsample/report/verdicts.py",
      "sigma = max(sigma, math.sqrt(float(np.sum(residual**2)) / (x.size - 2)))",
      "sigma = math.sqrt(float(np.sum(residual**2)) / (x.size - 2))",
      ("tests/report/test_verdicts.py::test_slope_is_fitted_before_the_floor_with_a_standard_error_the_keys_allow",),
      "a slope's standard error smaller than the keys allow (zero on a clean power law)"),
    M("verdict-speedup-one-error", "jaxsample/report/verdicts.py",
      "return Ratio(value, math.hypot(slow.rel_err, fast.rel_err), \"=\")",
      "return Ratio(value, slow.rel_err, \"=\")",
      ("tests/report/test_verdicts.py::test_speedup_carries_both_errors_and_bounds",),
      "a speed-up carries one time's error instead of both in quadrature"),
    M("verdict-no-ties", "jaxsample/report/verdicts.py",
      "TIE_Z = 2.0 ",
      "TIE_Z = 0.0 ",
      ("tests/report/test_verdicts.py::test_best_ranks_exact_first_names_ties_and_can_be_none",),
      "a runner-up within the keys' uncertainty of the best is not named as tied"),
    M("verdict-non-qmc-is-qmc", "jaxsample/report/verdicts.py",
      "if kinds[name] != QMC})",
      "if kinds[name] == QMC})",
      ("tests/report/test_verdicts.py::test_verdict_names_the_best_non_qmc_and_both_speedups",),
      "the best non-QMC strategy chosen among the QMC ones"),
    M("verdict-study-ignores-floor", "jaxsample/report/convergence.py",
      "floor = None if exact else V.floor_index(rmse, n_keys)",
      "floor = None",
      ("tests/report/test_verdicts.py::test_add_verdicts_reads_exact_floor_slope_and_times_off_a_row",),
      "the study fits slopes and reads times through floors"),
    M("verdict-baseline-not-the-flagged-one", "jaxsample/report/convergence.py",
      "baseline = next(r[\"strategy\"] for r in group if r[\"baseline\"])",
      "baseline = group[-1][\"strategy\"]",
      ("tests/report/test_verdicts.py::test_headline_table_from_synthetic_rows",),
      "speed-ups taken over the last strategy, not the integrand's baseline"),
    M("strategy-kind-sobol-not-qmc", "jaxsample/report/convergence.py",
      "        if self.uniforms == \"sobol\":\n            return V.QMC",
      "        if self.uniforms == \"sobol\":\n            return \"stratified\"",
      ("tests/report/test_verdicts.py::test_strategy_kind_comes_from_its_definition",),
      "Sobol' strategies coloured and ranked as stratified"),
    # ---- integrands: pytrees and complex values (issue 14, item 4) ----
    M("integrand-complex-parts-swapped", "jaxsample/estimators/integrand.py",
      "part = jax.lax.complex(part, imaginary)",
      "part = jax.lax.complex(imaginary, part)",
      ("tests/estimators/test_integrands.py::test_each_leaf_has_the_statistics_of_its_components",
       "tests/estimators/test_integrands.py::test_a_complex_integral_is_right_part_by_part"),
      "a complex leaf's real and imaginary statistics come back swapped"),
    M("integrand-conjugated", "jaxsample/estimators/integrand.py",
      "parts.extend([jnp.real(value), jnp.imag(value)] if leaf.is_complex else [value])",
      "parts.extend([jnp.real(value), -jnp.imag(value)] if leaf.is_complex else [value])",
      ("tests/estimators/test_integrands.py::test_a_complex_integral_is_right_part_by_part",),
      "the complex integrand is averaged as its conjugate (a wrong integral with honest error bars)"),
    M("integrand-leaf-offset-ignored", "jaxsample/estimators/integrand.py",
      "part = packed[..., leaf.start:leaf.start + leaf.size]",
      "part = packed[..., 0:leaf.size]",
      ("tests/estimators/test_integrands.py::test_each_leaf_has_the_statistics_of_its_components",),
      "every leaf is read from the start of the packed vector (the first leaf's statistics everywhere)",
      count=2),
    M("until-complex-per-part", "jaxsample/estimators/integrand.py",
      "pieces.extend([modulus, modulus])",
      "pieces.extend([jnp.abs(part), jnp.abs(imaginary)])",
      ("tests/estimators/test_integrands.py::test_estimate_until_measures_a_complex_leaf_by_its_modulus",),
      "estimate_until compares each part of a complex leaf with rtol times that part (never met for a "
      "purely imaginary integral)"),
    M("ratio-stack-axis", "jaxsample/estimators/variance_reduction.py",
      "return jnp.stack([y, z, y + z], axis=1)",
      "return jnp.stack([y, z, y + z], axis=-1)",
      ("tests/estimators/test_integrands.py::test_each_leaf_has_the_statistics_of_its_components",),
      "the (Y, Z, Y + Z) triple stacked on the last axis: right for a scalar f, mixed components for a pytree"),
    M("grad-accepts-pytree", "jaxsample/estimators/gradient_errors.py",
      'require_real(integrand_layout(fn, sampler, flat.dtype, owner), owner, "make(params)[0]",',
      '(integrand_layout(fn, sampler, flat.dtype, owner), owner, "make(params)[0]",',
      ("tests/estimators/test_integrands.py::test_integrands_an_estimator_cannot_take_raise_a_type_error",),
      "estimate_grad takes a pytree integrand and fails deep inside (KeyError) instead of a clear TypeError"),
    # ---- n and 64-bit sample indices (issue 14, item 5) ----
    M("philox-high-word-dropped", "jaxsample/uniforms/philox.py",
      "high = jnp.zeros_like(low) if block.hi is None else block.hi",
      "high = jnp.zeros_like(low)",
      ("tests/uniforms/test_large_index.py::test_the_point_past_2_to_the_33_is_the_one_its_counter_formula_gives",),
      "the counter's high word is dropped: past 2^32 blocks the stream repeats its beginning"),
    M("random-lanes-high-word", "jaxsample/uniforms/sources.py",
      "first = index_range(floordiv(as_index(offset, count), g), count // g)",
      "first = index_range(floordiv(Index(None, as_index(offset, count).lo), g), count // g)",
      ("tests/uniforms/test_large_index.py::test_lanes_at_a_64_bit_offset_are_the_block_points",),
      "the lanes the estimators read lose the offset's high word (they differ from block past 2^32)"),
    M("engine-offsets-narrow", "jaxsample/estimators/engine.py",
      "wide = total > NARROW_LIMIT",
      "wide = False",
      ("tests/uniforms/test_large_index.py::test_the_streaming_loop_carries_its_offset_across_2_to_the_33",),
      "the streaming loop keeps uint32 chunk offsets (the old wrap at 2^32)"),
    M("offset-product-in-32-bits", "jaxsample/uniforms/index.py",
      "return _from_u64(_to_u64(base) + product)",
      "return Index(None, base.lo + _u32(step) * _u32(stride))",
      ("tests/uniforms/test_large_index.py::test_index_arithmetic_matches_python_integers",
       "tests/uniforms/test_large_index.py::test_the_streaming_loop_carries_its_offset_across_2_to_the_33"),
      "base + step x stride computed in uint32: chunk offsets and device bases wrap at 2^32"),
    M("index-value-low-word", "jaxsample/uniforms/index.py",
      "return _to_u64(index).astype(dtype)",
      "return index.lo.astype(dtype)",
      ("tests/uniforms/test_large_index.py::test_index_arithmetic_matches_python_integers",),
      "a stratum index past 2^32 is converted to a float from its low word only"),
    M("sobol-high-index-bits-ignored", "jaxsample/uniforms/sobol.py",
      "words = [(index.lo, 0)] + ([(index.hi, 32)] if index.wide else [])",
      "words = [(index.lo, 0)]",
      ("tests/uniforms/test_large_index.py::test_the_point_past_2_to_the_33_is_the_one_its_counter_formula_gives",
       "tests/uniforms/test_large_index.py::test_sobol_points_past_2_to_the_32_continue_the_joe_kuo_sequence"),
      "Sobol' points past 2^32 per replicate repeat the first 2^32"),
    M("finish-n-as-int", "jaxsample/estimators/engine.py",
      "n = float(count)",
      "n = count",
      ("tests/uniforms/test_large_index.py::test_estimators_take_n_up_to_2_to_the_40",),
      "n beyond 2^31 in array arithmetic (OverflowError of JAX's weak int32)"),
    M("traced-n-unexplained", "jaxsample/_core/counts.py",
      "if isinstance(value, jax.core.Tracer):",
      "if False:",
      ("tests/uniforms/test_large_index.py::test_bad_n_raises_a_clear_error",),
      "a traced n fails with JAX's conversion error, which does not say to make n static"),
    M("bool-n-accepted", "jaxsample/_core/counts.py",
      'if isinstance(value, (bool, np.bool_)) or (hasattr(value, "dtype") and np.dtype(value.dtype) == np.bool_):',
      "if False:",
      ("tests/uniforms/test_large_index.py::test_bad_n_raises_a_clear_error",),
      "True is taken as the count 1"),
    M("mesh-base-32-bit", "jaxsample/estimators/engine.py",
      "base = offset_at(0, device.astype(jnp.uint32), per_device, n > NARROW_LIMIT)",
      "base = device.astype(jnp.uint32) * jnp.uint32(per_device)",
      ("tests/uniforms/test_large_index.py::test_estimators_take_n_up_to_2_to_the_40",),
      "the device-mesh path keeps 32-bit device bases (it cannot take n past 2^32 per device)"),
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
    M("contract-disk-quadrature", "jaxsample/domains.py",
      "weights = 0.5 * np.multiply.outer(ws, wphi).ravel()",
      "weights = 0.5 * np.multiply.outer(ws, 1.1 * wphi).ravel()",
      ("tests/samplers/test_contract.py", "-k", "chi_square_goodness and UniformDisk-polar"),
      "the disk's chi-square cells expect 10 % too many samples"),
    M("sampler-imports-check-geometry", "jaxsample/samplers/phong.py",
      "from .domain import Directions",
      "from ..domains import Directions",
      ("tests/checks/test_frame_and_checks.py::test_importing_a_sampler_does_not_import_the_checks_geometry",),
      "a sampler imports the checks' quadrature and binning again"),
    M("quadrature-bounds-unchecked", "jaxsample/quadrature.py",
      "concrete = concrete_value(value)  # float64, or None when traced (then it cannot be checked)",
      "concrete = None",
      ("tests/test_quadrature.py",),
      "concrete bounds are treated as traced: reversed or infinite bounds are no longer rejected"),
    # ---- eager calls run as one compiled program (issue 13: suite time; speed of eager calls) ----
    M("estimate-not-compiled-eagerly", "jaxsample/estimators/plain.py",
      '@compiled_entry("f", "n", "uniforms", "mode", "mesh", "chunk_size", "dtype")\n',
      "",
      ("tests/estimators/test_compiled_entry.py::test_a_repeated_eager_estimate_compiles_nothing",
       "tests/estimators/test_compiled_entry.py::test_a_repeated_eager_gradient_compiles_nothing"),
      "estimate runs op by op again: ~40 programs on the first call, its loop recompiled on every call"),
    M("entry-key-not-normalized", "jaxsample/_core/entry.py",
      'arguments["key"] = as_key(arguments["key"], fn.__name__)',
      'arguments["key"] = arguments["key"]',
      ("tests/estimators/test_compiled_entry.py::test_the_usual_errors_come_through",),
      "an int key reaches the compiled program and fails with a tracer's message instead of the key rule's"),
    # ---- diagnostics on every estimate: k-hat, nonzero values, the stderr floor, t intervals ----
    M("khat-without-prior", "jaxsample/estimators/diagnostics.py",
      "shrunk = (n_used * xi_hat + _PRIOR_WEIGHT * _PRIOR_SHAPE) / (n_used + _PRIOR_WEIGHT)", "shrunk = xi_hat",
      ("tests/estimators/test_diagnostics.py::test_khat_of_exact_generalized_pareto_quantiles",),
      "k-hat without PSIS's weakly informative prior: the fit disagrees with the stated estimator"),
    M("tail-merge-drops-second", "jaxsample/estimators/diagnostics.py",
      "jnp.maximum(jnp.minimum(a1, b1), jnp.maximum(a2, b2))", "jnp.maximum(a2, b2)",
      ("tests/estimators/test_diagnostics.py::test_tail_state_holds_the_largest_values",),
      "merging two bins' top-two lists loses the smaller of the two maxima"),
    M("tail-not-merged-over-chunks", "jaxsample/estimators/engine.py",
      "merge_tails(a.tail, b.tail)", "b.tail",
      ("tests/estimators/test_diagnostics.py::test_streamed_khat_is_the_fit_to_the_samples_averaged",),
      "the streamed tail keeps only the last chunk's values"),
    M("verdict-ignores-khat", "jaxsample/estimators/diagnostics.py",
      "return finite & enough & ~heavy", "return finite & enough",
      ("tests/estimators/test_diagnostics.py::test_infinite_variance_and_divergent_integrals_are_flagged",),
      "an infinite-variance estimate is called reliable"),
    M("verdict-any-nonzero", "jaxsample/estimators/diagnostics.py",
      "enough = count >= required_nonzero(n) - 0.5", "enough = count > 0",
      ("tests/estimators/test_diagnostics.py::test_a_handful_of_nonzero_values_is_flagged",),
      "an estimate resting on a handful of nonzero samples is called reliable"),
    M("verdict-zero-gradient", "jaxsample/estimators/diagnostics.py",
      "enough = enough | (count == 0)", "enough = enough",
      ("tests/estimators/test_diagnostics.py::test_gradient_components_that_are_exactly_zero_are_not_flagged",),
      "a gradient component that is exactly 0 (a parameter f ignores) is flagged"),
    M("no-stderr-floor", "jaxsample/estimators/engine.py",
      "stderr = jnp.maximum(stderr, stderr_floor(m.sum_abs, n))", "stderr = stderr",
      ("tests/estimators/test_diagnostics.py::test_zero_variance_stderr_is_floored_at_rounding",),
      "a zero-variance estimate reports a stderr below its own rounding (z in the hundreds)"),
    M("normal-interval-for-replicates", "jaxsample/estimators/result.py",
      "    if replicates <= 1:\n        return _normal_quantile", "    if True:\n        return _normal_quantile",
      ("tests/estimators/test_diagnostics.py::test_replicate_intervals_cover_at_their_level",),
      "replicate intervals at 1.96 instead of Student's t: coverage 88-94 %"),
    M("no-eager-warning", "jaxsample/_core/entry.py",
      "warn_if_unreliable(result, fn.__name__)", "result = result",
      ("tests/estimators/test_diagnostics.py::test_an_unreliable_eager_estimate_warns_and_a_jitted_one_does_not",),
      "an eager unreliable estimate is returned silently"),
    M("until-khat-dropped", "jaxsample/estimators/until.py",
      "verdict(self.mean, self.stderr, self.khat, self.nonzero, self.n_used)",
      "verdict(self.mean, self.stderr, -jnp.inf * self.khat, self.nonzero, self.n_used)",
      ("tests/estimators/test_diagnostics.py::test_estimate_until_carries_the_same_verdict",),
      "estimate_until's verdict ignores its tail"),
    M("vmf-far-t-from-log1p", "jaxsample/samplers/vmf.py",
      "jnp.where(far, 2.0 - direct, t)", "t",
      ("tests/samplers/test_directional.py::test_vmf_far_hemisphere_direction_and_density_agree",),
      "beyond the equator the VMF direction and its density disagree by 8e-4 (found by k-hat)"),
    # ---- boundary terms: gradients when a parameter moves an edge (issue 23) ----
    M("boundary-term-dropped", "jaxsample/estimators/boundary.py",
      "total = total + weight * speed.reshape(speed.shape + (1,) * (weight.ndim - 1))",
      "total = total + 0.0 * weight * speed.reshape(speed.shape + (1,) * (weight.ndim - 1))",
      ("tests/estimators/test_boundary.py::test_cap_solid_angle_derivative_is_exact_with_zero_variance",),
      "a masked integrand's gradient in the edge's parameters is 0 ± 0 again"),
    M("boundary-sampler-flow-ignored", "jaxsample/estimators/boundary.py",
      "flows = () if flow is None else (flow,)", "flows = ()",
      ("tests/estimators/test_boundary.py::test_attached_samples_that_move_across_a_fixed_edge",),
      "attached samples sliding over a fixed rim as n changes: d/dn of a fixed integral is not 0"),
    M("boundary-outside-support-counted", "jaxsample/estimators/boundary.py",
      "inside = (density > 0).astype(delta.dtype) if not weight_by_density else density",
      "inside = jnp.ones_like(density) if not weight_by_density else density",
      ("tests/estimators/test_boundary.py::test_cap_cut_by_the_horizon_under_cosine_sampling",),
      "the rim below the horizon counted for a cosine-sampled estimate that never sees it"),
    M("boundary-normal-inward", "jaxsample/edges/regions.py",
      "edge_normal = -side[..., None] * plane * jnp.ones_like(point)",
      "edge_normal = side[..., None] * plane * jnp.ones_like(point)",
      ("tests/estimators/test_boundary.py::test_spherical_triangle_vertex_gradient_matches_van_oosterom_strackee",),
      "a spherical polygon's edge normals point inward: its vertex gradient changes sign"),
    M("boundary-cap-arc-density", "jaxsample/edges/regions.py",
      "pdf = safe_div(INV_2PI, sin_alpha) * jnp.ones_like(t[..., 0])",
      "pdf = INV_2PI * jnp.ones_like(t[..., 0])",
      ("tests/estimators/test_boundary.py::test_cap_solid_angle_derivative_is_exact_with_zero_variance",),
      "the cap's rim density without its length: d/dα off by sin α"),
    M("shade-boundary-term-dropped", "jaxsample/scene/direct.py",
      "    _, tangent = jax.jvp(functools.partial(_boundary_surrogate, strategy, mode, exponent, rims),",
      "    _, tangent = jax.jvp(lambda *a: 0.0 * _boundary_surrogate(strategy, mode, exponent, rims, *a),",
      ("tests/scene/test_shade_gradients.py::test_every_gradient_agrees_with_the_reference",),
      "shade without the silhouette term: brdf's light gradient 0, mis 5-100 sd off (the issue's table)"),
    M("shade-brdf-flow-ignored", "jaxsample/scene/direct.py",
      "total = total + add(w_in * f_in - w_out * f_out, (self.brdf_flow,))",
      "total = total + add(w_in * f_in - w_out * f_out, ())",
      ("tests/scene/test_shade_gradients.py::test_every_gradient_agrees_with_the_reference",),
      "attached BRDF samples crossing the rim as the exponent changes: d/d log n biased"),
    M("shade-mis-weight-jump-ignored", "jaxsample/scene/direct.py",
      "w_in = mis_weight(brdf_pdf, mix_in, exponent) if strategy == \"mis\" else 1.0",
      "w_in = 1.0",
      ("tests/scene/test_shade_gradients.py::test_every_gradient_agrees_with_the_reference",),
      "the BRDF half of MIS jumps by w_b f at the rim, not f: its boundary term overcounted"),
    M("shade-other-lights-pieces-dropped", "jaxsample/scene/direct.py",
      "total = total + add(jump * pdf_k / count, (lambda wi, k=k: self.light_flow(k, wi),))",
      "total = total + 0.0 * add(jump * pdf_k / count, (lambda wi, k=k: self.light_flow(k, wi),))",
      ("tests/scene/test_shade_gradients.py::test_overlapping_lights_and_a_sky",),
      "one light's samples crossing another's rim as the lights move: the light half of MIS biased"),
    M("cone-from-sin2-plain-sqrt", "jaxsample/samplers/cone.py",
      "return cls(one_minus_cos_theta_max=s / (1.0 + safe_sqrt(1.0 - s)))",
      "return cls(one_minus_cos_theta_max=s / (1.0 + jnp.sqrt(1.0 - s)))",
      ("tests/scene/test_shade_gradients.py::test_gradients_stay_finite_at_degenerate_geometry",),
      "a point inside a sphere light: the rim term's gradient NaN (inf x 0 at the clamp)"),
    M("triangle-arc-plain-norm", "jaxsample/edges/regions.py",
      "    return jnp.arctan2(_norm(jnp.cross(a, b)), jnp.sum(a * b, axis=-1))",
      "    return jnp.arctan2(jnp.linalg.norm(jnp.cross(a, b), axis=-1), jnp.sum(a * b, axis=-1))",
      ("tests/scene/test_shade_gradients.py::test_gradients_stay_finite_at_degenerate_geometry",),
      "a viewpoint on a triangle edge's line: NaN from the norm's derivative at 0"),
    M("shade-refusal-skipped", "jaxsample/scene/direct.py",
      "    _refuse(strategy, mode, inputs[4], input_tangents[:5])", "    pass",
      ("tests/scene/test_shade_gradients.py::test_gradients_that_cannot_be_unbiased_are_refused",),
      "a biased environment-map gradient returned without a word"),
    # ---- the report draws no verdict it cannot support: slopes from 3 sizes, none in --tiny mode ----
    M("slope-from-two-sizes", "jaxsample/report/verdicts.py",
      "MIN_SLOPE_POINTS = 3 ",
      "MIN_SLOPE_POINTS = 2 ",
      ("tests/report/test_verdicts.py::test_a_slope_needs_three_sizes_and_a_time_without_one_has_no_error",
       "tests/report/test_verdicts.py::test_a_study_with_two_sizes_to_fit_draws_no_slope_and_no_verdict"),
      "a slope (and the times' errors from it) fitted through two points, which it fits exactly"),
    M("time-error-from-the-two-point-rate", "jaxsample/report/verdicts.py",
      "rate = slope if math.isfinite(slope) and slope < 0 else math.nan",
      "rate = slope if math.isfinite(slope) and slope < 0 else "
      "(log_e1 - log_e0) / (math.log(t[j]) - math.log(t[j - 1]))",
      ("tests/report/test_verdicts.py::test_a_slope_needs_three_sizes_and_a_time_without_one_has_no_error",),
      "with no fitted slope a time's error taken from the rate between the two points around the crossing"),
    M("unknown-error-ranked-as-known", "jaxsample/report/verdicts.py",
      "        elif ratio.bound == \"=\" and math.isnan(ratio.rel_err):",
      "        elif False:",
      ("tests/report/test_verdicts.py::test_an_unknown_error_names_no_single_winner",),
      "a runner-up whose ratio has no error is ranked as if it were measured: a single winner"),
    M("slope-cell-hides-too-few-sizes", "jaxsample/report/convergence.py",
      "if row[\"slope_points\"] < V.MIN_SLOPE_POINTS:",
      "if False:",
      ("tests/report/test_verdicts.py::test_a_study_with_two_sizes_to_fit_draws_no_slope_and_no_verdict",),
      "a row with too few sizes for a slope shows a bare dash instead of saying why"),
    M("tiny-headline-silent", "jaxsample/report/__init__.py",
      "    if tiny:\n        first, rest = smoke_test_headline().split(\". \", 1)",
      "    if False:\n        first, rest = smoke_test_headline().split(\". \", 1)",
      ("tests/report/test_report.py::test_in_tiny_mode_the_top_says_smoke_test_and_no_verdicts_are_drawn",),
      "the tiny report's top does not say it is a smoke test"),
    M("tiny-verdicts-drawn", "jaxsample/report/__init__.py",
      "    if tiny:\n        fitted = sum(",
      "    if False:\n        fitted = sum(",
      ("tests/report/test_report.py::test_in_tiny_mode_the_top_says_smoke_test_and_no_verdicts_are_drawn",),
      "the tiny report names winners and speed-ups from 4 keys and n <= 2^10"),
    M("tiny-paths-judged", "jaxsample/report/paths.py",
      "(\" met |\" if verdicts else \"\")",
      "\" met |\"",
      ("tests/report/test_report.py::test_in_tiny_mode_the_top_says_smoke_test_and_no_verdicts_are_drawn",),
      "the tiny path table says whether each speed target is met, from one timing round"),
    M("pointer-to-a-checkout-script", "jaxsample/report/__init__.py",
      "(run `python -m jaxsample.report.baselines`)",
      "(run `python benchmarks/baselines.py`)",
      ("tests/report/test_report.py::test_every_command_the_report_points_to_runs_after_a_plain_pip_install",),
      "the report points to a script the installed wheel does not have"),
    M("pointed-module-without-a-main", "jaxsample/report/hard_cases.py",
      "if __name__ == \"__main__\":\n    print(markdown_table(hard_case_table()))",
      "def _main():\n    print(markdown_table(hard_case_table()))",
      ("tests/report/test_report.py::test_every_command_the_report_points_to_runs_after_a_plain_pip_install",),
      "`python -m jaxsample.report.hard_cases` is pointed to but does nothing"),
    M("numpy-baseline-whole-chunks-only", "jaxsample/report/numpy_baseline.py",
      "for start in range(0, n, chunk):",
      "for start in range(0, n - n % chunk, chunk):",
      ("tests/report/test_report.py::test_the_numpy_baseline_draws_every_sample_when_n_is_not_a_multiple_of_its_chunk",),
      "the NumPy baseline drops the last partial chunk: below one chunk (--tiny's 2^16) it does no work"),
    # ---- errors in the library's words (issue 29): each refusal removed, its test must notice ----
    M("sampler-class-accepted", "jaxsample/samplers/base.py",
      "    if isinstance(value, type) and issubclass(value, Sampler):", "    if False:",
      ("tests/estimators/test_worded_errors.py::test_a_sampler_class_for_an_instance_is_named_by_every_entry_point",),
      "a sampler class for an instance: int() of a property, or JAX's abstract-array error, again"),
    M("empty-integrand-accepted", "jaxsample/estimators/integrand.py",
      "    if layout.width == 0:", "    if False:",
      ("tests/estimators/test_worded_errors.py::test_an_integrand_with_no_values_is_refused_before_it_runs",),
      "an integrand of shape (0,): a ZeroDivisionError from a reshape inside the engine"),
    M("mis-int-counts-accepted", "jaxsample/estimators/mis.py",
      'if isinstance(counts, (str, bytes)) or not hasattr(counts, "__iter__") or np.ndim(counts) == 0:', "if False:",
      ("tests/estimators/test_worded_errors.py::test_mis_counts_must_be_one_count_per_sampler",),
      "estimate_mis with one int for counts: 'int' object is not iterable"),
    M("oriented-batch-unchecked", "jaxsample/samplers/oriented.py",
      "            jnp.broadcast_shapes(base_batch, axis_batch)", "            pass",
      ("tests/estimators/test_worded_errors.py::test_an_oriented_batch_must_broadcast_with_its_normals",),
      "bases and normals whose batches cannot pair: accepted, then a broadcasting error at use"),
    M("float64-without-x64-accepted", "jaxsample/_core/params.py",
      "    if jnp.dtype(dtype) == np.float64 and default_float_dtype() != np.float64:", "    if False:",
      ("tests/estimators/test_worded_errors.py::test_float64_without_x64_is_refused_not_truncated",),
      "dtype=float64 without jax_enable_x64: warnings, then float32 in silence"),
    M("tfp-sample-refused", "jaxsample/samplers/base.py",
      "        key, sample_shape = None, key", "        pass",
      ("tests/estimators/test_worded_errors.py::test_the_tfp_spelling_of_sample_draws_the_same_points",),
      "sample((5,), seed=key), TFP's spelling, refused as a key given twice"),
    M("tiny-normal-accepted", "jaxsample/samplers/frame.py",
      "            bad = (squares < info.tiny) | (squares > info.max)", "            bad = squares > info.max",
      ("tests/estimators/test_worded_errors.py::test_a_concrete_normal_too_short_to_normalise_is_refused",),
      "a normal of length 1e-30: accepted, and n·n underflows to 0 in float32 (a NaN frame)"),
    M("user-inverse-called-no-bijection", "jaxsample/samplers/base.py",
      "    if library:", "    if True:",
      ("tests/estimators/test_worded_errors.py::test_a_user_sampler_without_inverse_is_not_told_its_warp_is_not_a_bijection",),
      "a user's sampler without inverse told that its warp is not a bijection"),
    # ---- Henyey–Greenstein, Gaussians, tent, linear, bilinear (jaxsample issue 24, part 3) ----
    M("hg-negative-g-cancels", "jaxsample/samplers/henyey_greenstein.py",
      "one_plus_g - g * rest)      # 1 + gξ", "1.0 + g * xi)      # 1 + gξ",
      ("tests/samplers/test_phase_and_simple.py::test_hg_warp_matches_exact_rational_arithmetic_at_the_hard_g",),
      "1 + gξ formed directly for g < 0: it cancels as g -> -1, ξ -> 1 (same value in exact arithmetic)"),
    M("hg-negative-g-wrong-denominator", "jaxsample/samplers/henyey_greenstein.py",
      "one_plus_g - 2.0 * g * rest)", "one_plus_g + 2.0 * g * rest)",
      ("tests/samplers/test_phase_and_simple.py::test_hg_pathwise_derivative_matches_a_float64_quadrature_derivative",
       "tests/samplers/test_phase_and_simple.py::test_hg_warp_and_its_derivative_are_continuous_through_g_zero"),
      "D = 1 - g + 2gξ with the wrong sign of the 1 - ξ term for g < 0: a wrong warp, a jump at g = 0"),
    M("hg-density-from-u", "jaxsample/samplers/henyey_greenstein.py",
      "return x, d * d * d / (4.0 * np.pi * s * s)", "return x, d * d / (4.0 * np.pi * s * s)",
      ("tests/samplers/test_phase_and_simple.py::test_hg_warp_matches_exact_rational_arithmetic_at_the_hard_g",),
      "warp_with_pdf's density D²/(4π(1 - g²)²) instead of D³/(...)"),
    M("normal-erfinv-of-2u-minus-1", "jaxsample/samplers/normal.py",
      "        return ndtri(u0)", "        return np.sqrt(2.0) * jax.scipy.special.erfinv(2.0 * u0 - 1.0)",
      ("tests/samplers/test_phase_and_simple.py::test_normal_tails_are_finite_and_accurate_in_float32",),
      "the quantile as √2 erf⁻¹(2u - 1): forming 2u - 1 rounds the lower tail away (0.8 % at u = 7e-8)"),
    M("normal-quadrature-half-line", "jaxsample/samplers/normal.py",
      "quadrature_low=float(breaks[0])", "quadrature_low=float(loc)",
      ("tests/samplers/test_phase_and_simple.py::test_normal_moments_by_quadrature_and_through_the_warp",),
      "the checks' rule for the real line starts at the mean: half the mass"),
    M("linear-textbook-root", "jaxsample/samplers/polynomial.py",
      "x = jnp.where(nonzero, (a + b) * u / jnp.where(nonzero, denominator, 1.0), 0.0)", "x = (weight - a) / (b - a)",
      ("tests/samplers/test_phase_and_simple.py::test_linear_tends_to_the_uniform_as_a_tends_to_b",
       "tests/samplers/test_phase_and_simple.py::test_linear_quantile_against_bisection_of_the_closed_form_cdf"),
      "the linear density's quantile by the textbook root: 0/0 at a = b, cancellation as a -> b"),
    M("tent-mirrored", "jaxsample/samplers/polynomial.py",
      "return self.radius * (2.0 * u0 - 1.0) / (1.0 + w), w / self.radius",
      "return self.radius * (1.0 - 2.0 * u0) / (1.0 + w), w / self.radius",
      ("tests/samplers/test_phase_and_simple.py::test_tent_cdf_in_closed_form",),
      "the tent's warp mirrored (the same distribution, but not the inverse of its CDF)"),
    M("bilinear-transposed-corners", "jaxsample/samplers/polynomial.py",
      "return (1.0 - y) * w00 + y * w01, (1.0 - y) * w10 + y * w11",
      "return (1.0 - y) * w00 + y * w10, (1.0 - y) * w01 + y * w11",
      ("tests/samplers/test_phase_and_simple.py::test_bilinear_marginal_and_conditional_cdfs_in_closed_form",),
      "the conditional's end weights taken with the corners transposed (w10 and w01 swapped)"),
    M("linear-zero-weights-traced", "jaxsample/samplers/polynomial.py",
      "return _all_of(super()._parameters_valid(), positive)", "return super()._parameters_valid()",
      ("tests/samplers/test_phase_and_simple.py::test_invalid_parameters_raise_and_traced_ones_give_nan",),
      "Linear(0, 0) under jit: finite samples of a density that is 0 everywhere, not NaN"),
    # ---- issue 30: options and error bars that had no test of their own ----
    M("until-atol-ignored", "jaxsample/estimators/until.py",
      'tolerance = jnp.maximum(atol_, rtol_ * layout.magnitudes(statistics["mean"]))',
      'tolerance = rtol_ * layout.magnitudes(statistics["mean"])',
      ("tests/estimators/test_until.py::test_an_absolute_tolerance_alone_stops_the_stream",),
      "estimate_until ignores atol: an atol-only request never converges and spends max_n"),
    M("until-min-n-ignored", "jaxsample/estimators/until.py",
      "max_steps, min_steps = max_n // step, min_n // step",
      "max_steps, min_steps = max_n // step, 8",
      ("tests/estimators/test_until.py::test_min_n_holds_the_stream_past_a_met_tolerance",),
      "estimate_until ignores min_n (always the default 8 chunks)"),
    M("replicate-stderr-not-over-r", "jaxsample/estimators/engine.py",
      "stderr = safe_sqrt(jnp.sum(spread * spread, axis=0) / (replicates - 1) / replicates)",
      "stderr = safe_sqrt(jnp.sum(spread * spread, axis=0) / (replicates - 1))",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[until-sobol]",
       "tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[estimate-grad-sobol]"),
      "the replicates' stderr is their spread, not divided by sqrt(R) (4x too large for R = 16), in "
      "estimate_until and in gradients"),
    M("iid-stderr-for-replicates", "jaxsample/estimators/engine.py",
      "if replicates == 1:", "if True:",
      ("tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[estimate-grad-sobol]",
       "tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[estimate-grad-stratified]",
       "tests/estimators/test_calibration.py::test_stderr_matches_the_spread_of_estimates_over_keys[expectation-grad-score-sobol]"),
      "the gradient's stderr taken as sqrt(s^2/n) whatever the source (Sobol' and stratified points "
      "are not independent: their error is far smaller)"),
    M("mis-variance-square", "jaxsample/estimators/mis.py",
      "variance=float(total) * stderr * stderr,", "variance=float(total) * stderr,",
      ("tests/estimators/test_calibration.py::test_mis_variance_is_per_evaluation_at_the_calibrated_stderr",),
      "estimate_mis's per-evaluation variance missing a square of the stderr"),
    M("lanes-dot-batch-zero", "jaxsample/_core/lanes.py",
      "total = lax.add(total, term(lhs_m[b + i + (c,)], rhs_m[b + j + (c,)]))",
      "total = lax.add(total, term(lhs_m[b + i + (c,)], rhs_m[(0,) * nb + j + (c,)]))",
      ("tests/_core/test_lanes.py::test_lane_map_equals_vmap",),
      "a batched dot_general on lanes reads the right-hand side's batch 0 for every term after the first "
      "(einsum('bij,bj->bi') wrong)"),
    M("lanes-transpose-inverse", "jaxsample/_core/lanes.py",
      'return _rearranged(eqn, inputs[0].cells.transpose(eqn.params["permutation"]))',
      'return _rearranged(eqn, inputs[0].cells.transpose(np.argsort(eqn.params["permutation"])))',
      ("tests/_core/test_lanes.py::test_lane_map_equals_vmap",),
      "a transpose on lanes applied with the inverse permutation (the same for 2 axes, wrong for 3)"),
    M("lanes-concatenate-axis-0", "jaxsample/_core/lanes.py",
      'return _rearranged(eqn, np.concatenate(cells, axis=eqn.params["dimension"]))',
      'return _rearranged(eqn, np.concatenate(cells, axis=0))',
      ("tests/_core/test_lanes.py::test_lane_map_equals_vmap",),
      "a concatenation on lanes always joined along axis 0 (an hstack of blocks wrong)"),
    # ---- microfacet distributions and their lobes (issue 24, part 1) ----
    M("ggx-d-wrong-power", "jaxsample/samplers/microfacet_ggx.py",
      "-jnp.log(np.pi * ax * ay) - 2.0 * jnp.log(q)", "-jnp.log(np.pi * ax * ay) - 1.9 * jnp.log(q)",
      ("tests/samplers/test_microfacet.py::test_projected_normal_distribution_integrates_to_one",),
      "GGX's D with (...)^-1.9 for (...)^-2: ∫ D cos θ is no longer 1"),
    M("ggx-g1-wrong", "jaxsample/samplers/microfacet_ggx.py",
      "        return safe_div(2.0, z + h)", "        return safe_div(2.0, z + 1.01 * h)",
      ("tests/samplers/test_microfacet.py::test_weak_white_furnace",),
      "GGX's G1 1 % off at grazing: the visible normals no longer project to cos θo"),
    M("ggx-g2-uncorrelated", "jaxsample/samplers/microfacet_ggx.py",
      "safe_div(2.0 * zo * zi, zi * ho + zo * hi)", "safe_div(4.0 * zo * zi, (zo + ho) * (zi + hi))",
      ("tests/samplers/test_microfacet.py::test_lambda_g1_and_g2_match_their_closed_forms",),
      "separable G1(wo) G1(wi) where the height-correlated G2 is documented"),
    M("beckmann-g2-term-dropped", "jaxsample/samplers/microfacet_beckmann.py",
      "                       + zo * si * jnp.exp(-ai * ai))", "                       )",
      ("tests/samplers/test_microfacet.py::test_lambda_g1_and_g2_match_their_closed_forms",),
      "Beckmann's G2 without wi's masking tail term"),
    M("beckmann-newton-one-step", "jaxsample/samplers/microfacet_beckmann.py",
      "_NEWTON_STEPS = 6", "_NEWTON_STEPS = 1",
      ("tests/samplers/test_microfacet.py::test_beckmann_visible_slope_inversion_reaches_its_floor",),
      "the visible-slope inversion stopped after two Newton steps instead of seven"),
    M("beckmann-implicit-derivative-dropped", "jaxsample/samplers/microfacet_beckmann.py",
      "    return jnp.minimum(x - step, cut_c)", "    return jax.lax.stop_gradient(jnp.minimum(x - step, cut_c))",
      ("tests/samplers/test_contract.py::test_density_is_one_over_the_jacobian_of_the_warp[VisibleNormals-Beckmann]",),
      "the Beckmann visible slope without its implicit-function derivative (zero in u, α and wo)"),
    M("ggx-cap-height", "jaxsample/samplers/microfacet_ggx.py",
      "        hz = k * (1.0 - u0)", "        hz = 2.0 * (1.0 - u0)",
      ("tests/samplers/test_contract.py::test_density_is_one_over_the_jacobian_of_the_warp[VisibleNormals-GGX]",),
      "the cap's height as at normal incidence, (c + wh)_z = 2 (1 - u₀): wrong for every tilted wo"),
    M("microfacet-stretch-not-differentiated", "jaxsample/samplers/microfacet.py",
      "        return _normalized(_stack(ax * w[..., 0], ay * w[..., 1], w[..., 2]))",
      "        return jax.lax.stop_gradient(_normalized(_stack(ax * w[..., 0], ay * w[..., 1], w[..., 2])))",
      ("tests/samplers/test_microfacet.py::test_pathwise_roughness_derivative_of_the_ggx_albedo",),
      "the stretched wo held constant: same samples and densities, a biased pathwise d/dα"),
    M("microfacet-no-flip-below-horizon", "jaxsample/samplers/microfacet.py",
      "        sign = jnp.where(wo[..., 2] < 0, -1.0, 1.0).astype(wo.dtype)",
      "        sign = jnp.ones_like(wo[..., 2])",
      ("tests/samplers/test_microfacet.py::test_wo_below_the_horizon_is_the_surface_seen_from_the_other_side",),
      "wo below the horizon used as is: the cap and the slopes of a wo the surface cannot see"),
    M("reflection-jacobian-quarter-dropped", "jaxsample/samplers/microfacet.py",
      "jnp.log(0.25 * d._g1_over_cos(wo_up))", "jnp.log(0.5 * d._g1_over_cos(wo_up))",
      ("tests/samplers/test_contract.py::test_normalization_within_1e_6[MicrofacetReflection-GGX]",),
      "the reflection's density with 1/(2 wo·m) for 1/(4 wo·m): it integrates to 2"),
    # ---- end microfacet ----
    # ---- rough conductor, quad light, solid-angle light sampling (jaxsample issue 24, the scene side) ----
    M("conductor-fresnel-rp-sign", "jaxsample/scene/rough_conductor.py",
      "r_p = safe_div((e_r * c - a) ** 2 + (e_i * c - b) ** 2,", "r_p = safe_div((e_r * c - a) ** 2 + (e_i * c + b) ** 2,",
      ("tests/scene/test_rough_conductor_and_quad.py::test_conductor_fresnel_closed_forms",),
      "R_p's numerator with Im(η² c − z) as e_i c + b: right for a dielectric (b = 0), wrong for a metal"),
    M("conductor-fresnel-cancelling-root", "jaxsample/scene/rough_conductor.py",
      "    a = jnp.where(w_r >= 0, big, small)", "    a = safe_sqrt(0.5 * (modulus + w_r))",
      ("tests/scene/test_rough_conductor_and_quad.py::test_conductor_fresnel_in_float32_against_complex_arithmetic",),
      "Re √(η² − sin²θ) by the textbook (|w| + Re w)/2, which cancels for a metal (Re w < 0)"),
    M("ggx-masking-heights-swapped", "jaxsample/scene/rough_conductor.py",
      "masking = safe_div(0.5, zi * height(wo) + zo * height(wi))",
      "masking = safe_div(0.5, zo * height(wo) + zi * height(wi))",
      ("tests/scene/test_rough_conductor_and_quad.py::test_brdf_is_d_g2_f_over_four_cosines_reciprocal_and_zero_below",),
      "G2 / (4 cos θo cos θi) with each height beside its own cosine (still reciprocal, wrong off the normal)"),
    M("full-d-reflection-jacobian", "jaxsample/scene/rough_conductor.py",
      "-safe_log(4.0 * jnp.abs(cosine))", "-safe_log(2.0 * jnp.abs(cosine))",
      ("tests/scene/test_rough_conductor_and_quad.py::test_brdf_sampler_density_is_its_jacobian_and_inverse_round_trips",),
      "the full-D reflection's density with dω_h/dω_i = 1/(2 |ω_o·h|)"),
    M("quad-silhouette-three-corners", "jaxsample/scene/quad_light.py",
      "return SphericalPolygon(self.vertices() - jnp.asarray(point))",
      "return SphericalPolygon(self.vertices()[:3] - jnp.asarray(point))",
      ("tests/scene/test_rough_conductor_and_quad.py::test_roughness_and_quad_corner_gradients_match_the_reference",),
      "the quad's silhouette as the triangle of three corners: a boundary term along a diagonal, none on two edges"),
    M("quad-rim-density", "jaxsample/scene/quad_light.py",
      "pdf = jnp.broadcast_to(1.0 / jnp.asarray(self.sampler(point).solid_angle, dtype), shape)",
      "pdf = jnp.broadcast_to(4.0 / jnp.asarray(self.sampler(point).solid_angle, dtype), shape)",
      ("tests/scene/test_rough_conductor_and_quad.py::test_roughness_and_quad_corner_gradients_match_the_reference",),
      "the light density just inside the rim 4/Ω: the boundary term's jump of the MIS weights is wrong"),
    M("quad-area-density-cosine", "jaxsample/scene/quad_light.py",
      "return wi, safe_div(distance2, area * jnp.abs(cos_light)), cos_light",
      "return wi, safe_div(distance2, area), cos_light",
      ("tests/scene/test_rough_conductor_and_quad.py::test_quad_light_checks_and_its_two_densities", "tests/scene/test_rough_conductor_and_quad.py::test_every_strategy_and_sampling_is_unbiased"),
      "area sampling's density without the cosine of the area-to-solid-angle Jacobian"),
    M("quad-reference-cosine", "jaxsample/scene/reference.py",
      "weights = area * np.outer(w_s, w_r).ravel() * np.abs(cos_light) / distance2",
      "weights = area * np.outer(w_s, w_r).ravel() / distance2",
      ("tests/scene/test_rough_conductor_and_quad.py::test_every_strategy_and_sampling_is_unbiased",),
      "the quad's reference quadrature without the cosine of dω = |cos θ_l| dA / d²"),
    M("triangle-solid-angle-rim-density", "jaxsample/scene/triangle_light.py",
      "pdf = jnp.broadcast_to(safe_div(1.0, jnp.asarray(omega, dtype)), jnp.shape(wi)[:-1])",
      "pdf = jnp.broadcast_to(safe_div(4.0, jnp.asarray(omega, dtype)), jnp.shape(wi)[:-1])",
      ("tests/scene/test_shade_gradients.py::test_every_gradient_agrees_with_the_reference[triangle-mis-attached]",),
      "the triangle light's density just inside its rim 4/Ω under solid-angle sampling (the default)"),
    M("roughness-fit-wrong-component", "jaxsample/report/inverse_problem.py",
      'gradient[:, CONDUCTOR_QUAD_PARAMETERS.index("log_alpha")]', "gradient[:, 1]",
      ("tests/scene/test_rough_conductor_and_quad.py::test_roughness_fit_recovers_alpha",),
      "the roughness fit follows ∂L/∂corner_y instead of ∂L/∂log α"),
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
