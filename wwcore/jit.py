"""The one place that configures numba for windwarden's compiled kernels (``wwcore.backend``).

Kernels are compiled on first call and cached on disk (``cache=True``), under ``$WINDWARDEN_CACHE/numba`` or
``~/.cache/windwarden/numba`` (as the wake tables are, ``plant_sim.farm.floris_wakes``) unless
``$NUMBA_CACHE_DIR`` says otherwise: a second process loads the machine code instead of compiling it again.
numba keys each entry on the kernel's source file and the CPU, so a changed kernel or another machine recompiles.

No ``fastmath``: floating-point operations keep IEEE semantics and the order the source gives them, which is what
lets a kernel reproduce the numpy reference bit for bit where it performs the same operations in the same order.
``error_model="numpy"``: a division by zero gives inf/nan as numpy does rather than raising.
"""

from __future__ import annotations

import os
from pathlib import Path

import numba
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic


def cache_dir() -> Path:
    """``$NUMBA_CACHE_DIR``, else ``$WINDWARDEN_CACHE/numba``, else ``~/.cache/windwarden/numba``."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    root = os.environ.get("WINDWARDEN_CACHE")
    return Path(root) / "numba" if root else Path.home() / ".cache" / "windwarden" / "numba"


# numba reads its cache directory when a cached function is decorated: set before any kernel module is imported
numba.config.CACHE_DIR = str(cache_dir())


def kernel(func):
    """Compile ``func`` in nopython mode, cached on disk, releasing the GIL, with numpy's division semantics."""
    return numba.njit(cache=True, nogil=True, error_model="numpy")(func)


@intrinsic
def fma(typingctx, a, b, c):
    """a·b + c rounded once (IEEE fused multiply-add, LLVM's ``llvm.fma``): what numpy's SIMD complex loops
    and OpenBLAS's kernels use, for the kernels that reproduce their results."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        double = ir.DoubleType()
        function = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(double, [double, double, double]), "llvm.fma.f64"
        )
        return builder.call(function, args)

    return signature, codegen
