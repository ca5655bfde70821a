"""Layer 7, the scene: only what one shading point needs (docs/design.md).

BRDFs (`Lambertian`, `Phong`, `RoughConductor`) work in the local shading frame (normal +z) and have
`eval`, `sample` and `pdf`; colours (albedo, η, k, radiance) are scalars or one value per channel
(`jaxsample.scene.colour`); lights (`ConstantSky`, `SphereLight`, `SphereLights`: many spheres as one
batch, `TriangleLight`, `QuadLight`, `EnvironmentMap`) work in world space and have
`sample(point, u) -> (ω, L, p)`, `pdf(point, ω)`, `radiance_from(point, ω)` and `sampler(point)` (a
`jaxsample.Sampler` of directions, for the statistical checks; a batch of lights has none). `shade`
estimates the outgoing radiance by BRDF sampling, light sampling or MIS; `reference_radiance`
gives the float64 quadrature value the tests hold it to. No ray tracer, no occlusion, no images.
"""

from .environment import EnvironmentDirections, EnvironmentMap
from .lambertian import Lambertian
from .phong import Phong, reflect
from .quad_light import QuadLight, QuadLightDirections
from .reference import reference_radiance
from .rough_conductor import (CONDUCTOR_RGB, FullNormalsReflection, RoughConductor, fresnel_conductor,
                              fresnel_schlick, normal_incidence_reflectance)
from .direct import STRATEGIES, mis_weight, shade, shade_grad
from .sky import ConstantSky
from .sphere_light import SphereLight
from .sphere_lights import SphereLights
from .triangle_light import TriangleLight, TriangleLightDirections

__all__ = [
    "Lambertian", "Phong", "reflect", "RoughConductor", "FullNormalsReflection", "CONDUCTOR_RGB",
    "fresnel_conductor", "fresnel_schlick", "normal_incidence_reflectance",
    "ConstantSky", "SphereLight", "SphereLights", "TriangleLight", "TriangleLightDirections", "QuadLight",
    "QuadLightDirections",
    "EnvironmentMap", "EnvironmentDirections",
    "shade", "shade_grad", "mis_weight", "STRATEGIES", "reference_radiance",
]
