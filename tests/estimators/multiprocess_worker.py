"""One process of the two-process test (tests/test_multiprocess.py); also runs alone as the
single-process reference.

    python tests/multiprocess_worker.py OUT.json                      # one process, no mesh
    python tests/multiprocess_worker.py OUT.json ID COUNT PORT        # process ID of COUNT

With ID/COUNT/PORT it joins JAX's distributed runtime (coordinator on 127.0.0.1:PORT, one CPU
device per process, CPU collectives through gloo), builds the global mesh over every process's
devices and runs the same estimates with `mesh=`; process 0 writes the results. Every estimate
draws the same points either way (the i-th sample depends only on the key and i), so the two
runs agree to float rounding.
"""

import json
import os
import sys

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402

N = 1 << 16


def results(mesh):
    import jax.numpy as jnp

    import jaxsample as js

    key = jax.random.key(2026)
    keys = jax.random.split(key, 8)
    tilted = jnp.array([0.3, 0.2, 0.9327379])
    cap = lambda w: (w @ tilted > 0.8).astype(jnp.float32)
    cos3 = lambda w: jnp.maximum(w[2], 0.0) ** 3

    def disk_density(x):
        return jnp.where(jnp.sum(x * x, axis=-1) < 1.0, 1.0 / jnp.pi, 0.0)

    rejection = js.Rejection(js.UniformBox(-jnp.ones(2), jnp.ones(2)), disk_density, 4.0 / jnp.pi, tries=4)

    def phong_expectation(exponent, gradient):
        return js.expectation(lambda w: w[2] ** 2, js.PhongLobe(exponent), keys[5], N, gradient=gradient,
                              mesh=mesh).mean

    out = {}
    for uniforms in ("random", "sobol"):
        est = jax.jit(lambda k, u=uniforms: js.estimate(cap, js.CosineHemisphere(), k, N, uniforms=u,
                                                         mesh=mesh))(keys[0])
        out[f"estimate/{uniforms}"] = [float(est.mean), float(est.stderr)]
        est = jax.jit(lambda k, u=uniforms: js.estimate(lambda x: jnp.sum(x * x), rejection, k, N, uniforms=u,
                                                         mesh=mesh))(keys[1])
        out[f"rejection/{uniforms}"] = [float(est.mean), float(est.stderr)]
    est = jax.jit(lambda k: js.estimate_mis(cos3, [js.CosineHemisphere(), js.PhongLobe(20.0)], k, [N, N // 2],
                                            heuristic="power", mesh=mesh))(keys[2])
    out["estimate_mis/power"] = [float(est.mean), float(est.stderr)]
    for gradient in ("pathwise", "score"):
        value, grad = jax.jit(jax.value_and_grad(phong_expectation), static_argnums=1)(5.0, gradient)
        out[f"expectation_grad/{gradient}"] = [float(value), float(grad)]
    return out


def main(argv):
    path = argv[0]
    mesh = None
    if len(argv) == 4:
        process_id, count, port = int(argv[1]), int(argv[2]), int(argv[3])
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
        jax.distributed.initialize(coordinator_address=f"127.0.0.1:{port}", num_processes=count,
                                   process_id=process_id, initialization_timeout=60)
        assert jax.process_count() == count and len(jax.devices()) == count, jax.devices()
        mesh = jax.sharding.Mesh(jax.devices(), ("samples",))
    out = results(mesh)
    if mesh is None or jax.process_index() == 0:
        out["devices"] = len(jax.devices())
        out["processes"] = jax.process_count()
        with open(path, "w") as handle:
            json.dump(out, handle, indent=1)
    if mesh is not None:
        jax.distributed.shutdown()


if __name__ == "__main__":
    main(sys.argv[1:])
