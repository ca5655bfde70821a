"""jaxsample: differentiable Monte Carlo sampling for JAX.

Samplers are immutable pytrees with `warp`, `pdf`, `log_pdf`, `inverse`, `sample` and
`sample_with_pdf`; each class's docstring states the measure its density is over. Estimators turn
them into integrals with standard errors under `jit`, `vmap`, `grad` and a device mesh.

The folders are the layers (docs/design.md): `_core` (numerics, pytrees, parameter checks),
`uniforms`, `samplers`, `estimators`, `edges` (discontinuities and their boundary terms), `testing`
(the public checks), `domains` (the checks' geometry), `quadrature`, `scene` and `report`
(`python -m jaxsample report`).

`__all__` is what a newcomer needs: the samplers, the estimators, `Estimate` and the modules. The
rest is reachable through its module (`js.samplers.RejectionInfo`, `js.estimators.EstimateUntil`,
`js.estimators.GuaranteedEstimate`,
`js.estimators.integrand_values`, `js.estimators.expectation_values`); `Frame`,
`UnreliableEstimateWarning` and the pieces for writing a sampler of one's own (`Pytree`,
`static_field`, `point_method`) are also attributes here, outside `__all__`.
"""

from . import edges, estimators, numerics, quadrature, samplers, scene, uniforms
from .estimators import (Estimate, estimate, estimate_antithetic, estimate_control_variate, estimate_grad,
                         estimate_guaranteed, estimate_mis, estimate_ratio, estimate_resampled, estimate_until,
                         expectation, expectation_grad)
from .samplers import (CosineHemisphere, Discrete, Exponential, Mixture, Oriented, PhongLobe, PiecewiseConstant1D,
                       PiecewiseConstant2D, PiecewiseLinear2D, Power, Rejection, Sampler, Transformed,
                       TruncatedExponential, UniformBox, UniformCone, UniformDisk, UniformHemisphere, UniformSphere,
                       UniformTriangle, VonMisesFisher, parameter)
from .samplers import (Bilinear, CatmullRom1D, CatmullRom2D, HenyeyGreenstein, Hierarchical2D, Linear, Normal,
                       Normal2D, SmoothStep, Tent, TrimmedLogistic)
from .samplers import CosineSphericalTriangle, SphericalRectangle, SphericalTriangle
from .samplers import SummedAreaTable, WindowedPiecewiseConstant2D
from .samplers import GGX, Beckmann, MicrofacetReflection, VisibleNormals

# The attributes outside `__all__` that the docstring names, re-exported explicitly (`name as name`).
from .estimators import UnreliableEstimateWarning as UnreliableEstimateWarning
from .samplers import Frame as Frame, Pytree as Pytree, point_method as point_method, static_field as static_field

__version__ = "0.1.0"

# The checks, their geometry and the adapters load on first use (`js.testing`, `js.domains`,
# `js.adapters`), so that a program that only samples and estimates never imports them.
_ON_FIRST_USE = ("adapters", "domains", "testing")


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
    "VonMisesFisher", "Oriented",
    # planar, one-dimensional, discrete and tabulated samplers
    "UniformDisk", "UniformTriangle", "UniformBox", "Exponential", "TruncatedExponential", "Power",
    "Discrete", "PiecewiseConstant1D", "PiecewiseConstant2D", "PiecewiseLinear2D", "Hierarchical2D",
    "CatmullRom1D", "CatmullRom2D", "SummedAreaTable", "WindowedPiecewiseConstant2D",
    # phase function, Gaussians, low-order polynomial and other smooth 1-D densities
    "HenyeyGreenstein", "Normal", "Normal2D", "Tent", "Linear", "Bilinear", "SmoothStep", "TrimmedLogistic",
    # microfacet normal distributions and the lobes built on them
    "GGX", "Beckmann", "VisibleNormals", "MicrofacetReflection",
    # solid-angle sampling of the triangles and rectangles a point sees
    "SphericalTriangle", "CosineSphericalTriangle", "SphericalRectangle",
    # generic constructions
    "Rejection", "Transformed", "Mixture",
    # writing your own: the base class and its parameter declarations
    "Sampler", "parameter",
    # estimators and their result
    "Estimate", "estimate", "estimate_mis", "estimate_ratio", "estimate_antithetic",
    "estimate_control_variate", "estimate_until", "estimate_guaranteed", "estimate_resampled",
    # gradients
    "expectation", "estimate_grad", "expectation_grad",
    # modules
    "samplers", "estimators", "domains", "edges", "numerics", "quadrature", "scene", "testing", "uniforms",
    "adapters",
]
