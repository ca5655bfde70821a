"""The checks' geometry: domains, their cells and quadrature (public name of `jaxsample.checks.domains`)."""

from .checks.domains import (
    GAUSS_ORDER, bin_index, gauss_legendre_panels, graded_edges, quantile_edges, Cells, Directions,
    Interval, Box, Disk, Triangle, DiscreteSet,
)

__all__ = [
    "GAUSS_ORDER", "bin_index", "gauss_legendre_panels", "graded_edges", "quantile_edges", "Cells",
    "Directions", "Interval", "Box", "Disk", "Triangle", "DiscreteSet",
]
