"""Discontinuities that move with a parameter, and the boundary terms of their gradients.

`Cap`, `SphericalTriangle`, `SphericalPolygon` (directions) and `Disk` (the plane) know their boundaries;
`mask(region, inside, outside)` is an integrand that jumps across one, and every gradient estimator
adds its boundary term (Li et al. 2018). See `regions.py` and `masked.py`.
"""

from .masked import Masked, boundary_dims, discontinuities, mask
from .regions import Cap, Disk, SphericalPolygon, SphericalTriangle

__all__ = ["Cap", "SphericalTriangle", "SphericalPolygon", "Disk", "Masked", "mask", "discontinuities", "boundary_dims"]
