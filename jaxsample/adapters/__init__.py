"""Bridges to the JAX distribution libraries, both ways; nothing here imports them until asked.

From jaxsample to theirs (the sampler keeps its warp, its stable density and its batch):

- `to_numpyro(sampler)`: a `numpyro.distributions.Distribution` (usable in `numpyro.sample`; for
  NUTS on a directional sampler, give the site `SphereReparam()`, since NumPyro has no bijection
  onto the sphere).
- `to_distrax(sampler)`: a `distrax.Distribution`.
- `to_tfp(sampler)`: a TensorFlow Probability on JAX distribution (`tfp.substrates.jax`).

Each has `sample` with `sample_shape`, `log_prob`, `batch_shape` and `event_shape` from the sampler,
and is reparameterized where the sampler is (its samples are differentiable functions of its
parameters: every continuous jaxsample sampler; `Discrete` is not).

From theirs to jaxsample: `from_distribution(dist)` wraps anything with `sample` and `log_prob`
(NumPyro, distrax, TFP on JAX) as a `jaxsample.Sampler` that `estimate`, `estimate_until`,
`expectation`, `estimate_grad`, `estimate_mis`, `estimate_ratio` and `estimate_control_variate`
accept with the random source. It has no warp of its own: it makes a key from its uniforms and
draws with it, so the estimators that rely on the uniforms' structure (`estimate_antithetic`,
stratified and QMC sources) refuse it by name.

The libraries are the optional extra `pip install "jaxsample[adapters]"` (NumPyro and distrax,
which brings TFP on JAX); `import jaxsample.adapters` alone imports none of them.
"""

from .foreign import DistributionSampler, from_distribution

__all__ = ["from_distribution", "DistributionSampler", "to_numpyro", "to_distrax", "to_tfp", "SphereReparam"]


def to_numpyro(sampler, *, support=None, validate_args=None):
    """The sampler as a `numpyro.distributions.Distribution`; see `jaxsample.adapters._numpyro`."""
    from ._numpyro import to_numpyro as convert
    return convert(sampler, support=support, validate_args=validate_args)


def to_distrax(sampler):
    """The sampler as a `distrax.Distribution`; see `jaxsample.adapters._distrax`."""
    from ._distrax import to_distrax as convert
    return convert(sampler)


def to_tfp(sampler):
    """The sampler as a TFP-on-JAX distribution; see `jaxsample.adapters._tfp`."""
    from ._tfp import to_tfp as convert
    return convert(sampler)


def __getattr__(name):
    if name == "SphereReparam":
        from ._numpyro import SphereReparam
        return SphereReparam
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
