"""jaxsample: differentiable Monte Carlo sampling for JAX.

Samplers are immutable pytrees with `warp`, `pdf`, `log_pdf`, `inverse`, `sample` and
`sample_with_pdf`; each class's docstring states the measure its density is over. Estimators turn
them into integrals with standard errors under `jit`, `vmap`, `grad` and a device mesh.

The folders are the layers (docs/design.md): `_core` (numerics, pytrees, parameter checks),
`uniforms`, `samplers`, `estimators`, `edges` (discontinuities and their boundary terms), `testing`
(the public checks), `quadrature`, `scene` and `report` (`python -m jaxsample report`). The public names are the ones below.
"""

from . import edges, numerics, quadrature, scene, uniforms
from .estimators import (Estimate, EstimateUntil, UnreliableEstimateWarning, estimate, estimate_antithetic, estimate_control_variate,
                         estimate_grad, estimate_mis, estimate_ratio, estimate_until, expectation,
                         expectation_grad, expectation_values, integrand_values)
from .samplers import (CosineHemisphere, Discrete, Exponential, Frame, Mixture, Oriented, PhongLobe,
                       PiecewiseConstant1D, PiecewiseConstant2D, Power, Pytree, Rejection, RejectionInfo, Sampler,
                       Transformed, parameter, point_method, static_field, TruncatedExponential, UniformBox, UniformCone, UniformDisk,
                       UniformHemisphere, UniformSphere, UniformTriangle, VonMisesFisher)

__version__ = "0.1.0"

# The checks and their geometry load on first use (`js.testing`, `js.domains`), so that a program
# that only samples and estimates never imports them.
_ON_FIRST_USE = ("domains", "testing")


def __getattr__(name):
    if name in _ON_FIRST_USE:
        import importlib
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_ON_FIRST_USE))

__all__ = [
    # directional samplers (density over solid angle)
    "UniformSphere", "UniformHemisphere", "CosineHemisphere", "PhongLobe", "UniformCone",
    "VonMisesFisher", "Oriented", "Frame",
    # planar, one-dimensional, discrete and tabulated samplers
    "UniformDisk", "UniformTriangle", "UniformBox", "Exponential", "TruncatedExponential", "Power",
    "Discrete", "PiecewiseConstant1D", "PiecewiseConstant2D",
    # generic constructions
    "Rejection", "RejectionInfo", "Transformed", "Mixture",
    # writing your own: the base classes, parameter declarations, per-point methods
    "Sampler", "Pytree", "parameter", "static_field", "point_method",
    # estimators
    "Estimate", "estimate", "estimate_mis", "estimate_ratio", "estimate_antithetic",
    "estimate_control_variate", "integrand_values", "estimate_until", "EstimateUntil",
    "UnreliableEstimateWarning",
    # gradients
    "expectation", "expectation_values", "estimate_grad", "expectation_grad",
    # modules
    "domains", "edges", "numerics", "quadrature", "scene", "testing", "uniforms",
]
