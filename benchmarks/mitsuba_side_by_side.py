"""jaxsample against Mitsuba 3 on the same two estimates, in one process, interleaved.

    python benchmarks/mitsuba_side_by_side.py [--log2n 24] [--repeats 7] [--out FILE.md]

The two programs, each a cosine-weighted hemisphere estimate of one number from n samples:
  ∫cos³θ dω               (only z = cos θ of the sample is used: the warp's sine and cosine of φ
                           are dead code in both systems)
  ∫max(ω·a, 0)³ dω         (a tilted axis: x, y and z are used, so φ's sine and cosine are paid)
jaxsample: `estimate(f, CosineHemisphere(), key, n).mean` under `jax.jit` (Philox4x32-10 uniforms,
the concentric map, f / p summed in the fused lanes). Mitsuba 3 (`llvm_ad_rgb` variant, Dr.Jit's
LLVM backend, the same concentric map `warp.square_to_cosine_hemisphere` and its pdf, PCG32 uniforms
seeded per call through an opaque variable so that its kernel is compiled once), `dr.mean(f / p)`
evaluated. Both use every core (XLA's CPU thread pool; Dr.Jit's own pool). Each system runs in a
process of its own, the two alternating `--alternations` times; in each, a system's two programs are
called `--repeats` times in a seeded random order (`interleaved_medians`) after one warm-up call each
(which compiles), and the table gives every process's median and the median of the paired ratios.

Mitsuba is not a dependency: `pip install mitsuba` into the same environment (the results file
`benchmarks/results/generators-and-mitsuba-cpu-2core-2026-12-04.md` names the versions it measured).
Dr.Jit loads libLLVM at run time. This machine's own /lib/x86_64-linux-gnu/libLLVM-15
loads but cannot compile Mitsuba's warps ("LLVM ERROR: Cannot select ... fmaximum": Dr.Jit emits
llvm.maximum, which LLVM 15's x86 backend does not lower), so it runs with Debian's LLVM 19 beside
it, as for the figures in benchmarks/results/:
    apt-get install libllvm19
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so python benchmarks/mitsuba_side_by_side.py
Without Mitsuba the script measures jaxsample alone and says so.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample.report.timing import interleaved_medians

AXIS = (0.3, 0.2, 0.9327379)
EXACT = {"cos3": np.pi / 2}  # ∫cos^k θ dω over the hemisphere = 2π / (k + 1)


def jaxsample_programs(n):
    a = jnp.array(AXIS, jnp.float32)
    cos3 = lambda w: w[2] ** 3
    tilted = lambda w: jnp.maximum(w[0] * a[0] + w[1] * a[1] + w[2] * a[2], 0.0) ** 3
    return {name: jax.jit(lambda k, f=f: js.estimate(f, js.CosineHemisphere(), k, n).mean)
            for name, f in (("cos3", cos3), ("tilted", tilted))}


def mitsuba_programs(n):
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        return {}, None
    mi.set_variant("llvm_ad_rgb")

    def program(which):
        def run(key):
            seed = int(jax.random.randint(key, (), 0, 2**31 - 1))
            rng = mi.PCG32(size=n, initstate=dr.opaque(mi.UInt64, seed))
            u = mi.Point2f(rng.next_float32(), rng.next_float32())
            w = mi.warp.square_to_cosine_hemisphere(u)
            pdf = mi.warp.square_to_cosine_hemisphere_pdf(w)
            if which == "cos3":
                f = w.z * w.z * w.z
            else:
                c = dr.maximum(w.x * AXIS[0] + w.y * AXIS[1] + w.z * AXIS[2], 0.0)
                f = c * c * c
            mean = dr.mean(dr.select(pdf > 0, f / pdf, 0.0))
            dr.eval(mean)
            return float(mean[0] if hasattr(mean, "__len__") else mean)
        return run

    versions = f"Mitsuba {mi.__version__}, Dr.Jit {dr.__version__}"
    return {"mitsuba cos3": program("cos3"), "mitsuba tilted": program("tilted")}, versions


def _measure(system, n, repeats):
    """Medians (seconds) of this system's two programs, in this process."""
    if system == "jaxsample":
        fns = jaxsample_programs(n)
        version = f"JAX {jax.__version__}"
    else:
        fns, version = mitsuba_programs(n)
        if not fns:
            return None, None
        fns = {name.removeprefix("mitsuba "): fn for name, fn in fns.items()}
    for name, fn in fns.items():
        value = float(fn(jax.random.key(1)))
        exact = f" (exact {EXACT['cos3']:.6f})" if name == "cos3" else ""
        print(f"  {system:9s} {name:6s} estimate {value:.6f}{exact}", file=sys.stderr)
    keys = iter(jax.random.split(jax.random.key(7), 1000))
    return interleaved_medians(fns, keys, repeats), version


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--log2n", type=int, default=24)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--alternations", type=int, default=3)
    parser.add_argument("--out", default=None)
    parser.add_argument("--system", choices=("jaxsample", "mitsuba"), default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    n = 1 << args.log2n
    if args.system:  # one measurement, in a process of its own
        t, version = _measure(args.system, n, args.repeats)
        print(json.dumps({"seconds": t, "version": version}))
        return
    # Each system in a process of its own, the two alternating: in one process Dr.Jit's worker threads
    # (which spin for a while after a kernel) and XLA's thread pool slowed whichever ran next.
    runs = {"jaxsample": [], "mitsuba": []}
    versions = {}
    for _ in range(args.alternations):
        for system in runs:
            command = [sys.executable, __file__, "--system", system, "--log2n", str(args.log2n),
                       "--repeats", str(args.repeats)]
            result = json.loads(subprocess.run(command, check=True, capture_output=True, text=True).stdout)
            if result["seconds"] is not None:
                runs[system].append(result["seconds"])
                versions[system] = result["version"]
    flags = os.environ.get("XLA_FLAGS", "")
    lines = [f"n = 2^{args.log2n}; per system the median of {args.repeats} calls in each of {args.alternations} "
             f"alternating processes; {platform.machine()}, {os.cpu_count()} cores; XLA_FLAGS={flags!r}; "
             + ", ".join(versions.values()) + ("" if runs["mitsuba"] else "; Mitsuba not installed"), "",
             "| program | jaxsample M samples/s | Mitsuba 3 M samples/s "
             "| jaxsample / Mitsuba (median of the alternations) |",
             "|---|---|---|---|"]
    for name in ("cos3", "tilted"):
        ours = [n / t[name] / 1e6 for t in runs["jaxsample"]]
        cell = lambda v: " / ".join(f"{x:.0f}" for x in v)
        if runs["mitsuba"]:
            theirs = [n / t[name] / 1e6 for t in runs["mitsuba"]]
            ratio = statistics.median(a / b for a, b in zip(ours, theirs))
            lines.append(f"| {name} | {cell(ours)} | {cell(theirs)} | {ratio:.2f}x |")
        else:
            lines.append(f"| {name} | {cell(ours)} | — | — |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        with open(args.out, "a") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
