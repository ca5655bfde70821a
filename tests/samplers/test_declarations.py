"""The one pytree idiom and the parameter declarations (`jaxsample._core.pytree`).

Each declared range is the single source of the constructor's check, the traced NaN rule, the
docstring's range and the hard cases below: for every registry sampler with a bounded declared
parameter, the values at (or one float32 step inside) each finite bound are valid and give finite
samples and densities, and one float32 step outside is refused at construction and makes every
output NaN when it reaches the sampler traced.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample._core.pytree import parameter, parameters, static_field, tree_fields

from registry import EDGE_VALUES, ENTRIES


def _bounded(entry):
    sampler = entry.build(entry.cases[0])
    return [(name, spec) for name, spec in parameters(sampler).items() if spec.bounded and not spec.static]


DECLARED = [(entry, name, spec) for entry in ENTRIES for name, spec in _bounded(entry)]
DECLARED_IDS = [f"{entry.name}-{name}" for entry, name, _ in DECLARED]


def _with_parameter(sampler, name, value):
    """`sampler` rebuilt (as JAX rebuilds it, past the constructor) with parameter `name` = value."""
    paths, treedef = jax.tree_util.tree_flatten_with_path(sampler)
    leaves = [jnp.full(jnp.shape(leaf), value, jnp.float32) if path == (jax.tree_util.GetAttrKey(name),) else leaf
              for path, leaf in paths]
    return jax.tree_util.tree_unflatten(treedef, leaves)


def _outputs(sampler):
    u = jnp.asarray(np.stack(np.meshgrid(*[EDGE_VALUES] * sampler.uniform_dims), -1).reshape(-1, sampler.uniform_dims),
                    jnp.float32)
    x, p = jax.jit(lambda s: s.warp_with_pdf(u))(sampler)
    return np.asarray(x, np.float64), np.asarray(p, np.float64)


def test_the_registry_declares_bounded_parameters_for_the_samplers_that_have_them():
    names = {entry.name.split("-")[0] for entry, _, _ in DECLARED}
    declared = {"PhongLobe", "UniformCone", "VonMisesFisher", "Exponential", "TruncatedExponential", "Power"}
    assert declared <= names, names


@pytest.mark.parametrize("entry,name,spec", DECLARED, ids=DECLARED_IDS)
def test_values_at_each_declared_bound_are_valid_and_finite(entry, name, spec):
    sampler = entry.build(entry.cases[0])
    for inside, _ in spec.edge_values():
        assert bool(spec.contains(inside)), (name, inside)
        x, p = _outputs(_with_parameter(sampler, name, inside))
        assert np.all(np.isfinite(p)) and np.all(p >= 0), (name, inside, p)
        assert np.all(np.isfinite(x)), (name, inside)


@pytest.mark.parametrize("entry,name,spec", DECLARED, ids=DECLARED_IDS)
def test_one_step_outside_a_declared_bound_is_refused_or_nan(entry, name, spec):
    sampler = entry.build(entry.cases[0])
    for _, outside in spec.edge_values():
        # Concrete: assigning it, as every constructor does, raises naming the parameter and range.
        fresh = object.__new__(type(sampler))
        with pytest.raises(ValueError, match=rf"parameter '{name}' must be in \S+, \S+"):
            setattr(fresh, name, jnp.float32(outside))
        if isinstance(getattr(sampler, name), (int, np.integer)):
            continue  # a Python int parameter is static in use (Power's "max"): always concrete
        # Traced (past any constructor): every sample is NaN, and so is the density at the valid
        # sampler's own points.
        bad = _with_parameter(sampler, name, outside)
        x, _ = _outputs(bad)
        points, _ = _outputs(sampler)
        density = np.asarray(jax.jit(lambda s, y: s.pdf(y))(bad, jnp.asarray(points, jnp.float32)))
        assert np.all(np.isnan(x)) and np.all(np.isnan(density)), (name, outside)


@pytest.mark.parametrize("entry,name,spec", DECLARED, ids=DECLARED_IDS)
def test_the_docstring_states_the_declared_range(entry, name, spec):
    cls = type(entry.build(entry.cases[0]))
    assert f"{name}: {spec.describe()}" in cls.__doc__


def test_samplers_lights_and_results_are_frozen_after_construction():
    objects = [js.PhongLobe(3.0), js.UniformCone(0.5), js.Discrete([1.0, 2.0]), js.uniforms.Sobol(4),
               js.scene.SphereLight(jnp.zeros(3), 1.0, 2.0),
               js.estimate(lambda w: w[2], js.CosineHemisphere(), jax.random.key(0), 256)]
    for obj in objects:
        name = tree_fields(obj)[0][0] if tree_fields(obj)[0] else tree_fields(obj)[1][0]
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, name, 1.0)


def test_a_subclass_keeps_its_own_fields_through_a_round_trip():
    class Tagged(js.PhongLobe):
        weight: jax.Array = 2.0          # an annotated field: a leaf
        label: str = static_field(default="a")

    class Untagged(js.UniformCone):
        def __init__(self, h, extra):
            super().__init__(one_minus_cos_theta_max=h)
            self.extra = extra           # not annotated: a leaf by its value

    for obj, check in [(Tagged(3.0, 5.0, "b"), lambda o: (float(o.weight), o.label) == (5.0, "b")),
                       (Untagged(0.5, 7.0), lambda o: float(o.extra) == 7.0)]:
        leaves, treedef = jax.tree_util.tree_flatten(obj)
        rebuilt = jax.tree_util.tree_unflatten(treedef, leaves)
        assert check(rebuilt) and len(leaves) == 2
        assert check(jax.jit(lambda o: o)(obj))


def test_a_users_declared_parameter_checks_batches_and_poisons():
    class Tilted(js.Sampler):
        """p(x) = 1 + s (x - 1/2) on [0, 1]."""

        slope: jax.Array = parameter(-2.0, 2.0)
        uniform_dims = 1

        def warp(self, u):
            s, u = self.slope, u[..., 0]
            return jnp.where(s == 0, u, ((s / 2 - 1) + jnp.sqrt((1 - s / 2) ** 2 + 2 * s * u)) / s)

        def pdf(self, x):
            return jnp.where((x >= 0) & (x <= 1), 1 + self.slope * (x - 0.5), 0.0)

        def domain(self):
            return js.domains.Interval(0.0, 1.0)

    with pytest.raises(ValueError, match=r"Tilted: parameter 'slope' must be in \[-2, 2\]"):
        Tilted(3.0)
    assert "slope: [-2, 2]" in Tilted.__doc__
    batch = Tilted(jnp.array([-1.0, 0.5, 1.5]))
    assert batch.batch_shape == (3,) and batch.event_shape == () and batch.measure == "length"
    assert np.allclose(batch.prob(jnp.full((4, 3), 0.25)), 1 + np.array([-1.0, 0.5, 1.5]) * -0.25)
    assert np.isnan(float(jax.jit(lambda s: Tilted(s).prob(jnp.float32(0.5)))(5.0)))


def test_a_user_sampler_takes_event_shape_and_measure_from_its_domain():
    class Lobe(js.Sampler):
        uniform_dims = 2

        def warp(self, u):
            return js.CosineHemisphere().warp(u)

        def pdf(self, x):
            return js.CosineHemisphere().pdf(x)

        def domain(self):
            return js.domains.Directions()

    assert Lobe().event_shape == (3,) and Lobe().measure == "solid angle"
    turned = js.Oriented(Lobe(), jnp.array([1.0, 0.0, 0.0]))
    est = js.estimate(lambda w: jnp.maximum(w[0], 0.0), turned, jax.random.key(3), 1 << 12)
    assert abs(float(est.mean) - np.pi) < 1e-5  # ∫ cos θ over the hemisphere, f/p = π exactly


def test_a_checked_copy_is_marked_and_the_users_object_is_not():
    from jaxsample._core.pytree import is_checked
    from jaxsample.samplers.base import checked

    lobe = js.Oriented(js.PhongLobe(4.0), jnp.array([0.0, 1.0, 0.0]))
    copy = checked(lobe)
    assert is_checked(copy) and is_checked(copy.base) and not is_checked(lobe) and not is_checked(lobe.base)
    leaves, treedef = jax.tree_util.tree_flatten(copy)
    assert is_checked(jax.tree_util.tree_unflatten(treedef, leaves))
    oriented = js.Oriented(js.PhongLobe(4.0), jnp.ones(3))
    assert jax.tree_util.tree_structure(lobe) == jax.tree_util.tree_structure(oriented)


def test_one_pytree_idiom_across_the_package():
    """Only `jaxsample._core.pytree` registers pytrees: every other class is a `Pytree` subclass."""
    import pathlib
    import re

    root = pathlib.Path(js.__file__).parent
    pattern = re.compile(r"register_pytree|register_dataclass|register_static|pytree_dataclass|pytree_attributes"
                         r"|_tree_fields")
    offenders = [str(path.relative_to(root)) for path in root.rglob("*.py")
                 if path.name != "pytree.py" and pattern.search(path.read_text())]
    assert not offenders, offenders
