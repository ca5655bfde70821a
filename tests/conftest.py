"""Test-wide settings: XLA's CPU compiler options, JAX's key-reuse checker, a deterministic hypothesis
profile, the second tier's `slow` marks, and the order in which the longest tests reach the workers."""

import os

# The suite compiles thousands of programs, most of them once, so compile time dominates it. Two XLA
# options compile them faster and leave the values the tests look at unchanged:
# - `--xla_cpu_use_fusion_emitters=false`: fusions are compiled by XLA's LLVM elemental emitters
#   rather than by the MLIR fusion emitters, XLA's default.
# - `--xla_backend_optimization_level=1`: LLVM at level 1 rather than XLA's default 3 (XLA's own HLO
#   passes, fusion included, run at any level). Level 0 is not used: without LLVM's instruction
#   selection fusing multiplies and adds, `sample` and `sample_with_pdf` round differently, and the
#   tests that hold them bit-equal fail; at level 1 they stay equal.
# JAXSAMPLE_TEST_XLA_DEFAULTS=1 runs the suite on XLA's defaults instead, as users compile. The flags
# must be set before JAX creates its backend. The timings behind both choices are in this file's git
# log (`git log tests/conftest.py`).
if not os.environ.get("JAXSAMPLE_TEST_XLA_DEFAULTS"):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_cpu_use_fusion_emitters=false --xla_backend_optimization_level=1").strip()

import jax  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

from tiers import in_second_tier, read_second_tier  # noqa: E402

# Keys are never reused; the checker turns a reuse into an error.
jax.config.update("jax_debug_key_reuse", True)

settings.register_profile(
    "ci",
    derandomize=True,
    deadline=None,
    max_examples=12,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
settings.load_profile("ci")

# pytest-xdist hands tests to its workers in collection order, so a long test collected last can
# leave one worker running alone at the end. These (each over ~5 s on the 2-core machine, most of
# it subprocesses and compilation) are collected first; the order of the rest is unchanged.
LONG_TESTS_FIRST = (
    "tests/report/test_report.py::test_tiny_report",
    "tests/test_readme.py::test_readme_blocks_run_outside_the_checkout",
    "tests/estimators/test_multiprocess.py",
    "tests/estimators/test_gradient_errors.py::test_leave_one_out_gradient_and_its_error_bar",
    "tests/estimators/test_estimate.py::test_sharded_matches_single_device_in_subprocess",
    "tests/scene/test_scene.py::test_exponent_gradient_is_finite_and_agrees_between_modes",
    "tests/scene/test_scene.py::test_a_short_inverse_problem_run_reduces_the_loss",
    "tests/scene/test_scene.py::test_every_strategy_is_unbiased",
    "tests/samplers/test_one_dimensional.py::test_zero_bins_never_sampled",
)


def pytest_collection_modifyitems(config, items):
    # The second tier: the tests `tests/second_tier.txt` names (made by `tests/tiers.py` from measured
    # times) are marked `slow`; the README's test command runs the rest, `.ci/run` both.
    listed = read_second_tier()
    for item in items:
        if in_second_tier(item.nodeid, listed):
            item.add_marker(pytest.mark.slow)

    def rank(item):
        return next((i for i, prefix in enumerate(LONG_TESTS_FIRST) if item.nodeid.startswith(prefix)),
                    len(LONG_TESTS_FIRST))

    items.sort(key=rank)  # stable: within a rank, collection order
