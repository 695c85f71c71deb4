"""A kernel's kept arguments as one argument: ``Kept(args)`` is a numba ``structref`` holding the tuple ``args``
(arrays, scalars, None, nested tuples) by reference, so a compiled entry point that takes it unboxes one object
instead of every array in the tuple; it reads them back with ``kept.args``.

numba's dispatcher unboxes each array argument of a call separately (about 0.06 µs an array on this machine,
``tools/kernel_call_cost.py``); a structref argument is one pointer to memory numba allocated when it was built,
in which the arrays are held as numba holds any array argument: their data pointers are the numpy buffers
themselves, and each array object is kept alive as long as the struct. So the kernel and Python read and write
the same memory: an array of ``args`` updated in place by either is seen by the other. An array that Python
replaces (a new object in the owner's attribute) is not: the struct keeps the one it was built with, so what a
struct holds follows the rule of the kept arguments it replaces (arrays updated in place, never replaced).
Scalars are copied into the struct when it is built (the kept arguments' scalars are constants).

The struct is built by a cached kernel (``keep``), and the entry points that take it are cached kernels, so a
second process loads both from numba's disk cache (``wwcore.jit``; ``tests/test_kept.py``). A copy or a pickle
of a ``Kept`` builds a new struct from a copy of its ``args`` (``__reduce__``): a deep copy of the object that
owns it holds the copy's arrays, as its other attributes do.
"""

from __future__ import annotations

from numba.core import types
from numba.experimental import structref

from wwcore.jit import kernel


@structref.register
class KeptType(types.StructRef):
    """The numba type of a ``Kept``: one field, ``args``, of the tuple's type."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Kept(structref.StructRefProxy):
    """A kernel's kept arguments ``args`` (a tuple) as one numba argument (module docstring). ``args`` is the
    tuple given, kept on the Python side for copies and pickles."""

    def __new__(cls, args: tuple):
        kept = keep(args)  # the struct built by a cached kernel, not by numba's uncached constructor
        kept.args = args
        return kept

    def __reduce__(self):
        return Kept, (self.args,)


structref.define_proxy(Kept, KeptType, ["args"])


@kernel
def keep(args):
    """A new ``Kept`` struct holding ``args``."""
    return Kept(args)
