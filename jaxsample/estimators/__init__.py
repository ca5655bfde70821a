"""Layers 4 and 5: estimators — ∫ f dμ as the mean of f(x)/p(x) with its standard error, on one
streaming engine (`engine.run_stream`: constant memory, counter-based uniforms, jit/vmap/grad and a
device mesh); MIS and variance reduction (`variance_reduction`); gradients (`gradients`)."""

from . import gradients
from .engine import DEFAULT_CHUNK_SIZE, Estimate, estimate, integrand_values, run_stream
from .gradients import expectation, expectation_values
from .variance_reduction import estimate_antithetic, estimate_control_variate, estimate_mis, estimate_ratio

__all__ = [
    "Estimate", "estimate", "integrand_values", "run_stream", "DEFAULT_CHUNK_SIZE", "estimate_mis",
    "estimate_ratio", "estimate_antithetic", "estimate_control_variate", "expectation", "expectation_values",
    "gradients",
]
