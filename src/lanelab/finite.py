"""The error of numbers that must be finite and are not: NaN or inf in a store's frame, a loss
or a checkpoint's weights. Its message names where (the clip and frame, the batch, the file)."""

from __future__ import annotations


class NonFiniteError(ValueError):
    """Numbers that must be finite hold NaN or inf; the message says where."""
