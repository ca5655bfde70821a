"""What a gradient of `shade` costs next to its value:
`python benchmarks/gradient_cost.py [--quick] [--channels grey|rgb|both] [--n N] [--out FILE]`.

For every BRDF x light x strategy x mode, in one process: the run time per radiance evaluation of
the value (`shade(...).mean` under `jax.jit`), of `jax.grad` of it and of `shade_grad` (the gradient
with its error bars), as medians of `--reps` interleaved calls; the first call of each (trace, lower,
compile and one run, on a program not compiled before); and the size of the optimized HLO of value
and gradient (kilobytes of text, loop fusions). The differentiated parameter is the BRDF's: the
Phong log-exponent, the Lambertian albedo, the rough conductor's GGX alpha; where `shade` refuses
that gradient as biased (the BRDF's samples crossing an environment map's texel edges, attached
"brdf" and "mis") the light's radiance scale is differentiated instead, and the row says so.

The targets: gradient / value run time at most 4, first call of the gradient at most
2.5x the value's, `shade_grad` at most 1.5x `jax.grad`. The table prints a row per configuration as
it goes, then the medians over rows; `--out` writes the markdown table.

`--channels rgb` gives every colour of the scene three channels (albedo, η and k, radiance, texels),
`both` measures each configuration grey and then RGB in the same process and adds the RGB / grey
ratios of the value's and the gradient's run time: three channels share the directions, densities and
MIS weights, so the target is well under 3x.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxsample import scene

POINT = jnp.zeros(3)
NORMAL = jnp.array([0.0, 0.0, 1.0])
WO = jnp.array([0.3, 0.1, 1.0])

# Each colour is scaled by `c`: 1.0 (grey) or an RGB triple (`--channels`).
RGB = jnp.array([1.0, 0.6, 0.3])
BRDFS = {
    "phong": (lambda t, c: scene.Phong(jnp.exp(t), 0.8 * c), float(np.log(25.0)), "log n"),
    "lambertian": (lambda t, c: scene.Lambertian(t * c), 0.7, "albedo"),
    "conductor": (lambda t, c: scene.RoughConductor(t, 0.2 * c, 3.0 * c), 0.3, "alpha"),
}


def _environment(scale, c):
    texels = np.random.default_rng(0).uniform(0.2, 2.0, (8, 16)).astype(np.float32)
    texels = jnp.asarray(texels) if jnp.ndim(c) == 0 else jnp.asarray(texels)[..., None] * c
    return scene.EnvironmentMap(scale * texels)


LIGHTS = {
    "sphere": lambda s, c: scene.SphereLight(jnp.array([0.4, 0.3, 2.0]), 0.5, 3.0 * s * c),
    "triangle": lambda s, c: scene.TriangleLight(jnp.array([-0.5, 0.2, 1.5]), jnp.array([0.6, -0.3, 1.7]),
                                                 jnp.array([0.1, 0.8, 1.2]), 3.0 * s * c),
    "quad": lambda s, c: scene.QuadLight(jnp.array([-0.5, -0.5, 2.0]), jnp.array([0.0, 1.0, 0.0]),
                                         jnp.array([1.0, 0.0, 0.0]), 3.0 * s * c),
    "sky": lambda s, c: scene.ConstantSky(0.5 * s * c),
    "environment": _environment,
}

STRATEGIES = ("brdf", "light", "mis")
MODES = ("attached", "detached")
QUICK = [("phong", "sphere"), ("conductor", "quad"), ("lambertian", "triangle"), ("phong", "environment")]


def scene_of(brdf_name, light_name, strategy, mode, colour=1.0):
    """(make(θ), θ, what θ is): the scene as a function of the one differentiated parameter."""
    make_brdf, brdf_theta, brdf_label = BRDFS[brdf_name]
    make_light = LIGHTS[light_name]
    refused = light_name == "environment" and mode == "attached" and strategy != "light"
    if refused:
        return (lambda t: (POINT, NORMAL, WO, make_brdf(brdf_theta, colour), make_light(t, colour))), 1.0, \
            "light scale"
    return (lambda t: (POINT, NORMAL, WO, make_brdf(t, colour), make_light(1.0, colour))), brdf_theta, brdf_label


def _hlo(compiled):
    text = compiled.as_text()
    return len(text) / 1024.0, text.count("kind=kLoop")


def measure(brdf_name, light_name, strategy, mode, n, reps, key, channels="grey"):
    make, theta, label = scene_of(brdf_name, light_name, strategy, mode, RGB if channels == "rgb" else 1.0)
    theta = jnp.asarray(theta, jnp.float32)

    # One number per program (the gradient of the channels' sum, for RGB).
    def value(t):
        return jnp.sum(scene.shade(*make(t), key, n, strategy=strategy, mode=mode).mean)

    def with_errors(t):
        return jnp.sum(scene.shade_grad(make, t, key, n, strategy=strategy, mode=mode).mean)

    programs = {"value": jax.jit(value), "grad": jax.jit(jax.grad(value)), "shade_grad": jax.jit(with_errors)}
    compiled, first, size = {}, {}, {}
    for name, program in programs.items():
        start = time.perf_counter()
        compiled[name] = program.lower(theta).compile()
        jax.block_until_ready(compiled[name](theta))
        first[name] = time.perf_counter() - start
        size[name] = _hlo(compiled[name])
    times = {name: [] for name in programs}
    for _ in range(reps):
        for name, program in compiled.items():
            start = time.perf_counter()
            jax.block_until_ready(program(theta))
            times[name].append(time.perf_counter() - start)
    ns = {name: float(np.median(t)) / n * 1e9 for name, t in times.items()}
    return dict(brdf=brdf_name, light=light_name, strategy=strategy, mode=mode, parameter=label, ns=ns, first=first,
                size=size, channels=channels)


def row_text(r):
    ns, first, size = r["ns"], r["first"], r["size"]
    return (f"| {r['brdf']} | {r['light']} | {r['channels']} | {r['strategy']} | {r['mode']} | {r['parameter']} | "
            f"{ns['value']:.1f} | "
            f"{ns['grad']:.1f} | **{ns['grad'] / ns['value']:.1f}x** | {ns['shade_grad'] / ns['grad']:.2f}x | "
            f"{first['value']:.1f} → {first['grad']:.1f} s ({first['grad'] / first['value']:.1f}x) | "
            f"{size['value'][0]:.0f} / {size['grad'][0]:.0f} kB, {size['value'][1]} / {size['grad'][1]} |")


HEADER = ("| BRDF | light | channels | strategy | mode | θ | value ns/eval | grad ns/eval | grad / value | "
          "shade_grad / grad | first call value → grad | HLO value / grad (kB, loop fusions) |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="four BRDF x light pairs instead of all fifteen")
    parser.add_argument("--n", type=int, default=1 << 18, help="radiance evaluations per call (default 2^18)")
    parser.add_argument("--reps", type=int, default=5, help="interleaved timed calls per program (default 5)")
    parser.add_argument("--channels", choices=("grey", "rgb", "both"), default="grey",
                        help="grey scenes, RGB scenes, or each configuration both ways (default grey)")
    parser.add_argument("--out", help="write the markdown table here")
    args = parser.parse_args(argv)
    pairs = QUICK if args.quick else [(b, l) for b in BRDFS for l in LIGHTS]
    key = jax.random.key(1)
    print(f"gradient cost of shade, n = {args.n}, JAX {jax.__version__}, {platform.processor() or platform.machine()}, "
          f"{jax.devices()[0].platform}", flush=True)
    print(HEADER, flush=True)
    rows = []
    for brdf_name, light_name in pairs:
        for strategy in STRATEGIES:
            for mode in MODES:
                for channels in (("grey", "rgb") if args.channels == "both" else (args.channels,)):
                    r = measure(brdf_name, light_name, strategy, mode, args.n, args.reps, key, channels)
                    rows.append(r)
                    print(row_text(r), flush=True)
    ratio = [r["ns"]["grad"] / r["ns"]["value"] for r in rows]
    first = [r["first"]["grad"] / r["first"]["value"] for r in rows]
    errors = [r["ns"]["shade_grad"] / r["ns"]["grad"] for r in rows]
    summary = (f"\nOver {len(rows)} rows: grad / value run time median {np.median(ratio):.1f}x (max {max(ratio):.1f}x, "
               f"{sum(x <= 4 for x in ratio)} of {len(rows)} at most 4x); first call grad / value median "
               f"{np.median(first):.1f}x (max {max(first):.1f}x, {sum(x <= 2.5 for x in first)} at most 2.5x); "
               f"shade_grad / grad median {np.median(errors):.2f}x (max {max(errors):.2f}x, "
               f"{sum(x <= 1.5 for x in errors)} at most 1.5x).")
    if args.channels == "both":
        pairs = list(zip(rows[::2], rows[1::2]))
        value_rgb = [b["ns"]["value"] / a["ns"]["value"] for a, b in pairs]
        grad_rgb = [b["ns"]["grad"] / a["ns"]["grad"] for a, b in pairs]
        summary += (f"\nRGB / grey over {len(pairs)} configurations: value run time median {np.median(value_rgb):.1f}x "
                    f"(max {max(value_rgb):.1f}x), gradient median {np.median(grad_rgb):.1f}x "
                    f"(max {max(grad_rgb):.1f}x).")
    print(summary, flush=True)
    if args.out:
        with open(args.out, "w") as out:
            out.write(f"# Gradient cost of `shade`\n\n`python benchmarks/gradient_cost.py {' '.join(sys.argv[1:])}`; "
                      f"n = {args.n}, medians of {args.reps} interleaved calls; JAX {jax.__version__}, "
                      f"{jax.devices()[0].platform}.\n\n{HEADER}\n")
            out.write("\n".join(row_text(r) for r in rows) + "\n" + summary + "\n")


if __name__ == "__main__":
    main()
