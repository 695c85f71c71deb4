"""windwarden application layer: the command line, batch evaluation and the live orchestration.

This is the top of the dependency graph: it may import every other package; nothing imports it.
"""

import os

# The numerical core multiplies small matrices (tens of rows); evaluation parallelises over processes instead.
# One BLAS thread per process avoids oversubscribing the cores and keeps summation order, hence results, fixed.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

__version__ = "0.1.0"
