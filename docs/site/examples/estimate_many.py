"""One estimate over every device of every process, with JAX's distributed runtime.

Start one copy per process with your launcher (SLURM's `srun`, `mpirun`), or by hand:
`python estimate_many.py PROCESS_ID PROCESS_COUNT COORDINATOR_HOST:PORT`. Alone, it runs as one
process. n must be a multiple of the device count (times the replicates for Sobol' and stratified
points).
"""

import os, sys
import jax, jax.numpy as jnp
import jaxsample as js

# SLURM sets these; by hand: python estimate_many.py PROCESS_ID PROCESS_COUNT COORDINATOR_HOST:PORT
process_id = int(os.environ.get("SLURM_PROCID", sys.argv[1] if len(sys.argv) > 1 else 0))
process_count = int(os.environ.get("SLURM_NTASKS", sys.argv[2] if len(sys.argv) > 2 else 1))
coordinator = os.environ.get("COORDINATOR", sys.argv[3] if len(sys.argv) > 3 else "127.0.0.1:12355")
jax.config.update("jax_cpu_collectives_implementation", "gloo")   # CPU collectives; GPUs use NCCL
jax.distributed.initialize(coordinator, num_processes=process_count, process_id=process_id)

mesh = jax.sharding.Mesh(jax.devices(), ("samples",))      # every device of every process
f = lambda w: jnp.maximum(w @ jnp.array([0.3, 0.2, 0.93]), 0.0) ** 3
est = jax.jit(lambda k: js.estimate(f, js.CosineHemisphere(), k, 1 << 24, mesh=mesh))(jax.random.key(0))
if jax.process_index() == 0:
    print(float(est.mean), "±", float(est.stderr))
jax.distributed.shutdown()
