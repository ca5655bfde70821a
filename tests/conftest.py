"""Test-wide settings: a deterministic hypothesis profile and JAX's key-reuse checker."""

import jax
from hypothesis import HealthCheck, settings

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
