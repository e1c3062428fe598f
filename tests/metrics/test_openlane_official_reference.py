"""evaluate() against numbers of the official OpenLane evaluator (see data/README.md)."""

import json
from pathlib import Path

import pytest

from lanelab.metrics.openlane import evaluate

BUNDLE = Path(__file__).parent / "data" / "official_reference_frames.json"


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    bundle = json.loads(BUNDLE.read_text())
    root = tmp_path_factory.mktemp("openlane")
    for rel, frame in zip(bundle["test_list"], bundle["frames"]):
        for side in ("gt", "pred"):
            path = root / side / rel.replace("jpg", "json")
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(frame[side]))
    (root / "test_list.txt").write_text("\n".join(bundle["test_list"]) + "\n")
    return evaluate(root / "gt", root / "pred", root / "test_list.txt"), bundle["official"]


def test_counts_match_the_official_evaluator(result):
    mine, official = result
    for key in ("gt_lanes", "pred_lanes", "matched", "recall_tp", "precision_tp", "category_correct"):
        assert mine[key] == official[key], key


def test_metrics_match_the_official_evaluator(result):
    # Equal to the last bit here; the tolerance only absorbs other BLAS builds' rounding.
    mine, official = result
    for key in ("f1", "recall", "precision", "category_accuracy",
                "x_error_close", "x_error_far", "z_error_close", "z_error_far"):
        assert mine[key] == pytest.approx(official[key], rel=0, abs=1e-12), key
