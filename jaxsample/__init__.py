"""jaxsample: differentiable Monte Carlo sampling for JAX.

Samplers are immutable pytrees with `warp`, `pdf`, `log_pdf`, `inverse`, `sample` and
`sample_with_pdf`; each class's docstring states the measure its density is over. Estimators turn
them into integrals with standard errors under `jit`, `vmap`, `grad` and a device mesh.
"""

from . import domains, gradients, numerics, quadrature, scene, testing, uniforms
from ._base import Sampler
from .box import UniformBox
from .cone import UniformCone
from .cosine import CosineHemisphere
from .discrete import Discrete
from .disk import UniformDisk
from .estimate import Estimate, estimate, integrand_values
from .estimators import estimate_antithetic, estimate_control_variate, estimate_mis, estimate_ratio
from .gradients import expectation, expectation_values
from .gradient_errors import estimate_grad, expectation_grad
from .until import EstimateUntil, estimate_until
from .exponential import Exponential, TruncatedExponential
from .frame import Frame
from .mixture import Mixture
from .oriented import Oriented
from .phong import PhongLobe
from .piecewise import PiecewiseConstant1D, PiecewiseConstant2D
from .power import Power
from .rejection import Rejection, RejectionInfo
from .sphere import UniformHemisphere, UniformSphere
from .transformed import Transformed
from .triangle import UniformTriangle
from .vmf import VonMisesFisher

__version__ = "0.1.0"

__all__ = [
    # directional samplers (density over solid angle)
    "UniformSphere", "UniformHemisphere", "CosineHemisphere", "PhongLobe", "UniformCone",
    "VonMisesFisher", "Oriented", "Frame",
    # planar, one-dimensional, discrete and tabulated samplers
    "UniformDisk", "UniformTriangle", "UniformBox", "Exponential", "TruncatedExponential", "Power",
    "Discrete", "PiecewiseConstant1D", "PiecewiseConstant2D",
    # generic constructions
    "Rejection", "RejectionInfo", "Transformed", "Mixture", "Sampler",
    # estimators
    "Estimate", "estimate", "estimate_mis", "estimate_ratio", "estimate_antithetic",
    "estimate_control_variate", "integrand_values", "estimate_until", "EstimateUntil",
    # gradients
    "expectation", "expectation_values", "estimate_grad", "expectation_grad",
    # modules
    "domains", "gradients", "numerics", "quadrature", "scene", "testing", "uniforms",
]
