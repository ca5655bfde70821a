"""Hard cases: sampler × extreme parameter -> non-finite values and gradients, float32 error.

Run alone: `python -m jaxsample.report.hard_cases`. For each case the warp, its density and the
gradients (reverse mode, w.r.t. the parameter and u) are evaluated at u in {0, 0.5, 1 - 2^-24}² in
float32; the worst relative error of the density and the worst absolute error of the sample are
taken (absolute, or relative for values above 1) against the same computation in float64 from the same (float32) inputs.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js

CASES = [
    ("PhongLobe", "exponent", lambda p: js.PhongLobe(p), [0.0, 1e6, 1e7]),
    ("UniformCone", "solid angle (sr)", lambda p: js.UniformCone.from_solid_angle(p), [1e-8, 1e-4, 4 * np.pi]),
    ("VonMisesFisher", "kappa", lambda p: js.VonMisesFisher(p), [1e-6, 89.0, 1e7]),
    ("Exponential", "rate", lambda p: js.Exponential(p), [1e-6, 1e6]),
    ("TruncatedExponential", "rate (t_max=1)", lambda p: js.TruncatedExponential(p, 1.0), [1e-6, 1e6]),
    ("Power", "exponent", lambda p: js.Power(p), [0.0, 1e6]),
    ("CosineHemisphere", "-", lambda p: js.CosineHemisphere(), [0.0]),
    ("UniformDisk(concentric)", "-", lambda p: js.UniformDisk(), [0.0]),
    ("UniformSphere", "-", lambda p: js.UniformSphere(), [0.0]),
]


def _uniforms(dims, dtype):
    edges = jnp.array([0.0, 0.5, 1.0 - 2.0**-24], dtype)
    grids = jnp.meshgrid(*([edges] * min(dims, 2)), indexing="ij")
    u = jnp.stack([g.ravel() for g in grids], -1)
    if dims > 2:
        u = jnp.concatenate([u, jnp.full((u.shape[0], dims - 2), 0.5, dtype)], -1)
    return u


def _probe(build, param, u):
    x, p = build(param).warp_with_pdf(u)
    return jnp.sum(x) + p * 1e-6


@functools.partial(jax.jit, static_argnums=0)
def _float32_case(build, param, u):
    """Sample, density, log-density at the sample, and the per-point gradients in (param, u): one
    compiled program per sampler, the parameter traced, so every value of it reuses the program."""
    sampler = build(param)
    x, p = sampler.warp_with_pdf(u)
    lp = sampler.log_pdf(x)
    grads = jax.vmap(jax.grad(lambda q, v: _probe(build, q, v), argnums=(0, 1)), (None, 0))(param, u)
    return x, p, lp, grads


@functools.partial(jax.jit, static_argnums=0)
def _float64_case(build, param, u):
    return build(param).warp_with_pdf(u)


def hard_case_table() -> list[dict]:
    rows = []
    for name, what, build, values in CASES:
        for value in values:
            param = jnp.float32(value)
            u = _uniforms(build(param).uniform_dims, jnp.float32)
            x, p, lp, grads = jax.tree_util.tree_map(np.asarray, _float32_case(build, param, u))
            bad_values = int(np.sum(~np.isfinite(x).reshape(len(u), -1).all(-1))
                             + np.sum(~np.isfinite(p)) + np.sum(np.isnan(lp)))
            bad_grads = int(sum(np.sum(~np.isfinite(g).reshape(len(u), -1).all(-1)) for g in grads))
            with jax.enable_x64(True):
                x64, p64 = (np.asarray(a) for a in _float64_case(build, jnp.float64(param), u.astype(jnp.float64)))
            positive = p64 > 0
            rel = np.abs(p.astype(np.float64)[positive] / p64[positive] - 1)
            rows.append({"sampler": name, "parameter": what, "value": value,
                         "non_finite_values": bad_values, "non_finite_gradients": bad_grads,
                         "worst_pdf_rel_error": float(rel.max()) if rel.size else 0.0,
                         # absolute for unit vectors and points; relative for distances above 1
                         "worst_sample_error": float(np.max(np.abs(x.astype(np.float64) - x64)
                                                            / np.maximum(np.abs(x64), 1.0)))})
    return rows


def markdown_table(rows) -> str:
    out = ["| sampler | parameter | value | non-finite values | non-finite gradients "
           "| worst pdf rel. error (f32 vs f64) | worst sample error (abs.; rel. above 1) |",
           "|---|---|---|---|---|---|---|"]
    out += [f"| {r['sampler']} | {r['parameter']} | {r['value']:g} | {r['non_finite_values']} | "
            f"{r['non_finite_gradients']} | {r['worst_pdf_rel_error']:.2e} | {r['worst_sample_error']:.2e} |"
            for r in rows]
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(markdown_table(hard_case_table()))
