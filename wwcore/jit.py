"""The one place that configures numba for windwarden's compiled kernels (``wwcore.backend``).

Kernels are compiled on first call and cached on disk (``cache=True``), under ``$WINDWARDEN_CACHE/numba`` or
``~/.cache/windwarden/numba`` (as the wake tables are, ``plant_sim.farm.floris_wakes``) unless
``$NUMBA_CACHE_DIR`` says otherwise: a second process loads the machine code instead of compiling it again.
numba keys each entry on the kernel's own source file (its time stamp and size) and the CPU, not on the files of
the kernels it calls, whose code it compiles in: a kernel whose callee in another module changed would load stale
machine code. So the entries live in a subdirectory named by a hash of every module of the packages that hold
kernels (``source_key``): any change to them compiles afresh, once.

No ``fastmath``: floating-point operations keep IEEE semantics and the order the source gives them, which is what
lets a kernel reproduce the numpy reference bit for bit where it performs the same operations in the same order.
``error_model="numpy"``: a division by zero gives inf/nan as numpy does rather than raising.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

KERNEL_PACKAGES = ("wwcore", "plant_sim", "service")
"""The packages whose modules hold kernels or code compiled into them."""


def source_key(root: Path | None = None) -> str:
    """A hash (16 hex digits) of every module of ``KERNEL_PACKAGES`` under ``root`` (default: as installed), names
    and contents."""
    root = Path(__file__).resolve().parents[1] if root is None else root
    digest = hashlib.sha256()
    for package in KERNEL_PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_dir() -> Path:
    """``$NUMBA_CACHE_DIR``, else ``$WINDWARDEN_CACHE/numba``, else ``~/.cache/windwarden/numba``; in it the
    subdirectory of this source's ``source_key``."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        base = Path(os.environ["NUMBA_CACHE_DIR"])
    else:
        root = os.environ.get("WINDWARDEN_CACHE")
        base = Path(root) / "numba" if root else Path.home() / ".cache" / "windwarden" / "numba"
    return base / f"source-{source_key()}"


# numba reads its cache directory when a cached function is decorated: set before any kernel module is imported
numba.config.CACHE_DIR = str(cache_dir())


def kernel(func):
    """Compile ``func`` in nopython mode, cached on disk, releasing the GIL, with numpy's division semantics."""
    return numba.njit(cache=True, nogil=True, error_model="numpy")(func)


def inlined_kernel(func):
    """``kernel``, inlined by numba into every kernel that calls it (``inline="always"``): its arrays are the
    caller's, so LLVM sees their allocation (a shape the caller gives as a constant stays one, as in
    ``service.turbine.fast_actuator._signature_block_lanes``)."""
    return numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")(func)


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
