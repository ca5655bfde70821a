"""Layers 4 and 5: estimators — ∫ f dμ as the mean of f(x)/p(x) with its standard error, on one
streaming engine (`engine.run_stream`: constant memory, counter-based uniforms, jit/vmap/grad and a
device mesh); the result type (`result.Estimate`); the plain estimator (`plain`); MIS (`mis`) and
variance reduction (`variance_reduction`); gradients (`gradients`), gradients with their standard
errors (`gradient_errors`), resampled importance sampling and its reservoir
(`resampling`), estimates to a requested accuracy (`until`), with a guaranteed error
bound from lattices and nets (`guaranteed`) and the diagnostics every
estimate carries (`diagnostics`)."""

from . import diagnostics, gradients
from .diagnostics import UnreliableEstimateWarning
from .engine import DEFAULT_CHUNK_SIZE, run_stream
from .gradient_errors import estimate_grad, expectation_grad
from .gradients import expectation, expectation_values
from .guaranteed import GuaranteedEstimate, estimate_guaranteed
from .mis import estimate_mis
from .plain import estimate, integrand_values
from .resampling import Reservoir, estimate_resampled
from .result import Estimate
from .until import EstimateUntil, estimate_until
from .variance_reduction import estimate_antithetic, estimate_control_variate, estimate_ratio

__all__ = [
    "Estimate", "estimate", "integrand_values", "run_stream", "DEFAULT_CHUNK_SIZE", "estimate_mis",
    "estimate_ratio", "estimate_antithetic", "estimate_control_variate", "expectation", "expectation_values",
    "gradients", "estimate_grad", "expectation_grad", "estimate_until", "EstimateUntil", "estimate_guaranteed",
    "GuaranteedEstimate", "estimate_resampled", "Reservoir",
    "diagnostics", "UnreliableEstimateWarning",
]
