"""Issue 37, case 4: a calibration whose K is not a pinhole matrix (a zero K[2][2], a
lower-triangular entry, a focal length of 0) never makes a frame; the reason says what is wrong."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ingest_helpers import ingest_into, read_log, write_log

CALIBRATION = "/camera/front/camera_info"
REASON = f"calibration K on {CALIBRATION} is not a pinhole matrix: "


def with_K(log: Path, out: Path, spoil, which) -> Path:
    """The log with ``spoil(K)`` applied to the K (3, 3 nested lists) of the calibration messages ``which(k)``."""
    messages, k = [], 0
    for m in read_log(log):
        if m.topic == CALIBRATION:
            if which(k):
                calibration = json.loads(m.data)
                K = [calibration["K"][i:i + 3] for i in (0, 3, 6)]
                spoil(K)
                calibration["K"] = [v for row in K for v in row]
                m = dataclasses.replace(m, data=json.dumps(calibration).encode())
            k += 1
        messages.append(m)
    return write_log(out, messages)


def test_a_singular_K_refuses_the_log_naming_the_problem(tmp_path, synth_log):
    log = with_K(synth_log("foxglove-json"), tmp_path / "singular.mcap", lambda K: K[2].__setitem__(2, 0.0),
                 lambda k: True)
    (result,) = ingest_into(tmp_path / "store", log)
    assert result.status == "failed"
    assert result.error == f"{log}: no usable frame (20 x {REASON}last row is [0.0, 0.0, 0.0], not [0, 0, 1])"


def test_frames_of_a_K_that_is_not_upper_triangular_are_dropped(tmp_path, synth_log):
    log = with_K(synth_log("foxglove-json"), tmp_path / "skewed.mcap", lambda K: K[1].__setitem__(0, 3.0),
                 lambda k: k in (4, 5, 6))
    (result,) = ingest_into(tmp_path / "store", log)
    assert result.status == "ingested" and result.num_frames == 17
    assert result.dropped == {f"{REASON}K[1][0]=3, not 0 (not upper-triangular)": 3}
