"""Calibration of the z-scores `tests/scene/test_rough_conductor_and_quad.py` holds to |z| < 4.5: the
report's conductor program (RGB gold under a quad light, `shade` and `shade_grad` per channel, default
"mis", attached, 4096 evaluations) against the float64 quadrature's central differences, over many keys.

    python benchmarks/conductor_quad_calibration.py [KEYS]      # default 40

Prints the mean and spread of z per channel and parameter and the largest |z|: for calibrated error
bars the means are near 0 (a mean of K keys carries ±1/sqrt(K)), the spreads near 1.
"""

import sys
import time
import warnings

import jax
import numpy as np

from jaxsample.report import inverse_problem as ip


def main(keys: int = 40) -> None:
    warnings.simplefilter("ignore")
    cases = ip.CONDUCTOR_QUAD_CASES
    start = time.perf_counter()
    references = [ip.conductor_quad_reference(case, panels=32) for case in cases]
    print(f"references: {time.perf_counter() - start:.1f} s", flush=True)
    ref_value = np.array([r[0] for r in references])
    ref_grad = np.stack([r[1] for r in references])
    configs, params = ip.conductor_quad_inputs(cases)
    program = ip.conductor_quad_program(4096)
    z_values, z_grads = [], []
    for seed in range(keys):
        split = jax.random.split(jax.random.key(1000 + seed), len(cases))
        value, value_err, grad, grad_err = (np.asarray(a, float) for a in program(configs, params, split))
        z_values.append((value - ref_value) / np.sqrt(value_err ** 2 + (1e-4 * np.abs(ref_value)) ** 2))
        z_grads.append((grad - ref_grad) / np.sqrt(grad_err ** 2 + (1e-4 * np.abs(ref_grad) + 1e-7) ** 2))
    zv, zg = np.array(z_values), np.array(z_grads)   # (keys, cases, channels) and (..., parameters)
    print("value z per channel: mean", zv.mean(axis=(0, 1)).round(2), "sd", zv.std(axis=(0, 1)).round(2))
    print("gradient z per parameter", ip.CONDUCTOR_QUAD_PARAMETERS, ": mean", zg.mean(axis=(0, 1, 2)).round(2),
          "sd", zg.std(axis=(0, 1, 2)).round(2))
    print("per (case, channel, parameter): mean z in", zg.mean(0).min().round(2), "..", zg.mean(0).max().round(2),
          ", sd in", zg.std(0).min().round(2), "..", zg.std(0).max().round(2))
    print(f"largest |z|: value {np.abs(zv).max():.2f}, gradient {np.abs(zg).max():.2f} of {zv.size + zg.size}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
