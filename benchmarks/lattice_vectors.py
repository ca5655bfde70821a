"""Generating vectors compared: the rule error of the shifted, tent-transformed lattice by m and d.

    python benchmarks/lattice_vectors.py [VECTOR_FILE ...]

Each VECTOR_FILE holds one generating vector (one integer per line, at least 32 of them; Kuo's
files from https://web.maths.unsw.edu.au/~fkuo/lattice/ with their comment lines removed); the
vector `jaxsample.uniforms.Lattice` ships is always included. For each vector it prints Zaremba's
index of the first three coordinates (min over the nonzero dual vectors h, |h_2|, |h_3| <= 40, of
prod max(1, |h_j|)) at m = 10 .. 20, and the root-mean-square error over 4 random shifts of the
2^m-point rule (float64 NumPy, exact integer products) at m = 10, 12, ..., 20 on two smooth
integrands with integral 1: prod_j e^(x_j) / (e - 1) (equal weights, d = 2, 3, 4, 6) and
prod_j (1 + (e^(x_j) - (e - 1)) / j^2) (decaying weights, d = 8, 32).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from jaxsample.uniforms import lattice_generating_vector

M_ERRORS = (10, 12, 14, 16, 18, 20)


def shortest_dual(z, m: int, reach: int = 40) -> int:
    n = 1 << m
    h2, h3 = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1))
    h1 = -(h2 * int(z[1]) + h3 * int(z[2])) % n
    h1 = np.where(h1 > n // 2, h1 - n, h1)
    weight = np.maximum(1, np.abs(h1)) * np.maximum(1, np.abs(h2)) * np.maximum(1, np.abs(h3))
    return int(weight[(h2 != 0) | (h3 != 0)].min())


def rule(z, m: int, dims: int, shift, f) -> float:
    n = 1 << m
    total = 0.0
    for start in range(0, n, 1 << 16):
        k = np.arange(start, min(n, start + (1 << 16)), dtype=np.int64)
        x = np.mod(np.outer(k, z[:dims]).astype(np.float64) / n + shift, 1.0)
        total += f(1.0 - np.abs(2.0 * x - 1.0)).sum()
    return total / n


def equal(x):
    return np.prod(np.exp(x) / (np.e - 1.0), axis=1)


def decaying(x):
    j = np.arange(1, x.shape[1] + 1)
    return np.prod(1.0 + (np.exp(x) - (np.e - 1.0)) / j ** 2, axis=1)


def main(paths):
    vectors = {"shipped": lattice_generating_vector(32).astype(np.int64)}
    for path in paths:
        vectors[Path(path).stem] = np.loadtxt(path, dtype=np.int64)[:32]
    rng = np.random.default_rng(1)
    print("Zaremba index of coordinates 1-3, m = 10 .. 20")
    for name, z in vectors.items():
        print(f"  {name:36s}", " ".join(str(shortest_dual(z, m)) for m in range(10, 21)))
    print("RMS error over 4 shifts, m = " + ", ".join(map(str, M_ERRORS)))
    for dims, f, label in [(2, equal, "equal"), (3, equal, "equal"), (4, equal, "equal"), (6, equal, "equal"),
                           (8, decaying, "decaying"), (32, decaying, "decaying")]:
        for name, z in vectors.items():
            errors = [np.sqrt(np.mean([(rule(z, m, dims, rng.random(dims), f) - 1.0) ** 2 for _ in range(4)]))
                      for m in M_ERRORS]
            print(f"  d={dims:2d} {label:8s} {name:36s}", " ".join(f"{e:.1e}" for e in errors), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
