"""Named planes of one array: an object's per-row state arrays of one dtype and shape kept as views of one block
(``block[i]``, or a range ``block[:-1]``), so that a compiled kernel takes the block (one array to unbox,
``wwcore.jit``) while the numpy code reads and writes each array by its name as before.

A copy or a pickle of a numpy view is a new array, no longer a view of anything: ``Planes`` (a mixin) drops each
named view from the object's state while it is still the view of its block, and takes it again from the block
(copied once, with whatever else shares it) when the state is restored, so the copy's planes are views of the
copy's block. An array the object has put in a plane's place (as the numpy reference may) is copied as any
attribute is. Views of a plane held outside the object are not followed: its holders keep the object or the block.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np


def planes(block: np.ndarray, names: tuple) -> dict[str, np.ndarray]:
    """{name: view}: the views of ``block`` by name, each name's index its position in ``names`` (``block[i]``) or
    given with it, as a (name, index or slice) pair."""
    return {name: block[key] for name, key in _keys(names)}


def _keys(names: tuple) -> list[tuple[str, int | slice]]:
    return [(entry, i) if isinstance(entry, str) else entry for i, entry in enumerate(names)]


class Planes:
    """State arrays as named views of a block (module docstring). ``PLANES`` maps each block's attribute to the
    names of its views (``planes``); the class sets them with ``planes`` when it builds the block."""

    PLANES: ClassVar[dict[str, tuple]] = {}

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        for block_name, names in self.PLANES.items():
            block = state[block_name]
            for name, key in _keys(names):
                view, plane = state.get(name), block[key]
                if (
                    isinstance(view, np.ndarray)
                    and view.base is block
                    and view.ctypes.data == plane.ctypes.data
                    and view.shape == plane.shape
                ):
                    del state[name]  # taken again from the block by ``__setstate__``
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        for block_name, names in self.PLANES.items():
            block = state[block_name]
            for name, key in _keys(names):
                if name not in state:
                    setattr(self, name, block[key])
