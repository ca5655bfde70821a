"""`python -m jaxsample report [--quick] [--out DIR]`: see jaxsample.report."""

import sys

from .report import main

sys.exit(main())
