"""OpenLane's lists of frames: test lists and the scenario lists of its six test cases.

A test list names one frame a line, by the image (or JSON) path relative to the ground-truth
and prediction folders; :func:`read_test_list` reads it as the official evaluator does and
:func:`write_test_list` writes one.

The OpenLane download lists the frames of each of its six cases in a text file of image
paths, one a line, named by the case with a prefix or suffix that depends on the subset:
``lane3d_1000/test/1000_curve.txt``, ``lane3d_300/test/curve.txt`` or ``curve_case.txt``.
:func:`read_scenario_lists` reads every ``*.txt`` of a folder and names each list by its case
(``curve``); a file of another name makes a scenario named by its stem.

The lines of these lists and of a test list may differ in their leading folders
(``validation/segment-x/1.jpg`` against ``test/curve_case/segment-x/1.jpg``), so frames are
matched by :func:`frame_key`, "<segment>/<timestamp>", which every layout shares.
"""

from __future__ import annotations

import os
import re
from pathlib import Path, PurePosixPath
from typing import Iterable

from lanelab.atomic_file import atomic_output
from lanelab.json_files import LaneFileError

# OpenLane's scenario lists -> column labels, in the order of SparseLaneSTP's Table 4.
OPENLANE_SCENARIOS = {
    "up_down": "Up & Down",
    "curve": "Curve",
    "extreme_weather": "Extreme Weather",
    "night": "Night",
    "intersection": "Intersection",
    "merge_split": "Merge & Split",
}

# "1000_curve", "curve", "curve_case" -> "curve"
_CASE_NAME = re.compile(r"^(?:\d+_)?(?P<name>.+?)(?:_case)?$")


def read_test_list(path: str | os.PathLike[str]) -> list[str]:
    """Relative JSON paths named by a test list (one image or JSON path a line).

    As the official evaluator does, every 'jpg' in a line becomes 'json'. Blank lines are
    skipped (the official one crashes on them).
    """
    try:
        text = Path(path).read_text()
    except OSError as error:
        raise LaneFileError(path, f"cannot read the test list ({error.strerror})") from None
    return [line.replace("jpg", "json").lstrip("/") for line in text.splitlines() if line.strip()]


def write_test_list(path: str | os.PathLike[str], file_paths: Iterable[str]) -> None:
    """Write a test list of these frames (their ``file_path``, one a line), atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text("".join(f"{file_path}\n" for file_path in file_paths))


def case_name(list_file: str | os.PathLike[str]) -> str:
    """The case a list file holds: '1000_curve.txt', 'curve.txt', 'curve_case.txt' -> 'curve'."""
    return _CASE_NAME.match(Path(list_file).stem)["name"]


def frame_key(path: str) -> str:
    """'validation/segment-x/155.jpg' (or .json, any leading folders) -> 'segment-x/155'."""
    path = PurePosixPath(path)
    return f"{path.parent.name}/{path.stem}"


def read_scenario_lists(directory: str | os.PathLike[str]) -> dict[str, frozenset[str]]:
    """Case name -> frame keys of every ``*.txt`` list in directory.

    The six OpenLane cases come first, in the order of the papers' tables, then any other
    list by name. Raises LaneFileError naming the folder when it holds no list, or the file
    that cannot be read.
    """
    files = sorted(Path(directory).glob("*.txt"))
    if not files:
        raise LaneFileError(directory, "no scenario lists (*.txt) in this folder")
    lists = {case_name(f): frozenset(frame_key(line) for line in read_test_list(f)) for f in files}
    order = list(OPENLANE_SCENARIOS) + sorted(set(lists) - set(OPENLANE_SCENARIOS))
    return {name: lists[name] for name in order if name in lists}
