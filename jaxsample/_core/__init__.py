"""Layer 1 and the engine's private pieces: safe elementary functions (`numerics`), double-float
sums (`doublefloat`), the pytree machinery (`pytree`), parameter checks (`params`), and the lane
helpers the compiled loops are built from (`lanes`, `computed_once`). Nothing here is public API
except what `jaxsample.numerics` re-exports."""
