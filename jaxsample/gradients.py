"""Gradient estimators (public name of `jaxsample.estimators.gradients`)."""

from .estimators.gradients import expectation, expectation_values

__all__ = ["expectation", "expectation_values"]
