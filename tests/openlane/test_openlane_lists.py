"""OpenLane's test lists, and its scenario lists whatever their file names and leading folders."""

import pytest

from lanelab.json_files import LaneFileError
from lanelab.metrics.scenarios import scenarios_of
from lanelab.openlane.lists import case_name, frame_key, read_scenario_lists, read_test_list, write_test_list


@pytest.mark.parametrize("name", ["1000_curve.txt", "curve.txt", "curve_case.txt", "lists/300_curve_case.txt"])
def test_list_files_are_named_by_their_case(name):
    assert case_name(name) == "curve"


def test_frame_key_ignores_leading_folders_and_extensions():
    keys = {frame_key(p) for p in ["validation/segment-1/15.jpg", "test/curve_case/segment-1/15.json",
                                   "segment-1/15.jpg", "/validation/segment-1/15.json"]}
    assert keys == {"segment-1/15"}


def test_lists_are_read_in_table_order_and_match_test_list_ids(tmp_path):
    (tmp_path / "my_list.txt").write_text("validation/segment-2/7.jpg\n")
    (tmp_path / "1000_night.txt").write_text("test/night_case/segment-1/5.jpg\n\n")
    (tmp_path / "1000_up_down.txt").write_text("validation/segment-1/5.jpg\nvalidation/segment-2/7.jpg\n")
    (tmp_path / "notes.md").write_text("not a list")
    lists = read_scenario_lists(tmp_path)
    assert list(lists) == ["up_down", "night", "my_list"]

    ids = ["validation/segment-1/5.json", "validation/segment-2/7.json", "validation/segment-3/9.json"]
    scenarios = scenarios_of(lists, ids)
    assert [(s.group, s.name) for s in scenarios] == [("OpenLane", "Up & Down"), ("OpenLane", "Night"),
                                                      ("OpenLane", "my_list")]
    assert [sorted(s.frames) for s in scenarios] == [ids[:2], ids[:1], ids[1:2]]


def test_a_folder_without_lists_is_named(tmp_path):
    with pytest.raises(LaneFileError, match=f"{tmp_path}: no scenario lists"):
        read_scenario_lists(tmp_path)


def test_a_written_test_list_reads_back_as_json_paths(tmp_path):
    write_test_list(tmp_path / "test_list.txt", ["clip/1.jpg", "clip/2.jpg"])
    assert (tmp_path / "test_list.txt").read_text() == "clip/1.jpg\nclip/2.jpg\n"
    assert read_test_list(tmp_path / "test_list.txt") == ["clip/1.json", "clip/2.json"]
