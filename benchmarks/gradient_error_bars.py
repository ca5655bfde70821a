"""Run the gradient-error-bar and accuracy tables of the report alone:
`python benchmarks/gradient_error_bars.py [--quick]`.

The code lives in the package (`jaxsample/report/gradient_error_bars.py`, also
`python -m jaxsample.report.gradient_error_bars`), so the report runs from any directory after
`pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.gradient_error_bars", run_name="__main__", alter_sys=True)
