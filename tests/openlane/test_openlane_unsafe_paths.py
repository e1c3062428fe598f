"""Issue 37, case 1: a ``file_path`` (a frame's tag, a test-list line) is data. Every OpenLane
writer joins it under its folder or refuses it, for a ``..`` path, an absolute one and a link
that leads elsewhere; nothing is written outside."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lanelab.data_paths import UnsafePathError, path_inside, path_problem
from lanelab.lanes import Lane
from lanelab.openlane.write import write_ground_truth, write_prediction

K = np.array([[1000.0, 0.0, 480.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]])
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])
LANE = Lane(np.stack([np.zeros(5), np.arange(5.0, 10.0), np.zeros(5)], 1), np.ones(5), 2)


def escaping_paths(tmp_path: Path) -> dict[str, str]:
    """A relative path that climbs to tmp_path/outside from any folder below tmp_path, and an absolute one."""
    outside = tmp_path / "outside"
    return {"relative": "../" * (len(tmp_path.parts) + 3) + f"{outside.relative_to('/')}/rel.jpg",
            "absolute": str(outside / "abs.jpg")}


@pytest.mark.parametrize("kind", ["relative", "absolute"])
@pytest.mark.parametrize("write", [
    lambda out, file_path: write_prediction(out, file_path, [LANE]),
    lambda out, file_path: write_ground_truth(out, file_path, [LANE], K, T_LANE_CAM),
], ids=["prediction", "ground_truth"])  # fmt: skip
def test_openlane_writers_refuse_a_file_path_leading_out_of_their_folder(tmp_path, kind, write):
    file_path = escaping_paths(tmp_path)[kind]
    out = tmp_path / "ev" / "predictions"
    with pytest.raises(UnsafePathError, match=f"file_path '{file_path}' (is absolute|climbs out of its folder)"):
        write(out, file_path)
    assert not (tmp_path / "outside").exists()
    assert write(out, "segment-1/155.jpg") == out / "segment-1" / "155.json"  # an honest one still goes in


def test_a_link_below_the_folder_cannot_lead_out(tmp_path):
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "link").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(UnsafePathError, match="'link/x.json' resolves outside its folder through a link"):
        path_inside(tmp_path / "out", "link/x.json")
    assert path_inside(tmp_path / "out", "a/b.json") == tmp_path / "out" / "a" / "b.json"


@pytest.mark.parametrize("value, problem", [
    ("", "is empty"), ("/etc/x.jpg", "is absolute"), ("a/../../x.jpg", "climbs out of its folder ('..')"),
    ("..\\x.jpg", "climbs out of its folder ('..')"), ("C:\\x.jpg", "is absolute"), ("a/b.jpg", ""),
])  # fmt: skip
def test_path_problem(value, problem):
    assert path_problem(value) == problem
