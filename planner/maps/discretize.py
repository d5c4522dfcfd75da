"""Pixels (or characters) to sub-cells: a sub-cell is free only if every pixel in it is.

numpy's reshape turns the image into (rows, size, cols, size) blocks so the rule is one
``all`` over two axes, with no Python loop over pixels.
"""

from __future__ import annotations

import numpy as np

from planner.errors import MapFormatError
from planner.types import BoolArray


def check_cell_size(cell_size: int, source: str) -> int:
    if isinstance(cell_size, bool) or not isinstance(cell_size, int) or cell_size < 1:
        raise MapFormatError(source, f"cell_size must be a positive integer, got {cell_size!r}")
    return cell_size


def downsample(free: BoolArray, cell_size: int, source: str) -> BoolArray:
    """Sub-cells of ``cell_size`` x ``cell_size`` pixels; trailing partial blocks are dropped."""
    size = check_cell_size(cell_size, source)
    if size == 1:
        return free
    h, w = free.shape
    rows, cols = h // size, w // size
    if rows == 0 or cols == 0:
        raise MapFormatError(
            source, f"map of {h} x {w} pixels holds no whole {size} x {size} sub-cell")
    blocks = free[: rows * size, : cols * size].reshape(rows, size, cols, size)
    return np.asarray(blocks.all(axis=(1, 3)), dtype=np.bool_)
