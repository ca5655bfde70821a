"""jaxsample: differentiable Monte Carlo sampling for JAX.

Samplers are immutable pytrees with `warp`, `pdf`, `log_pdf`, `inverse`, `sample` and
`sample_with_pdf`; see `../shared/design.md` for the contract and each class for its measure.
"""

from . import numerics, testing
from ._base import Sampler
from .cone import UniformCone
from .cosine import CosineHemisphere
from .frame import Frame
from .oriented import Oriented
from .phong import PhongLobe
from .sphere import UniformHemisphere, UniformSphere
from .vmf import VonMisesFisher

__version__ = "0.1.0"

__all__ = [
    "CosineHemisphere",
    "Frame",
    "Oriented",
    "PhongLobe",
    "Sampler",
    "UniformCone",
    "UniformHemisphere",
    "UniformSphere",
    "VonMisesFisher",
    "numerics",
    "testing",
]
