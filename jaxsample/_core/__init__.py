"""Layer 1 and the engine's private pieces: safe elementary functions (`numerics`), double-float
sums (`doublefloat`), the pytree machinery (`pytree`), parameter checks (`params`), and the lane
helpers the compiled loops are built from (`lanes`, `computed_once`), where those run (`cpu_paths`:
the CPU, and the JAXSAMPLE_LANES switch) and every use of JAX's internals (`jax_internals`). Nothing
here is public API except what `jaxsample.numerics` re-exports."""
