"""OpenLane's scenario lists: which frames make the Up & Down, Curve, ... test cases.

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
from typing import Iterable, Mapping

from lanelab.metrics.json_files import LaneFileError
from lanelab.metrics.openlane_io import read_test_list
from lanelab.metrics.scenarios import OPENLANE_SCENARIOS, Scenario, list_scenarios

# "1000_curve", "curve", "curve_case" -> "curve"
_CASE_NAME = re.compile(r"^(?:\d+_)?(?P<name>.+?)(?:_case)?$")


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


def scenarios_of(lists: Mapping[str, frozenset[str]], frame_ids: Iterable[str]) -> list[Scenario]:
    """The scenarios of the lists over frame_ids (test-list ids, as evaluate_frames names
    frames): each holds the ids whose frame_key its list names; labelled as in the papers."""
    frame_ids = list(frame_ids)
    return list_scenarios({
        name: [frame for frame in frame_ids if frame_key(frame) in keys] for name, keys in lists.items()
    })
