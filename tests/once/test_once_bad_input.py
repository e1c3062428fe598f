"""Bad ONCE-3DLanes input fails its sequence with one line naming the file; the others go on."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from once_helpers import adapter_config, write_tiny_once

from data_ingest.once.adapter import adapt

LABEL = "val/000076/cam01/1616100800900.json"


def label_content(tiny, change) -> str:
    content = json.loads(json.dumps(tiny.labels[LABEL]))
    change(content)
    return json.dumps(content)


def _nan_point(content: dict) -> None:
    content["lanes"][0][2][0] = float("nan")


def _behind(content: dict) -> None:
    content["lanes"][1][0][2] = -2.0


CASES = {
    "malformed JSON": (lambda tiny: "{\"lanes\": [", "not valid JSON"),
    "no calibration": (lambda tiny: label_content(tiny, lambda c: c.pop("calibration")), "missing key 'calibration'"),
    "calibration 3x3": (lambda tiny: label_content(tiny, lambda c: c.update(calibration=[r[:3] for r in c["calibration"]])),
                        "'calibration' must have shape (3, 4), got (3, 3)"),
    "NaN point": (lambda tiny: label_content(tiny, _nan_point), "holds NaN or inf"),
    "points behind the camera": (lambda tiny: label_content(tiny, _behind), "points behind the camera"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_bad_label_fails_its_sequence_naming_the_file(case: str, tmp_path: Path) -> None:
    tiny = write_tiny_once(tmp_path)
    content, message = CASES[case]
    (tiny.root / LABEL).write_text(content(tiny))
    results = {r.sequence: r for r in adapt(adapter_config(tiny, tmp_path / "store"))}
    assert [results[s].status for s in ("000027", "000112")] == ["written", "written"]
    error = results["000076"].error
    assert results["000076"].status == "failed" and "\n" not in error
    assert error.startswith(f"{tiny.root / LABEL}: ") and message in error, error


def test_a_missing_image_names_it(tmp_path: Path) -> None:
    tiny = write_tiny_once(tmp_path)
    image = tiny.root / LABEL.replace(".json", ".jpg")
    image.unlink()
    (result,) = [r for r in adapt(adapter_config(tiny, tmp_path / "store")) if r.sequence == "000076"]
    assert result.status == "failed" and result.error.startswith(f"{image}: no such image")


def test_a_sequence_of_one_frame_is_refused(tmp_path: Path) -> None:
    tiny = write_tiny_once(tmp_path)
    for path in sorted((tiny.root / "test/000112/cam01").glob("*.json"))[1:]:
        path.unlink()
    (result,) = [r for r in adapt(adapter_config(tiny, tmp_path / "store")) if r.sequence == "000112"]
    assert result.status == "failed" and "the only frame of its sequence" in result.error


def test_a_bad_pose_file_names_it(tmp_path: Path) -> None:
    tiny = write_tiny_once(tmp_path)
    pose_file = tiny.poses / "000076" / "000076.json"
    pose_file.write_text(json.dumps({"calib": {"cam01": {"cam_to_velo": [[1, 0, 0]]}}, "frames": []}))
    (result,) = [r for r in adapt(adapter_config(tiny, tmp_path / "store")) if r.sequence == "000076"]
    assert result.status == "failed" and result.error.startswith(f"{pose_file}: 'calib.cam01.cam_to_velo' must have shape")
