"""Every sampler the package exports, listed once with its hard cases: the contract suite
(`test_contract.py`) runs every check on every entry, so a new sampler gets them all by being
added here (and `test_every_exported_sampler_is_in_the_registry` fails until it is).

An entry builds its sampler from parameters with a module-level function (`make(*params)`), which
the gradient check calls inside `jit` with traced parameters: one compilation per entry and dtype
serves every case. A parameter may be any pytree (a prebuilt sampler too, for a table that must be
built from concrete values); its floating leaves are what the derivatives are taken in.

Chi-square family: the chi-square tests of the contract (one per case that takes part) form one
family run at an overall false-failure rate of 1e-6 (Šidák: each test at 1 - (1 - 1e-6)^(1/N),
N = `N_CHI2_TESTS`). The family files show a wrong sampler rejected at the same settings
(`chi2_settings`): the sample size, cells and threshold of the entry it imitates.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample.samplers.domain import Box, Directions, Disk

FAMILY_SIGNIFICANCE = 1e-6
F32_LAST = 1.0 - 2.0 ** -24
EDGE_VALUES = (0.0, 0.5, F32_LAST)


@dataclasses.dataclass(frozen=True)
class Case:
    """One parameter set. `x64`: checked in float64 only (thin triangles, Power(1e6), whose
    samples float32 cannot resolve). `chi2`, `inverse`, `gradients`, `samples`: which checks it
    takes part in (a table of 10^6 entries has no business in a Jacobian over its weights)."""

    params: tuple
    x64: bool = False
    chi2: bool = True
    inverse: bool = True
    gradients: bool = True
    samples: bool = True


@dataclasses.dataclass(frozen=True)
class Inverse:
    """Round trip u -> warp -> inverse on `n` uniform points in [margin, 1 - margin] (plus the
    edge rows when `edges`), max |error| below `tol32` in float32 and `tol64` in float64 (None:
    that precision is not checked); Jacobian |p(T(u)) J(u) - 1| below `jacobian32`/`jacobian64`
    on points in [jacobian_margin, 1 - jacobian_margin] (away from the horizon, where J -> inf)."""

    tol32: float | None
    tol64: float | None = None
    jacobian32: float | None = None
    jacobian64: float | None = None
    margin: float = 1e-3
    edges: bool = False
    n: int = 2048
    jacobian_margin: float = 1e-3


@dataclasses.dataclass(frozen=True)
class Entry:
    name: str
    make: Callable
    cases: tuple
    points: np.ndarray          # where pdf and log_pdf (and their derivatives) are checked: in, on and outside
                                # the support
    chi2_samples: int = 100_000
    chi2_cells: int = 64
    chi2_pilot: int = 20_000
    inverse: Inverse | None = None
    pdf_rtol: float = 2e-5      # pdf(x) against the density sample_with_pdf returns, in float32
    pdf_rtol64: float = 1e-12   # and in float64 (the x64 cases)
    positive_at_edges: bool = True  # p > 0 at every edge u (directions may have p = 0 at the horizon)
    gradients64: bool = True    # the gradient check in float64 too (not only float32)

    def build(self, case: Case, dtype=None):
        return self.make(*cast_params(case.params, dtype))

    def chi2_cases(self):
        return [c for c in self.cases if c.chi2]


def cast_params(params, dtype=None):
    """Numbers and lists of numbers as arrays of `dtype` (default: float32, or float64 under x64),
    a prebuilt sampler with its floating leaves in `dtype`; Python ints (static: `tries`) kept."""

    def cast(value):
        if isinstance(value, js.Sampler):
            return jax.tree_util.tree_map(cast, value)
        if isinstance(value, (bool, int, np.integer)):
            return value
        array = np.asarray(value)
        return jnp.asarray(array, dtype) if np.issubdtype(array.dtype, np.floating) else value

    return tuple(cast(p) for p in params)


# ---------------------------------------------------------------------------------------------
# Constructors (module level: one compilation per constructor; values vary, not shapes).
# ---------------------------------------------------------------------------------------------

def sphere():
    return js.UniformSphere()


def sphere_rejection():
    return js.UniformSphere(method="rejection")


def sphere_equal_area():
    return js.UniformSphere(method="equal_area")


def hemisphere():
    return js.UniformHemisphere()


def cosine_malley():
    return js.CosineHemisphere()


def cosine_inversion():
    return js.CosineHemisphere(method="inversion")


def phong(n):
    return js.PhongLobe(n)


def cone(h):
    return js.UniformCone(one_minus_cos_theta_max=h)


def vmf(kappa):
    return js.VonMisesFisher(kappa)


def oriented_phong(n, normal):
    return js.Oriented(js.PhongLobe(n), normal)


def oriented_cone(h, normal):
    return js.Oriented(js.UniformCone(one_minus_cos_theta_max=h), normal)


def disk_concentric():
    return js.UniformDisk()


def disk_polar():
    return js.UniformDisk("polar")


def disk_rejection(tries):
    return js.UniformDisk("rejection", tries=tries)


def triangle(a, b, c):
    return js.UniformTriangle(a, b, c)


def box(low, high):
    return js.UniformBox(low, high)


def exponential(rate):
    return js.Exponential(rate)


def truncated(rate, t_max):
    return js.TruncatedExponential(rate, t_max)


def power(n):
    return js.Power(n)


def power_max():
    return js.Power(5, method="max")


def discrete(weights):
    return js.Discrete(weights)


def prebuilt(sampler):
    """For samplers whose tables need concrete parameters (the alias table): the sampler itself is
    the parameter pytree, and derivatives are taken in its floating leaves."""
    return sampler


def piecewise_1d(values):
    return js.PiecewiseConstant1D(values)


def piecewise_2d(values):
    return js.PiecewiseConstant2D(values)


def piecewise_linear_2d(values):
    return js.PiecewiseLinear2D(values)


def hierarchical_2d(values):
    return js.Hierarchical2D(values)


def catmull_rom_1d(nodes, values):
    return js.CatmullRom1D(nodes, values)


def windowed_2d(values, low, high):
    return js.WindowedPiecewiseConstant2D(values, low, high)


def catmull_rom_2d(alpha_nodes, nodes, values, alpha):
    return js.CatmullRom2D(alpha_nodes, nodes, values, alpha)


SPLINE_ALPHAS = [0.0, 0.4, 1.0, 1.5]
SPLINE_X = [0.0, 0.3, 0.5, 1.2, 2.0]
SPLINE_ROWS = (1.0 + 0.5 * np.sin(3.0 * np.array(SPLINE_ALPHAS)[:, None] + 2.0 * np.array(SPLINE_X)[None, :])).tolist()


def mixture_of_exponentials(weights, rate):
    return js.Mixture((js.Exponential(1.0), js.Exponential(rate)), weights)


def mixture_of_directions(weights, n1, n2):
    return js.Mixture((js.PhongLobe(n1), js.UniformHemisphere(), js.PhongLobe(n2)), weights)


def mixture_of_disks(weights):
    return js.Mixture((js.UniformDisk("polar"), js.UniformDisk("concentric")), weights)


def _disk_density(x):
    return jnp.where(jnp.sum(x * x, axis=-1) < 1.0, 1.0 / np.pi, 0.0)


def _cubic_density(x):
    return jnp.where((x >= 0) & (x <= 1), 4.0 * x ** 3, 0.0)


def rejection_disk(bound):
    """Rejection from the square [-1, 1]² with a polar fallback: exactly uniform on the disk."""
    square = js.UniformBox(-jnp.ones(2, jnp.result_type(bound)), jnp.ones(2, jnp.result_type(bound)))
    return js.Rejection(square, _disk_density, bound, tries=2, fallback=js.UniformDisk("polar"), support=Disk())


def rejection_loose(bound):
    """Three tries without a fallback: the fall-through (ε = 0.42) shows in the stated density."""
    return js.Rejection(js.Power(0.0), _cubic_density, bound, tries=3)


def _polar_forward(p):
    # (s, θ) -> sqrt(s)(cos θ, sin θ); |det J| = ½, so a uniform (s, θ) box gives 1/π.
    return jnp.sqrt(p[0]) * jnp.stack([jnp.cos(p[1]), jnp.sin(p[1])])


def _polar_inverse(y):
    return jnp.stack([jnp.sum(y * y), jnp.mod(jnp.arctan2(y[1], y[0]), 2 * np.pi)])


def _sphere_forward(p):
    # (μ, φ) -> the unit sphere; the surface Jacobian sqrt(det JᵀJ) is 1.
    sin_theta = jnp.sqrt(1.0 - p[0] ** 2)
    return jnp.stack([sin_theta * jnp.cos(p[1]), sin_theta * jnp.sin(p[1]), p[0]])


def _sphere_inverse(y):
    return jnp.stack([y[2], jnp.mod(jnp.arctan2(y[1], y[0]), 2 * np.pi)])


def transformed_polar(high):
    base = js.UniformBox(jnp.zeros(2, jnp.result_type(high)), high)
    return js.Transformed(base, _polar_forward, _polar_inverse, domain=Disk())


def transformed_exponential():
    """y = (e^{x₀}, e^{x₁}) of the unit square: p(y) = 1 / (y₀ y₁) on [1, e]², smooth on the closed box."""
    return js.Transformed(js.UniformBox(jnp.zeros(2), jnp.ones(2)), jnp.exp, jnp.log,
                          domain=Box.from_bounds([1.0, 1.0], [np.e, np.e]))


def transformed_spherical(low, high):
    return js.Transformed(js.UniformBox(low, high), _sphere_forward, _sphere_inverse, domain=Directions())


# Henyey–Greenstein, Gaussians, tent, linear, bilinear.

def henyey_greenstein(g):
    return js.HenyeyGreenstein(g)


def normal(loc, scale):
    return js.Normal(loc, scale)


def normal_2d(loc, scale):
    return js.Normal2D(loc, scale)


def tent(radius):
    return js.Tent(radius)


def linear(a, b):
    return js.Linear(a, b)


def smooth_step(low, high):
    return js.SmoothStep(low, high)


def trimmed_logistic(scale, low, high):
    return js.TrimmedLogistic(scale, low, high)


def bilinear(w):
    return js.Bilinear(w)


# Microfacet distributions (GGX, Beckmann) and their lobes.

def ggx(alpha_x, alpha_y):
    return js.GGX(alpha_x, alpha_y)


def beckmann(alpha_x, alpha_y):
    return js.Beckmann(alpha_x, alpha_y)


def ggx_visible(alpha_x, alpha_y, wo):
    return js.VisibleNormals(js.GGX(alpha_x, alpha_y), wo)


def beckmann_visible(alpha_x, alpha_y, wo):
    return js.VisibleNormals(js.Beckmann(alpha_x, alpha_y), wo)


def ggx_reflection(alpha_x, alpha_y, wo):
    return js.MicrofacetReflection(js.GGX(alpha_x, alpha_y), wo)


def beckmann_reflection(alpha_x, alpha_y, wo):
    return js.MicrofacetReflection(js.Beckmann(alpha_x, alpha_y), wo)


# ---------------------------------------------------------------------------------------------
# Fixed points and tables
# ---------------------------------------------------------------------------------------------

DIRECTION_POINTS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8],
                             [1e-4, 0.0, np.sqrt(1.0 - 1e-8)], [0.0, 0.6, -0.8]])
DISK_POINTS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, -0.5], [0.5, 0.5], [0.3, 0.0], [2.0, 0.0]])

_rng = np.random.default_rng(5)
TABLE = _rng.random(257)
TABLE[::5] = 0.0
TABLE_2D = _rng.random((24, 40))
TABLE_2D[3] = 0.0
TABLE_2D[:, 7] = 0.0
HUGE_TABLE = _rng.random(10 ** 6)
HUGE_TABLE[_rng.random(10 ** 6) < 0.3] = 0.0
GRID_WITH_ZEROS = np.random.default_rng(13).random((6, 8))
GRID_WITH_ZEROS[2, :] = 0.0
GRID_WITH_ZEROS[:, 5] = 0.0

_rng = np.random.default_rng(9)
WEIGHTS = np.array([0.0, 3.0, 1.0, 0.0, 0.5, 2.0, 0.0, 1.5])
HUGE_WEIGHTS = _rng.random(10 ** 6)
HUGE_WEIGHTS[_rng.random(10 ** 6) < 0.3] = 0.0
HUGE_WEIGHTS[:1000] = 0.0  # a leading run of zeros: u = 0 must not select them

TRIANGLE_2D = ([0.0, 0.0], [1.0, 0.2], [0.3, 1.0])
TRIANGLE_3D = ([0.0, 0.0, 1.0], [1.0, 0.2, 0.0], [0.3, 1.0, 2.0])
# Area 1e-12 of |edge|², tilted so that no coordinate axis helps.
THIN_2D = ([0.0, 0.0], [1.0, 1.0], [0.5, 0.5 + 2e-12])
THIN_3D = ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, 0.5 + 2e-12, 0.5])

TINY_CONE = 1e-8  # steradians
HAIR_OFF_MINUS_Z = (1e-7, 0.0, -1.0)  # Duff et al. 2017's branch point
TILTED_DOWN = (0.3, -0.5, -0.8)

_C = Case
_DIRECTIONAL_INVERSE = Inverse(tol32=2e-6, jacobian64=1e-6, margin=0.0, edges=True, n=4096)
_PLANAR_INVERSE = Inverse(tol32=2e-4, tol64=1e-9, jacobian32=1e-3, n=4096)
_LINE_INVERSE = Inverse(tol32=1e-4, jacobian32=1e-3, margin=1e-4, jacobian_margin=1e-4)

# Microfacet lobes: wo at cos θ_o = 1e-7 (grazing), oblique, skew to the anisotropy's axes, along the
# normal, and below the horizon (the surface seen from its other side). The grazing and oblique wo are
# turned 0.3 rad in azimuth: GGX's cap map is singular at u = (1, (φ_wo + π) / 2π) (c = -wh, where the normals
# perpendicular to wo meet; the condition number is 1 / (1 - u₀)), and for φ_wo = 0 that is an edge row
# (1 - 2^-24, 0.5), whose float32 round trip no float32 arithmetic can hold.
MICROFACET_GRAZING = (float(np.sqrt(1.0 - 1e-14) * np.cos(0.3)), float(np.sqrt(1.0 - 1e-14) * np.sin(0.3)), 1e-7)
MICROFACET_OBLIQUE = (float(0.6 * np.cos(0.3)), float(0.6 * np.sin(0.3)), 0.8)
MICROFACET_SKEW = (0.5, 0.5, float(np.sqrt(0.5)))
MICROFACET_BELOW = (0.0, 0.3, -float(np.sqrt(0.91)))
_MICROFACET_INVERSE = Inverse(tol32=5e-5, tol64=1e-9, jacobian64=1e-6, margin=0.0, edges=True, n=4096)
_MICROFACET_REFLECTION_INVERSE = dataclasses.replace(_MICROFACET_INVERSE, tol32=5e-3, tol64=1e-6)
_MICROFACET_LOBE_CASES = (
    _C((1e-4, 1e-4, MICROFACET_GRAZING)), _C((1.0, 1.0, MICROFACET_GRAZING)), _C((1.0, 1e-3, MICROFACET_SKEW)),
    _C((0.3, 0.3, MICROFACET_OBLIQUE), chi2=False), _C((1e-2, 1e-2, (0.0, 0.0, 1.0)), chi2=False),
    _C((0.3, 0.3, MICROFACET_BELOW), chi2=False))

# Solid-angle sampling of spherical triangles and rectangles: from a
# near-hemisphere (the viewer 0.05 from the plane, inside) down to 1e-8 sr, where float32 Arvo and
# Ureña formulas fail (benchmarks/float32_spherical.py).

def spherical_triangle(a, b, c):
    return js.SphericalTriangle(a, b, c)


def cosine_spherical_triangle(a, b, c, normal):
    return js.CosineSphericalTriangle(a, b, c, normal)


def spherical_rectangle(corner, edge_u, edge_v):
    return js.SphericalRectangle(corner, edge_u, edge_v)


SPHERICAL_OCTANT = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))                 # π/2 sr
SPHERICAL_HEMISPHERE = ((1.0, 0.0, -0.05), (-0.5, 0.866, -0.05), (-0.5, -0.866, -0.05))  # 5.77 sr
SPHERICAL_MEDIUM = ((0.3, -0.2, 1.0), (0.75, -0.155, 1.09), (0.39, 0.205, 0.865))       # 0.058 sr
SPHERICAL_SMALL = ((0.3, -0.2, 1.0), (0.3179, -0.19821, 1.00358), (0.30358, -0.18389, 0.99463))  # 1.0e-4 sr
SPHERICAL_TINY = ((0.3, -0.2, 1.0), (0.300179, -0.1999821, 1.0000358), (0.3000358, -0.1998389, 0.9999463))  # 1.0e-8 sr
SPHERICAL_RECTANGLE_SQUARE = ((-1.0, -1.0, 1.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0))      # 2π/3 sr
SPHERICAL_RECTANGLE_NEAR = ((-1.0, -1.5, -0.05), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0))      # 5.94 sr
SPHERICAL_RECTANGLE_SMALL = ((0.4, -0.3, 1.0), (0.0118, 0.00236, 0.00118), (-0.00236, 0.0118, 0.0))  # 1.0e-4 sr
SPHERICAL_RECTANGLE_TINY = ((0.4, -0.3, 1.0), (1.18e-4, 2.36e-5, 1.18e-5), (-2.36e-5, 1.18e-4, 0.0))  # 1.0e-8 sr
# In, on and outside the shapes above: the octant's centre, a vertex, the antipode of +z, ...
SPHERICAL_POINTS = np.array([[1.0, 1.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.3, -0.2, 1.0],
                             [-0.6, 0.0, -0.8], [0.4, -0.3, 1.0]])
SPHERICAL_POINTS = SPHERICAL_POINTS / np.linalg.norm(SPHERICAL_POINTS, axis=-1, keepdims=True)
# Round trips away from u₁ = 0 (the apex b, or the corner edge of the rectangle's sweep), where u₀ is
# not determined by the direction; the float32 tolerance is what rounding the sample costs at 1e-4 sr
# (~ε/θ) and at the near-hemisphere (the map's shear); the 1e-8 sr cases are checked in
# tests/samplers/test_spherical_polygons.py against that rounding itself.
_SPHERICAL_INVERSE = Inverse(tol32=3e-4, tol64=1e-9, jacobian32=2e-3, jacobian64=1e-8, margin=1e-3, n=2048)

ENTRIES = [
    # ---- directions (solid angle) ----
    Entry("UniformSphere", sphere, (_C(()),), DIRECTION_POINTS, 400_000, 128, 65_536, _DIRECTIONAL_INVERSE,
          positive_at_edges=False),
    Entry("UniformSphere-rejection", sphere_rejection, (_C(()),), DIRECTION_POINTS, 400_000, 128, 65_536,
          positive_at_edges=False),
    Entry("UniformSphere-equal-area", sphere_equal_area, (_C(()),), DIRECTION_POINTS, 400_000, 128, 65_536,
          _DIRECTIONAL_INVERSE, positive_at_edges=False),
    Entry("UniformHemisphere", hemisphere, (_C(()),), DIRECTION_POINTS, 400_000, 128, 65_536, _DIRECTIONAL_INVERSE,
          positive_at_edges=False),
    Entry("CosineHemisphere-malley", cosine_malley, (_C(()),), DIRECTION_POINTS, 400_000, 128, 65_536,
          _DIRECTIONAL_INVERSE, positive_at_edges=False),
    Entry("CosineHemisphere-inversion", cosine_inversion, (_C(()),), DIRECTION_POINTS, 400_000, 128, 65_536,
          _DIRECTIONAL_INVERSE, positive_at_edges=False),
    # A 2 % exponent error is rejected for every key tried at 2M samples (at 400k only for some).
    Entry("PhongLobe", phong, (_C((0.0,)), _C((1.0,)), _C((20.0,)), _C((100.0,)), _C((1e3,), chi2=False),
                               _C((1e4,), chi2=False), _C((1e7,))),
          DIRECTION_POINTS, 2_000_000, 128, 65_536, _DIRECTIONAL_INVERSE, positive_at_edges=False),
    # h = 1 - cos θ_max. Besides its own range, the caps the other constructors make at their hard
    # cases (from_solid_angle(1e-3): h = 1e-3/2π; from_sin2(0.5): h = 1 - sqrt(0.5); the rest
    # coincide with these); that their conversions have finite derivatives there is checked in
    # test_directional.py, so by the chain rule every constructor's derivatives are finite.
    Entry("UniformCone", cone, (*(_C((h,)) for h in (TINY_CONE / (2 * np.pi), 1e-6, 1e-3, 0.5, 1.0, 2.0)),
                                _C((1e-3 / (2 * np.pi),), chi2=False), _C((1.0 - np.sqrt(0.5),), chi2=False)),
          DIRECTION_POINTS, 400_000, 128, 65_536, _DIRECTIONAL_INVERSE, positive_at_edges=False),
    # κ = 88: where the textbook inverse CDF overflows in float32.
    Entry("VonMisesFisher", vmf, (_C((1e-6,)), _C((1e-2,)), _C((1.0,)), _C((88.0,), chi2=False), _C((89.0,)),
                                  _C((1e3,)), _C((1e7,))),
          DIRECTION_POINTS, 400_000, 128, 65_536, _DIRECTIONAL_INVERSE, positive_at_edges=False),
    # A rotated lobe loses ~1e-7 absolute per component in the rotation, which n = 1000 amplifies
    # in u₀ = 1 - cos^{n+1}: 5e-5 on the round trip (documented in Oriented).
    Entry("Oriented-Phong", oriented_phong,
          (_C((0.0, TILTED_DOWN)), _C((10.0, TILTED_DOWN)), _C((1e3, TILTED_DOWN)),
           *(_C((n, normal), chi2=False, inverse=False) for n in (1.0, 1e3)
             for normal in ((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), HAIR_OFF_MINUS_Z, (0.3, -0.4, 0.2)))),
          DIRECTION_POINTS, 2_000_000, 128, 65_536,
          dataclasses.replace(_DIRECTIONAL_INVERSE, tol32=5e-5), positive_at_edges=False),
    Entry("Oriented-UniformCone", oriented_cone,
          (_C((1e-3, (0.0, 0.0, -1.0))), _C((0.3, (0.0, 0.0, -1.0))), _C((1e-3, HAIR_OFF_MINUS_Z), chi2=False)),
          DIRECTION_POINTS, 400_000, 128, 65_536, _DIRECTIONAL_INVERSE, positive_at_edges=False),
    # ---- the plane (area) ----
    Entry("UniformDisk-concentric", disk_concentric, (_C(()),), DISK_POINTS, inverse=_PLANAR_INVERSE),
    Entry("UniformDisk-polar", disk_polar, (_C(()),), DISK_POINTS, inverse=_PLANAR_INVERSE),
    # `tries` is static: one compiled gradient check (tries = 3) serves the family.
    Entry("UniformDisk-rejection", disk_rejection, (_C((4,), gradients=False), _C((1,), gradients=False),
                                                     _C((3,), chi2=False)), DISK_POINTS),
    Entry("UniformTriangle-2d", triangle, (_C(TRIANGLE_2D), _C(((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)), chi2=False),
                                           _C(THIN_2D, x64=True, inverse=False, chi2=False)),
          np.array([[0.0, 0.0], [0.2, 0.2], [1.0, 0.0], [0.5, 0.5], [2.0, 2.0], [0.0, 0.5]]),
          inverse=_PLANAR_INVERSE),
    Entry("UniformTriangle-3d", triangle, (_C(TRIANGLE_3D), _C(((0.0, 0.0, 0.0), (1.0, 0.0, 0.5), (0.0, 1.0, 0.0)),
                                                               chi2=False),
                                           _C(THIN_3D, x64=True, inverse=False)),
          np.array([[0.0, 0.0, 0.0], [0.2, 0.2, 0.1], [1.0, 0.0, 0.5], [0.5, 0.5, 0.25], [2.0, 2.0, 0.0],
                    [0.0, 0.5, 0.0]]),
          inverse=_PLANAR_INVERSE),
    Entry("UniformBox", box, (_C(([-1.0, 0.5], [2.0, 0.75])),),
          np.array([[-1.0, 0.5], [0.0, 0.6], [2.0, 0.75], [3.0, 0.6], [0.0, 0.0], [0.5, 0.7]]),
          inverse=_PLANAR_INVERSE),
    # ---- the line (length) ----
    # Parametric 1-D samplers get 10^6 chi-square samples: a rate 2 % off is then rejected with
    # p < 1e-45 for every key tried (at 10^5 it passed for most keys).
    Entry("Exponential", exponential, tuple(_C((r,), chi2=r in (1e-6, 1.0, 1e6)) for r in (1e-6, 1e-2, 1.0, 1e3, 1e6)),
          np.array([0.0, 1.0, 1e-3, 1e3, -1.0, 1e7]), 1_000_000, inverse=_LINE_INVERSE),
    # Power(1e6) and TruncatedExponential(1e6, 1e-3) put their mass within 1e-5 of an end, which
    # float32 resolves only to 6e-8 (samples quantised to a few dozen values): float64 there.
    Entry("TruncatedExponential", truncated,
          (*(_C((r, 2.5), chi2=r in (1e-6, 1.0, 1e6)) for r in (1e-6, 1e-2, 1.0, 1e3, 1e6)),
           _C((1e-6, 3.0), chi2=False), _C((1.0, 1e-6), chi2=False), _C((1e6, 1e-3), x64=True, inverse=False)),
          np.array([0.0, 1e-7, 0.5, 2.5, 4.0, -1.0]), 1_000_000, inverse=_LINE_INVERSE),
    Entry("Power", power, (_C((0.0,), chi2=False), _C((0.5,)), _C((1.0,), chi2=False), _C((3.0,), chi2=False),
                           _C((1e3,)), _C((1e6,), inverse=False, chi2=False, samples=False),
                           _C((1e6,), x64=True, inverse=False)),
          np.array([0.0, 1.0, 0.5, 1e-30, 2.0, -0.5]), 1_000_000, inverse=_LINE_INVERSE,
          # (n+1) x^n at x rounded to the working precision: n ulps relative, 6e-5 at n = 1000 in
          # float32 and 1e-10 at n = 1e6 in float64.
          pdf_rtol=1e-4, pdf_rtol64=1e-9),
    Entry("Power-max", power_max, (_C(()),), np.array([0.0, 1.0, 0.5, 1e-30, 2.0, -0.5]), 1_000_000,
          positive_at_edges=False),  # u = 0 gives x = 0, where p = 6x⁵ = 0
    Entry("PiecewiseConstant1D", piecewise_1d,
          (_C((TABLE,)), _C((np.array([2.0]),), inverse=False, gradients=False),
           _C((HUGE_TABLE,), chi2=False, inverse=False, gradients=False)),
          np.array([0.0, 0.3, 1.0, 0.5, 2.0, -0.5]),
          inverse=dataclasses.replace(_LINE_INVERSE, jacobian32=None)),  # smooth within bins only
    Entry("PiecewiseConstant2D", piecewise_2d,
          (_C((TABLE_2D,)), _C((HUGE_TABLE.reshape(1000, 1000),), chi2=False, inverse=False, gradients=False)),
          np.array([[0.3, 0.6], [0.0, 0.0], [1.0, 1.0], [0.5, 0.14], [2.0, 0.5], [-0.5, 0.5]]),
          inverse=dataclasses.replace(_LINE_INVERSE, jacobian32=None)),
    # A 16 x 32 table with a zero row and column, and a single row (only x splits).
    Entry("Hierarchical2D", hierarchical_2d,
          (_C((TABLE_2D[:16, :32],)), _C((np.array([[1.0, 2.0, 0.0, 3.0]]),), gradients=False)),
          np.array([[0.3, 0.6], [0.0, 0.0], [1.0, 1.0], [0.5, 0.14], [2.0, 0.5], [-0.5, 0.5]]),
          inverse=dataclasses.replace(_LINE_INVERSE, jacobian32=None)),
    # A random grid, the smallest one (one cell), and one with a zero row and a zero column of vertices
    # (a density that falls to 0 along them, linearly).
    Entry("PiecewiseLinear2D", piecewise_linear_2d,
          (_C((TABLE_2D[:9, :13],)), _C((np.array([[1.0, 4.0], [0.5, 2.0]]),)),
           _C((GRID_WITH_ZEROS,), gradients=False)),
          np.array([[0.3, 0.6], [0.0, 0.0], [1.0, 1.0], [0.5, 0.14], [2.0, 0.5], [-0.5, 0.5]]),
          # Where the density falls to 0 its float32 Jacobian is resolved to 1e-2 only: checked in float64.
          inverse=dataclasses.replace(_PLANAR_INVERSE, jacobian32=None, jacobian64=1e-9), pdf_rtol=1e-4,
          positive_at_edges=False),
    # Uneven nodes with a peak and a dip, the two-node spline (a linear density), and a spline that falls
    # to 0 at its last node (the density is 0 there).
    Entry("CatmullRom1D", catmull_rom_1d,
          (_C(([0.0, 0.3, 0.5, 1.2, 2.0, 2.1, 3.0], [1.0, 2.0, 0.8, 1.5, 1.5, 1.2, 0.3])),
           _C(([-1.0, 1.0], [0.5, 2.0])), _C(([0.0, 1.0, 2.0, 4.0], [2.0, 1.0, 0.5, 0.0]), chi2=False)),
          np.array([0.0, 0.25, 1.2, 3.0, -1.0, 3.5]), 1_000_000, inverse=_LINE_INVERSE,
          pdf_rtol=1e-4, positive_at_edges=False),
    # The 24 x 40 table (a zero row and column) in a window whose edges cut cells, the whole square, and a
    # window 1e-3 wide inside one cell (a uniform density; in float64, as float32 resolves x there only to
    # 3e-8 / 1e-3 = 3e-5 of u).
    Entry("WindowedPiecewiseConstant2D", windowed_2d,
          (_C((TABLE_2D, [0.13, 0.2], [0.71, 0.93])), _C((TABLE_2D, [0.0, 0.0], [1.0, 1.0]), chi2=False),
           _C((TABLE_2D, [0.301, 0.502], [0.302, 0.503]), chi2=False, x64=True)),
          np.array([[0.3, 0.6], [0.13, 0.2], [0.71, 0.93], [0.5, 0.14], [2.0, 0.5], [-0.5, 0.5]]),
          inverse=dataclasses.replace(_LINE_INVERSE, jacobian32=None)),
    # A smooth positive table, conditioned between rows, on the first row and on the last.
    Entry("CatmullRom2D", catmull_rom_2d,
          (_C((SPLINE_ALPHAS, SPLINE_X, SPLINE_ROWS, 0.7)), _C((SPLINE_ALPHAS, SPLINE_X, SPLINE_ROWS, 0.0), chi2=False),
           _C((SPLINE_ALPHAS, SPLINE_X, SPLINE_ROWS, 1.5), chi2=False)),
          np.array([0.0, 0.25, 1.2, 2.0, -1.0, 2.5]), 1_000_000, inverse=_LINE_INVERSE, pdf_rtol=1e-4),
    # ---- finite sets (counting) ----
    Entry("Discrete-cdf", discrete, (_C((WEIGHTS,)), _C((np.array([2.5]),), gradients=False),
                                     _C((np.ones(1),), gradients=False),
                                     _C((HUGE_WEIGHTS,), gradients=False)),
          np.array([0, 1, 2, 7, -1, 8], np.int32)),
    Entry("Discrete-alias", prebuilt, (_C((js.Discrete(WEIGHTS, "alias"),)),
                                       _C((js.Discrete(np.array([2.5]), "alias"),), gradients=False),
                                       _C((js.Discrete(HUGE_WEIGHTS, "alias"),), gradients=False)),
          np.array([0, 1, 2, 7, -1, 8], np.int32)),
    # ---- generic constructions ----
    Entry("Rejection-disk-with-fallback", rejection_disk, (_C((4.0 / np.pi,)),), DISK_POINTS),
    Entry("Rejection-without-fallback", rejection_loose, (_C((4.0,)),), np.array([0.0, 0.5, 1.0, 1e-30, 2.0, -0.5])),
    # Polar and spherical coordinates are singular at u₀ = 0 (the disk's centre, the poles: det J =
    # 0, where the sampler reports density 0); there the derivatives are those of the user's
    # forward and inverse (sqrt, arctan2), which the sampler cannot repair, so the gradient check
    # of Transformed runs on a transform smooth on the closed box (the exponential map).
    Entry("Transformed-polar-disk", transformed_polar, (_C(([1.0, 2 * np.pi],), gradients=False),), DISK_POINTS,
          inverse=Inverse(tol32=1e-4, jacobian32=1e-3)),
    Entry("Transformed-spherical", transformed_spherical, (_C(([-1.0, 0.0], [1.0, 2 * np.pi]), gradients=False),),
          DIRECTION_POINTS, inverse=Inverse(tol32=1e-4, jacobian32=1e-3), positive_at_edges=False),
    Entry("Transformed-exponential-map", transformed_exponential, (_C(()),),
          np.array([[1.0, 1.0], [2.0, 1.5], [np.e, np.e], [1.0, 2.0], [0.5, 1.5], [3.0, 3.0]]),
          inverse=Inverse(tol32=1e-5, tol64=1e-12, jacobian32=1e-4, jacobian64=1e-12)),
    Entry("Mixture-exponentials", mixture_of_exponentials,
          (_C(([0.3, 0.7], 1e3)), _C(([0.5, 0.5], 1e6), chi2=False), _C(([0.0, 1.0], 1e-6), chi2=False)),
          np.array([0.0, 0.5, 1.0, 1e-3, 1e3, -1.0])),
    Entry("Mixture-directions", mixture_of_directions,
          (_C(([1.0, 2.0, 1.0], 50.0, 1e4)), _C(([0.7, 0.3, 0.0], 20.0, 20.0), chi2=False),
           _C(([1.0, 0.0, 0.0], 20.0, 1e3), chi2=False), _C(([0.0, 1.0, 0.0], 20.0, 1e3), chi2=False)),
          # Mixture's float64 code is checked on the exponentials above; this three-lobe program
          # is the costliest to compile of all, so its gradients are checked in float32.
          DIRECTION_POINTS, positive_at_edges=False, gradients64=False),
    # (Its gradients are those of the other two mixtures' code with the disks' warps.)
    Entry("Mixture-disks", mixture_of_disks, (_C(([1.0, 0.0],), chi2=False, gradients=False),), DISK_POINTS),
    # ---- Henyey–Greenstein, Gaussians, tent, linear, bilinear ----
    # g at its float32 hard cases; chi-square at a sharp forward lobe and the sharpest backward
    # one (the warp's factors are formed differently for g < 0).
    Entry("HenyeyGreenstein", henyey_greenstein,
          (_C((0.0,), chi2=False), _C((1e-4,), chi2=False), _C((-0.5,), chi2=False), _C((0.99,)),
           _C((-0.99,), chi2=False), _C((1.0 - 1e-4,), chi2=False), _C((-(1.0 - 1e-4),))),
          DIRECTION_POINTS, 400_000, 128, 65_536, _DIRECTIONAL_INVERSE),
    Entry("Normal", normal, (_C((0.5, 2.0)), _C((0.0, 1e-6), chi2=False), _C((3.0, 1e6), chi2=False)),
          np.array([0.0, 1.0, -3.0, 1e-30, 40.0, -1e3]), 1_000_000, inverse=_LINE_INVERSE),
    # Scales 1e-6 and 1e6 on the two axes: the check's det(JᵀJ) cancels in float32 for so
    # unequal columns, so that case's round trip is in test_phase_and_simple.py instead.
    Entry("Normal2D", normal_2d, (_C(((1.0, -2.0), (0.5, 3.0))),
                                  _C(((0.0, 0.0), (1e-6, 1e6)), chi2=False, inverse=False)),
          DISK_POINTS, inverse=_PLANAR_INVERSE),
    # pdf(x) near the zero ends has the relative error of x's rounding over the density,
    # ulp/p: 2e-5 at p = 0.0025 (Tent) and 5e-5 at p = 0.0036 (Bilinear's zero corners).
    Entry("Tent", tent, (_C((1.0,)), _C((1e-6,), chi2=False), _C((1e6,), chi2=False)),
          np.array([0.0, 0.5, -1.0, 1.0, 2.0, -1e-30]), 1_000_000, inverse=_LINE_INVERSE,
          pdf_rtol=1e-4, positive_at_edges=False),  # u = 0 gives x = -r, where the density is 0
    # a = b (the textbook root's 0/0), a weight of 0 at either end, and a ratio of 1e12.
    Entry("Linear", linear, (_C((1.0, 3.0)), _C((0.0, 1.0)), _C((1.0, 0.0), chi2=False), _C((2.0, 2.0), chi2=False),
                             _C((1e6, 1e-6), chi2=False)),
          np.array([0.0, 1.0, 0.5, 1e-30, 2.0, -0.5]), 1_000_000, inverse=_LINE_INVERSE,
          positive_at_edges=False),  # a = 0: u = 0 gives x = 0, where the density is 0
    # The smooth step rises from p = 0 at a; a wide and a narrow interval, and one far from 0 (in
    # float64: float32 rounds x = 1000 + 5t to 6e-5, so p ∝ t² near a is resolved to 2e-4 at t = 0.1).
    Entry("SmoothStep", smooth_step, (_C((-1.0, 2.0)), _C((0.0, 1e-3), chi2=False),
                                      _C((1e3, 1e3 + 5.0), x64=True, chi2=False)),
          np.array([-1.0, 0.5, 2.0, -2.0, 3.0, 1.999]), 1_000_000, inverse=_LINE_INVERSE,
          pdf_rtol=1e-4, positive_at_edges=False),  # u = 0 gives x = a, where the density is 0
    # Across the peak, deep in the right tail (F(a) = 1 - e^-10), in the left tail, and narrow.
    Entry("TrimmedLogistic", trimmed_logistic,
          (_C((1.0, -2.0, 3.0)), _C((0.1, 1.0, 2.0)), _C((2.0, -20.0, -5.0), chi2=False),
           _C((0.5, -0.01, 0.01), chi2=False)),
          np.array([-2.0, 0.0, 1.5, 3.0, -3.0, 4.0]), 1_000_000, inverse=_LINE_INVERSE),
    Entry("Bilinear", bilinear, (_C(((1.0, 2.0, 3.0, 4.0),)), _C(((0.0, 0.0, 1.0, 3.0),)),
                                 _C(((0.0, 1.0, 1.0, 0.0),), chi2=False), _C(((1e6, 1.0, 0.0, 1e-6),), chi2=False)),
          np.array([[0.3, 0.6], [0.0, 0.0], [1.0, 1.0], [0.5, 0.14], [2.0, 0.5], [-0.5, 0.5]]),
          inverse=_PLANAR_INVERSE, pdf_rtol=1e-4, positive_at_edges=False),  # a zero corner weight: p = 0 there
    # ---- microfacet distributions and their lobes ----
    # Roughness 1e-4..1 and anisotropy 1e3 (alpha_x = 1, alpha_y = 1e-3); wo at cos θ_o = 1e-7, 45°-ish,
    # along the normal and below the horizon. Chi-square at the smoothest, the roughest and the
    # anisotropic lobe; the rest are checked for normalization, inverse, support and gradients.
    Entry("GGX", ggx, (_C((1e-4, 1e-4)), _C((1e-2, 1e-2), chi2=False), _C((0.3, 0.3), chi2=False),
                       _C((1.0, 1.0)), _C((1.0, 1e-3))),
          DIRECTION_POINTS, 400_000, 128, 65_536, _MICROFACET_INVERSE, positive_at_edges=False),
    Entry("Beckmann", beckmann, (_C((1e-4, 1e-4)), _C((1e-2, 1e-2), chi2=False), _C((0.3, 0.3), chi2=False),
                                 _C((1.0, 1.0)), _C((1.0, 1e-3))),
          DIRECTION_POINTS, 400_000, 128, 65_536, _MICROFACET_INVERSE, positive_at_edges=False),
    Entry("VisibleNormals-GGX", ggx_visible, _MICROFACET_LOBE_CASES, DIRECTION_POINTS, 400_000, 128, 65_536,
          _MICROFACET_INVERSE, positive_at_edges=False),
    Entry("VisibleNormals-Beckmann", beckmann_visible, _MICROFACET_LOBE_CASES, DIRECTION_POINTS, 400_000, 128,
          65_536, _MICROFACET_INVERSE, positive_at_edges=False),
    # wi is recomputed into m = normalize(wo + wi): a float32 wi fixes m to ~6e-8 / |wo + wi| rad, which a
    # lobe of alpha = 1e-4 (or alpha_y = 1e-3) turns into ~1e-3 of u (the round trip's tolerance; 1e-6 in
    # float64 for the same reason at grazing). At alpha = 1e-4 and a grazing wo the lobe of wi is
    # 2 (wo·m) alpha ~ 2e-8 rad across, below float32's spacing of directions: that case is float64 only.
    Entry("MicrofacetReflection-GGX", ggx_reflection,
          (_C((0.3, 0.3, MICROFACET_OBLIQUE)), _C((1.0, 1.0, MICROFACET_GRAZING)), _C((1.0, 1e-3, MICROFACET_SKEW)),
           _C((1e-4, 1e-4, MICROFACET_OBLIQUE), chi2=False), _C((1e-4, 1e-4, MICROFACET_GRAZING), x64=True, chi2=False),
           _C((1e-2, 1e-2, MICROFACET_BELOW), chi2=False)),
          DIRECTION_POINTS, 400_000, 128, 65_536, _MICROFACET_REFLECTION_INVERSE,
          positive_at_edges=False),
    # Its two parts are checked elsewhere: the visible normals (chi-square, float64 gradients) in
    # VisibleNormals-Beckmann, the reflection about them in MicrofacetReflection-GGX; here the
    # composition, at a third of the cost (each Beckmann program takes seconds to compile).
    Entry("MicrofacetReflection-Beckmann", beckmann_reflection,
          (_C((0.3, 0.3, MICROFACET_OBLIQUE), chi2=False), _C((1.0, 1e-3, MICROFACET_SKEW), chi2=False),
           _C((1.0, 1.0, MICROFACET_GRAZING), chi2=False)),
          DIRECTION_POINTS, 400_000, 128, 65_536, _MICROFACET_REFLECTION_INVERSE, positive_at_edges=False,
          gradients64=False),
    # ---- spherical triangles and rectangles ----
    # Chi-square at a near-hemisphere, a medium and a 1e-4 sr shape; 1e-8 sr for the support and the
    # gradients (its round trip, against the rounding of the sample, is in test_spherical_polygons.py).
    Entry("SphericalTriangle", spherical_triangle,
          (_C(SPHERICAL_HEMISPHERE), _C(SPHERICAL_MEDIUM), _C(SPHERICAL_SMALL), _C(SPHERICAL_OCTANT, chi2=False),
           _C(SPHERICAL_TINY, chi2=False, inverse=False)),
          SPHERICAL_POINTS, inverse=_SPHERICAL_INVERSE),
    Entry("CosineSphericalTriangle", cosine_spherical_triangle,
          (_C(SPHERICAL_OCTANT + ((0.3, -0.2, 0.9),)), _C(SPHERICAL_SMALL + ((1.0, 0.0, 0.0),), chi2=False),
           _C(SPHERICAL_TINY + ((0.0, 0.0, -1.0),), chi2=False, inverse=False)),
          # Its float64 code is SphericalTriangle's (checked there) and the bilinear warp's arithmetic.
          SPHERICAL_POINTS, inverse=_SPHERICAL_INVERSE, gradients64=False),
    Entry("SphericalRectangle", spherical_rectangle,
          (_C(SPHERICAL_RECTANGLE_NEAR), _C(SPHERICAL_RECTANGLE_SQUARE), _C(SPHERICAL_RECTANGLE_SMALL),
           _C(SPHERICAL_RECTANGLE_TINY, chi2=False, inverse=False)),
          SPHERICAL_POINTS, inverse=_SPHERICAL_INVERSE),
]

BY_NAME = {entry.name: entry for entry in ENTRIES}
assert len(BY_NAME) == len(ENTRIES), "entry names must be unique"

CHI2_CASES = [(entry, case) for entry in ENTRIES for case in entry.chi2_cases()]
N_CHI2_TESTS = len(CHI2_CASES)


def chi2_settings(name: str) -> dict:
    """`chi2_test` keyword arguments of an entry (its sample size, cells, pilot) at the family's level."""
    entry = BY_NAME[name]
    return dict(n_samples=entry.chi2_samples, n_cells=entry.chi2_cells, n_pilot=entry.chi2_pilot,
                significance=FAMILY_SIGNIFICANCE, n_tests=N_CHI2_TESTS)


def edge_uniforms(dims: int, dtype) -> jnp.ndarray:
    """u at the hard values {0, 0.5, 1 - 2^-24}: every combination in the first two coordinates
    (0.5 beyond them), the concentric map's axes, centre and diagonal for d = 2, and constant and
    alternating rows for samplers that use more than two uniforms."""
    if dims == 1:
        rows = [[v] for v in EDGE_VALUES]
    else:
        rows = [[a, b] + [0.5] * (dims - 2) for a in EDGE_VALUES for b in EDGE_VALUES]
        if dims == 2:
            rows += [[0.5, 0.25], [0.25, 0.5], [0.75, 0.75], [0.5, 0.75], [0.75, 0.5], [0.25, 0.25]]
        else:
            rows += [[v] * dims for v in EDGE_VALUES] + [[EDGE_VALUES[i % 3] for i in range(dims)]]
    return jnp.asarray(np.array(rows, np.float64), dtype)
