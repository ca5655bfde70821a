"""One estimate over two processes with JAX's distributed runtime.

Two processes on this machine (one CPU device each; coordinator on 127.0.0.1 with a free port;
CPU collectives through gloo) run `tests/multiprocess_worker.py` over the global mesh: `estimate`
with "random" and "sobol" uniforms, a `Rejection` sampler, `estimate_mis`, and `expectation`'s
pathwise and score gradients. The test's own process runs the same calls without a mesh while
they run (`multiprocess_worker.results(None)`, as `python multiprocess_worker.py OUT.json` would;
a third interpreter cost a JAX import and seven compilations more). Every run draws
the same points (the i-th sample depends only on the key and i), so the results agree to float
rounding: means and gradients to 2e-6 relative (the partial sums are added in another order),
standard errors to 1e-5. Bounded: each process is killed after TIMEOUT_S.
"""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np

import multiprocess_worker

WORKER = Path(__file__).with_name("multiprocess_worker.py")
TIMEOUT_S = 300


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _environment():
    # One device per process, whatever device count the caller forced; its other compiler options
    # (tests/conftest.py) are kept.
    flags = " ".join(flag for flag in os.environ.get("XLA_FLAGS", "").split() if "device_count" not in flag)
    return dict(os.environ, JAX_PLATFORMS="cpu", PYTHONUNBUFFERED="1", XLA_FLAGS=flags)


def test_two_processes_give_the_single_process_results(tmp_path):
    port = _free_port()
    multi = tmp_path / "multi.json"
    commands = [[sys.executable, str(WORKER), str(multi), str(i), "2", str(port)] for i in range(2)]
    processes = [subprocess.Popen(c, env=_environment(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                 for c in commands]
    try:
        # The worker hands the same keys to several programs, as a script may; the suite's
        # key-reuse checker (tests/conftest.py) would call that reuse.
        with jax.debug_key_reuse(False):
            single = dict(multiprocess_worker.results(None), devices=len(jax.devices()),
                          processes=jax.process_count())
        outputs = [p.communicate(timeout=TIMEOUT_S)[0] for p in processes]
    finally:
        for p in processes:
            if p.poll() is None:
                p.kill()
                p.wait()
    for p, out in zip(processes, outputs):
        assert p.returncode == 0, out[-3000:]
    a, b = json.loads(multi.read_text()), single
    assert (a.pop("processes"), a.pop("devices")) == (2, 2)
    assert (b.pop("processes"), b.pop("devices")) == (1, 1)
    assert a.keys() == b.keys() and len(a) == 7
    for name in a:
        (value_a, second_a), (value_b, second_b) = a[name], b[name]
        np.testing.assert_allclose(value_a, value_b, rtol=2e-6, err_msg=name)
        # the second entry is a standard error, or a gradient for expectation_grad/*
        rtol = 2e-6 if name.startswith("expectation_grad") else 1e-5
        np.testing.assert_allclose(second_a, second_b, rtol=rtol, err_msg=name)
