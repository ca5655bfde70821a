"""The scene's entry points check their arguments as `estimate` does, in the library's words.

`check_scene` runs before anything is traced (`compiled_entry(check=...)`), so the checks that need
numbers see them when the call is eager: a zero-length normal, a view below the surface, a point
inside a light. Under `jit`, `vmap` or `grad` those values are tracers and only the structure is
checked; a traced point inside a sphere light gives NaN (`SphereLight.sin2_theta_max`).

The view below the surface is refused, not shaded from the other side: the BRDFs here are one-sided
(reflection off the side the normal points to), and a wo under the surface almost always means a
flipped normal or a wo that points toward the surface instead of away from it; two-sided shading is
the caller's choice of normal.
"""

from __future__ import annotations

import numpy as np

from .._core.params import concrete_value
from .colour import scene_channels

__all__ = ["check_scene", "as_lights"]

BRDF_METHODS = ("eval", "sample", "pdf")
LIGHT_METHODS = ("sample", "pdf", "radiance_from")


def _refuse_class(owner: str, name: str, value) -> None:
    if isinstance(value, type):
        raise ValueError(f"{owner}: parameter '{name}' must be an instance; got the class {value.__name__}: "
                         f"call it, {value.__name__}(...)")


def _check_methods(owner: str, name: str, value, methods) -> None:
    _refuse_class(owner, name, value)
    missing = [m for m in methods if not callable(getattr(value, m, None))]
    if missing:
        raise TypeError(f"{owner}: parameter '{name}' must have {', '.join(methods)}; "
                        f"{type(value).__name__} lacks {', '.join(missing)}")


def as_lights(owner: str, lights) -> tuple:
    """`lights` as a non-empty tuple: one light, or a list or tuple of them (a dict is refused)."""
    if isinstance(lights, dict):
        raise ValueError(f"{owner}: parameter 'lights' must be one light or a list of lights; got a dict "
                         "(pass list(lights.values()))")
    lights = tuple(lights) if isinstance(lights, (list, tuple)) else (lights,)
    if not lights:
        raise ValueError(f"{owner}: parameter 'lights' must hold at least one light")
    for k, light in enumerate(lights):
        _check_methods(owner, "lights" if len(lights) == 1 else f"lights[{k}]", light, LIGHT_METHODS)
    return lights


def _vector(owner: str, name: str, value) -> np.ndarray | None:
    shape = np.shape(value)
    if shape != (3,):
        batch = " (one shading point per call: jax.vmap over a batch)" if len(shape) > 1 and shape[-1] == 3 else ""
        raise ValueError(f"{owner}: parameter '{name}' must be a 3-vector (shape (3,)); got shape {shape}{batch}")
    concrete = concrete_value(value)
    if concrete is not None and not np.all(np.isfinite(concrete)):
        raise ValueError(f"{owner}: parameter '{name}' must be finite; got {concrete}")
    return concrete


def check_scene(owner: str, point, normal, wo, brdf, lights) -> tuple:
    """Raise `ValueError` (`TypeError` for a wrong kind of object) for a scene `shade` cannot shade;
    returns the lights as a tuple."""
    _check_methods(owner, "brdf", brdf, BRDF_METHODS)
    lights = as_lights(owner, lights)
    p = _vector(owner, "point", point)
    n = _vector(owner, "normal", normal)
    w = _vector(owner, "wo", wo)
    scene_channels(owner, brdf, lights)
    for name, v in (("normal", n), ("wo", w)):
        if v is not None and not np.any(v):
            raise ValueError(f"{owner}: parameter '{name}' must be a non-zero vector (it is normalized); got {v}")
    if n is not None and w is not None and float(n @ w) < 0:
        raise ValueError(f"{owner}: parameter 'wo' points below the surface (wo·normal = {float(n @ w):.3g} < 0): "
                         "wo points from the surface toward the viewer, and the BRDFs reflect on the side the "
                         "normal points to; flip the normal to shade the other side")
    if p is None:
        return lights
    for k, light in enumerate(lights):
        inside = concrete_value(light.contains(p)) if hasattr(light, "contains") else None
        if inside is not None and bool(inside):
            raise ValueError(f"{owner}: parameter 'point' {p} lies inside or on light {k} "
                             f"({type(light).__name__}); a shading point must be outside every sphere light")
    behind = [concrete_value(light.behind(p)) if hasattr(light, "behind") else None for light in lights]
    if all(side is not None and bool(side) for side in behind):
        names = ", ".join(type(light).__name__ for light in lights)
        raise ValueError(f"{owner}: parameter 'point' {p} is behind every light ({names}): each emits from its "
                         "front face only (the side its normal, edge_u × edge_v or (b - a) × (c - a), points to), "
                         "so L_o is 0; reverse the light's orientation or move the point")
    return lights
