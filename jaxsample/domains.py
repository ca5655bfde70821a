"""Domains and the checks' geometry on them (public name of `jaxsample.testing.domains`).

The domain classes (`Directions`, `Interval`, `Box`, `Disk`, `Triangle`, `DiscreteSet`) are what a
sampler's `domain()` returns (defined in `jaxsample.samplers.domain`); `quadrature`, `cells` and
`contains` are what the checks compute on them.
"""

from .testing.domains import (
    GAUSS_ORDER, bin_index, gauss_legendre_panels, graded_edges, quantile_edges, Cells, Directions,
    Interval, Box, Disk, Triangle, DiscreteSet, quadrature, cells, contains, panel_edges, barycentric,
)

__all__ = [
    "GAUSS_ORDER", "bin_index", "gauss_legendre_panels", "graded_edges", "quantile_edges", "Cells",
    "Directions", "Interval", "Box", "Disk", "Triangle", "DiscreteSet", "quadrature", "cells", "contains",
    "panel_edges", "barycentric",
]
