"""evaluate() on the official OpenLane repository's own example (data/openlane_example, see
data/README.md): the numbers its evaluator prints for it, to the last digit."""

from pathlib import Path

from lanelab.metrics.openlane import evaluate

EXAMPLE = Path(__file__).parent / "data" / "openlane_example"

# eval_3D_lane.py on eval/LANE_evaluation/lane3d/example (eval_demo.sh).
OFFICIAL = {
    "f1": 0.7875,
    "recall": 0.7,
    "precision": 0.9,
    "category_accuracy": 0.8,
    "x_error_close": 0.12335687109684694,
    "x_error_far": 0.27181566681800984,
    "z_error_close": 0.07864679302064796,
    "z_error_far": 0.09742020346080087,
}


def test_the_official_example_gives_the_official_numbers() -> None:
    result = evaluate(EXAMPLE / "annotations", EXAMPLE / "results", EXAMPLE / "test_list.txt")
    assert {key: result[key] for key in OFFICIAL} == OFFICIAL
    # 5 lanes a frame on both sides, all matched; 7 GT lanes recalled, 9 predictions precise.
    counts = ("gt_lanes", "pred_lanes", "matched", "recall_tp", "precision_tp", "category_correct")
    assert [result[key] for key in counts] == [10, 10, 10, 7, 9, 8]
