"""The test that would have caught "the detectors do not learn": small models trained for a
bounded number of steps on a few synthetic drives must beat the blind prior (the training
drives' mean lane layout, straight and flat, no image) by a wide margin on other drives.

Known to fail today (issue "The detectors must learn" is open: at this budget, at stop 30,
SparseLaneSTP scores 58.0 % against the prior's 62.0 % and the baseline 64.7 %, not both 5
points above as asked).
The mark is strict: once the models learn, the test passes, pytest reports the unexpected pass
as a failure, and the mark must go.
"""

import json
from pathlib import Path

import pytest

from lanelab.demo import main

MARGIN = 0.05  # F1 points (as a fraction) above the prior that count as learning
SMALL = [
    "demo.synth=['camera.width=128','camera.height=96','fps=5','workers=2']",
    "demo.train_logs=['num_logs=20','duration_s=2','seed=1']",  # many short drives, as the demo's
    "demo.test_logs.fog=['num_logs=1','duration_s=4','seed=101','world.weather=fog']",
    "demo.test_logs.traffic=['num_logs=1','duration_s=4','seed=102']",
    "demo.ingest_train=['split.by=clip','split.train=0.8','split.val=0.2','split.test=0.0','clips.max_length_s=4']",
    "trainer.max_steps=400", "trainer.max_time=null", "evaluation.num_pictures=0",
]  # fmt: skip


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError, reason='issue "The detectors must learn": the models do not beat the blind prior by the margin yet')
def test_small_models_beat_the_blind_prior_on_drives_they_never_saw(tmp_path: Path) -> None:
    main([f"demo.out={tmp_path}", *SMALL])
    scores = {}
    for model in ("sparselanestp", "latr_baseline"):
        report = json.loads((tmp_path / model / "heldout" / "report.json").read_text())
        scores[model] = report["overall"]["f1"], report["blind_prior"]["overall"]["f1"]
    assert all(f1 > prior + MARGIN for f1, prior in scores.values()), f"held-out F1, prior: {scores}"
