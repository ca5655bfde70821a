"""Layer 3: samplers — warps from [0, 1)^d onto a domain, each beside its density and inverse.

`Sampler` (in `base`) is the public base class: a subclass is a pytree without registration
(`Pytree`), declares its parameters' ranges with `parameter(low, high)`, and may decorate its
per-point methods with `point_method` (batched and checked). One file per family; each class's
docstring states the measure its density is over.
"""

from .._core.pytree import Pytree, parameter, static_field
from .base import Sampler, point_method
from .catmull_rom import CatmullRom1D, CatmullRom2D
from .box import UniformBox
from .cone import UniformCone
from .cosine import CosineHemisphere
from .discrete import Discrete
from .disk import UniformDisk
from .exponential import Exponential, TruncatedExponential
from .frame import Frame
from .henyey_greenstein import HenyeyGreenstein
from .hierarchical import Hierarchical2D
from .mixture import Mixture
from .microfacet import MicrofacetDistribution, MicrofacetReflection, VisibleNormals
from .microfacet_beckmann import Beckmann
from .microfacet_ggx import GGX
from .normal import Normal, Normal2D
from .oriented import Oriented
from .phong import PhongLobe
from .piecewise import PiecewiseConstant1D, PiecewiseConstant2D
from .piecewise_linear import PiecewiseLinear2D
from .polynomial import Bilinear, Linear, Tent
from .power import Power
from .ramps import SmoothStep, TrimmedLogistic
from .rejection import Rejection, RejectionInfo
from .sphere import UniformHemisphere, UniformSphere
from .spherical_rectangle import SphericalRectangle
from .summed_area import SummedAreaTable, WindowedPiecewiseConstant2D
from .spherical_triangle import CosineSphericalTriangle, SphericalTriangle
from .transformed import Transformed
from .triangle import UniformTriangle
from .vmf import VonMisesFisher

__all__ = [
    "Sampler", "Pytree", "parameter", "static_field", "point_method", "UniformSphere", "UniformHemisphere",
    "CosineHemisphere", "PhongLobe", "UniformCone",
    "VonMisesFisher", "Oriented", "Frame", "UniformDisk", "UniformTriangle", "UniformBox", "Exponential",
    "TruncatedExponential", "Power", "Discrete", "PiecewiseConstant1D", "PiecewiseConstant2D", "PiecewiseLinear2D",
    "Hierarchical2D", "CatmullRom1D", "CatmullRom2D", "SummedAreaTable",
    "WindowedPiecewiseConstant2D", "Rejection",
    "RejectionInfo", "Transformed", "Mixture",
    "HenyeyGreenstein", "Normal", "Normal2D", "Tent", "Linear", "Bilinear", "SmoothStep", "TrimmedLogistic",
    "GGX", "Beckmann", "MicrofacetDistribution", "VisibleNormals", "MicrofacetReflection",
    "SphericalTriangle", "CosineSphericalTriangle", "SphericalRectangle",
]
