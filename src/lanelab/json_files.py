"""Reading lane JSON files with errors that name the file and the problem.

Shared by the readers of OpenLane (:mod:`lanelab.openlane`, the OpenLane adapter's annotation
reader) and of ONCE-3DLanes (:mod:`lanelab.metrics.once`): a malformed file raises
:class:`LaneFileError` ("<path>: <problem>"), never a traceback from deep inside numpy.
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np


class LaneFileError(ValueError):
    """A lane JSON file (or a list of files) does not have the layout its reader expects."""

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = str(path)
        self.problem = problem


def load_json_object(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The JSON object stored in path."""
    try:
        with open(path) as f:
            data = json.load(f)
    except OSError as error:
        raise LaneFileError(path, f"cannot read the file ({error.strerror})") from None
    except json.JSONDecodeError as error:
        raise LaneFileError(path, f"not valid JSON ({error})") from None
    if not isinstance(data, dict):
        raise LaneFileError(path, "the top level must be a JSON object")
    return data


def require(obj: Any, key: str, path: str | os.PathLike[str], where: str = "") -> Any:
    """obj[key], where obj must be a JSON object; `where` names obj in the message."""
    if not isinstance(obj, dict):
        raise LaneFileError(path, f"{where or 'the top level'} must be a JSON object")
    if key not in obj:
        raise LaneFileError(path, f"missing key '{key}'" + (f" in {where}" if where else ""))
    return obj[key]


def require_list(obj: Any, key: str, path: str | os.PathLike[str], where: str = "") -> list[Any]:
    """obj[key], which must be a JSON list."""
    value = require(obj, key, path, where)
    if not isinstance(value, list):
        raise LaneFileError(path, f"'{key}' must be a list" + (f" in {where}" if where else ""))
    return value


def numeric_array(
    value: Any, shape: tuple[int | None, ...], what: str, path: str | os.PathLike[str]
) -> np.ndarray:
    """value as a float64 array of the given shape (None: any length)."""
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise LaneFileError(path, f"{what} must be a numeric array") from None
    wrong_length = any(n is not None and n != m for n, m in zip(shape, array.shape))
    if array.ndim != len(shape) or wrong_length:
        expected = "(" + ", ".join("N" if n is None else str(n) for n in shape) + ")"
        raise LaneFileError(path, f"{what} must have shape {expected}, got {array.shape}")
    return array
