"""Many sphere lights: one `SphereLights` batch against a Python list of `SphereLight`s.

    python benchmarks/many_lights.py [--counts 1 4 16 64 256 1000] [--list-up-to 16] [--n 65536]

Each configuration runs in a fresh process (so every first call compiles): the first call of
`scene.shade` (trace, lower, compile, one run; Lambertian, "mis", n evaluations) and the median of
three later calls. A list is unrolled into the program, so its first call grows with the number of
lights; a batch is one program whatever its number, and its run time grows with it (every
direction is tested against every cone).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

_ONE = r"""
import json, statistics, sys, time, warnings
import jax, jax.numpy as jnp, numpy as np
from jaxsample import scene
count, kind, n = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
rng = np.random.default_rng(0)
centers = np.stack([rng.uniform(-3, 3, count), rng.uniform(-3, 3, count), rng.uniform(1.0, 4.0, count)], -1)
if kind == "batch":
    lights = scene.SphereLights(jnp.asarray(centers, jnp.float32), jnp.full(count, 0.2), jnp.ones(count))
else:
    lights = [scene.SphereLight(jnp.asarray(c, jnp.float32), 0.2, 1.0) for c in centers]
args = (jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0]), scene.Lambertian(0.8), lights)
warnings.simplefilter("ignore")
start = time.perf_counter()
float(scene.shade(*args, jax.random.key(0), n).mean)
first = time.perf_counter() - start
times = []
for i in range(3):
    start = time.perf_counter()
    float(scene.shade(*args, jax.random.key(1 + i), n).mean)
    times.append(time.perf_counter() - start)
print(json.dumps({"lights": count, "kind": kind, "first_call_s": first, "run_ms": 1e3 * statistics.median(times)}))
"""


def measure(count: int, kind: str, n: int) -> dict:
    out = subprocess.run([sys.executable, "-c", _ONE, str(count), kind, str(n)], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 4, 16, 64, 256, 1000])
    parser.add_argument("--list-up-to", type=int, default=16)
    parser.add_argument("--n", type=int, default=1 << 16)
    args = parser.parse_args(argv)
    print("| lights | kind | first call (s) | later calls (ms) |\n|---|---|---|---|")
    for kind in ("list", "batch"):
        for count in args.counts:
            if kind == "list" and count > args.list_up_to:
                continue
            row = measure(count, kind, args.n)
            print(f"| {count} | {kind} | {row['first_call_s']:.2f} | {row['run_ms']:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
