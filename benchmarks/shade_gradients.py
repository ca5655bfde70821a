"""Run the report's check of shade's gradients alone: `python benchmarks/shade_gradients.py [--quick] [--out DIR]`.

The code lives in the package (`jaxsample/report/shade_gradients.py`): z-scores of every gradient of
12 configurations per light against finite differences of the float64 reference, per strategy and
mode, with and without the silhouettes' boundary term, and the term's cost per gradient sample.
"""

import runpy

runpy.run_module("jaxsample.report.shade_gradients", run_name="__main__", alter_sys=True)
