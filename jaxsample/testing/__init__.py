"""Layer 6: the public statistical checks that users can run on their own samplers — chi-square
goodness of fit, normalization by quadrature, inverse and Jacobian consistency — and the geometry
they integrate over and bin on (`jaxsample.domains`)."""

from .sampler_checks import (Chi2Result, chi2_test, inverse_error, jacobian_error, normalization, pdf_float64,
                             surface_jacobian, to_float64)

__all__ = ["Chi2Result", "chi2_test", "normalization", "inverse_error", "jacobian_error", "surface_jacobian",
           "pdf_float64", "to_float64"]
