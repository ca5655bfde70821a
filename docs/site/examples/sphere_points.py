"""Points drawn by each directional sampler, on the unit sphere, coloured by their density."""

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import jaxsample as js

wo = jnp.array([0.6, 0.0, 0.8])  # the view direction of the microfacet lobes
samplers = {
    "UniformSphere()": js.UniformSphere(),
    "UniformHemisphere()": js.UniformHemisphere(),
    "CosineHemisphere()": js.CosineHemisphere(),
    "PhongLobe(20)": js.PhongLobe(20.0),
    "UniformCone(0.8)": js.UniformCone(0.8),
    "VonMisesFisher(10)": js.VonMisesFisher(10.0),
    "HenyeyGreenstein(0.6)": js.HenyeyGreenstein(0.6),
    "VisibleNormals(GGX(0.3), wo)": js.VisibleNormals(js.GGX(0.3), wo),
    "MicrofacetReflection(GGX(0.3), wo)": js.MicrofacetReflection(js.GGX(0.3), wo),
    "Oriented(PhongLobe(20), n)": js.Oriented(js.PhongLobe(20.0), jnp.array([1.0, 0.0, 1.0])),
}

fig = plt.figure(figsize=(12, 5.4))
fig.suptitle("1500 directions from each sampler; colour: log density over solid angle")
keys = jax.random.split(jax.random.key(0), len(samplers))
for index, ((name, sampler), key) in enumerate(zip(samplers.items(), keys), 1):
    x, p = sampler.sample_with_pdf(key, (1500,))
    x, p = np.asarray(x), np.asarray(p)
    unit_error = np.abs(np.linalg.norm(x, axis=1) - 1.0).max()
    print(f"{name:35s} max ||x| - 1| {unit_error:.1e}  mean z {x[:, 2].mean():+.3f}  pdf {p.min():.3g} to {p.max():.3g}")
    axes = fig.add_subplot(2, 5, index, projection="3d")
    axes.scatter(x[:, 0], x[:, 1], x[:, 2], c=np.log(p), s=1.5, cmap="viridis", depthshade=False)
    axes.set_title(name, fontsize=8)
    axes.set(xlim=(-1, 1), ylim=(-1, 1), zlim=(-1, 1), xticks=[], yticks=[], zticks=[])
    axes.set_box_aspect((1, 1, 1))
    axes.view_init(elev=18, azim=-60)
fig.tight_layout()
