"""OpenLaneMetric: equal to summarize() of the same frames, and exact under DDP."""

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

from lanelab.metrics.openlane import OpenLaneConfig, evaluate_frame, summarize
from lanelab.metrics.openlane_metric import LaneBatch, OpenLaneMetric


@dataclass
class Frame:
    """One frame as lists: lanes (N_i, 3) in the lane frame, visibility (N_i,), categories."""

    gt_lanes: list[np.ndarray]
    gt_visibility: list[np.ndarray]
    gt_categories: list[int]
    pred_lanes: list[np.ndarray]
    pred_visibility: list[np.ndarray]
    pred_categories: list[int]

    def evaluate(self, config: OpenLaneConfig = OpenLaneConfig()):
        return evaluate_frame(
            self.gt_lanes, self.gt_visibility, self.gt_categories, self.pred_lanes,
            self.pred_categories, config, pred_visibility=self.pred_visibility,
        )


def random_frame(rng: np.random.Generator, lanes: int = 6, y_max: float = 200.0) -> Frame:
    """GT lanes of 10-40 points (some invisible, some occluded stretches), predictions on a
    fixed grid of 30 y values with noisy geometry and visibility, some missing or extra."""
    frame = Frame([], [], [], [], [], [])
    for i in range(lanes):
        x0 = -12.0 + 24.0 * (i + rng.random()) / lanes
        bend = rng.normal(0.0, 3e-4)
        y = np.sort(rng.uniform(0.0, rng.uniform(30.0, y_max), rng.integers(10, 40)))
        vis = (rng.random(len(y)) > 0.1).astype(float)
        if rng.random() < 0.3:  # an occluded stretch
            vis[(y > 20) & (y < 35)] = 0.0
        frame.gt_lanes.append(np.stack([x0 + bend * y**2, y, 0.01 * y], axis=1))
        frame.gt_visibility.append(vis)
        frame.gt_categories.append(int(rng.choice([1, 2, 20, 21])))
        if rng.random() < 0.15:
            continue  # missed lane
        grid = np.linspace(1.0, y_max, 30)
        shift = 3.5 if rng.random() < 0.15 else 0.0
        points = np.stack([x0 + shift + bend * grid**2, grid, 0.01 * grid], axis=1)
        points += rng.normal(0.0, 0.15, points.shape)
        pred_vis = np.clip((grid < y[-1] + rng.normal(0, 5)) + rng.normal(0, 0.3, 30), 0, 1)
        frame.pred_lanes.append(points)
        frame.pred_visibility.append(pred_vis)
        frame.pred_categories.append(frame.gt_categories[-1] if rng.random() < 0.8 else 2)
    return frame


def batches(frames: list[Frame], slots: int = 8) -> tuple[LaneBatch, LaneBatch]:
    """(predictions, ground truth) LaneBatch of frames."""
    preds = LaneBatch.from_lists(
        [f.pred_lanes for f in frames], [f.pred_visibility for f in frames],
        [f.pred_categories for f in frames], slots,
    )
    target = LaneBatch.from_lists(
        [f.gt_lanes for f in frames], [f.gt_visibility for f in frames],
        [f.gt_categories for f in frames], slots,
    )
    return preds, target


CONFIGS = {"official": OpenLaneConfig(), "long_range": OpenLaneConfig.long_range()}


def frames(seed: int, count: int) -> list[Frame]:
    rng = np.random.default_rng(seed)
    return [random_frame(rng) for _ in range(count)]


def metric_over(frames_: list[Frame], config: OpenLaneConfig, batch_size=5) -> OpenLaneMetric:
    metric = OpenLaneMetric(config)
    for start in range(0, len(frames_), batch_size):
        metric.update(*batches(frames_[start : start + batch_size]))
    return metric


def assert_same_numbers(mine: dict, expected: dict) -> None:
    assert set(mine) == set(expected)
    for key, value in expected.items():
        value, got = float(value), float(mine[key])
        if math.isnan(value):
            assert math.isnan(got), key
        elif key.endswith("error") or "_error_" in key or key == "vis_iou":
            # Sums in another order: equal up to rounding.
            assert got == pytest.approx(value, rel=1e-12, abs=1e-15), key
        else:
            assert got == value, key  # counts and the scores made from them: exact


@pytest.mark.parametrize("name", CONFIGS)
def test_metric_equals_summarize_of_the_same_frames(name):
    config = CONFIGS[name]
    data = frames(0, 40)
    expected = summarize(f.evaluate(config) for f in data)
    assert expected["matched"] > 50 and 0 < expected["f1"] < 1
    assert_same_numbers(metric_over(data, config).compute(), expected)


def test_vis_iou_and_long_range_errors_are_reported():
    result = metric_over(frames(1, 10), OpenLaneConfig.long_range()).compute()
    for key in ("x_error_close", "x_error_far", "x_error_100_150", "x_error_150_200",
                "z_error_150_200", "vis_iou"):
        assert key in result
    assert 0 < result["vis_iou"] < 1


def test_nan_padding_and_invalid_slots_are_ignored():
    frame = frames(2, 1)[0]
    preds, target = batches([frame], slots=12)  # extra empty slots, NaN-padded points
    metric = OpenLaneMetric()
    metric.update(preds, target)
    assert_same_numbers(metric.compute(), summarize([frame.evaluate()]))


def straight_frame(pred_offsets: list[float]) -> Frame:
    """GT lanes at x = 0, 4, -4, ...; predictions shifted by the given offsets (metres)."""
    xs = [0.0, 4.0, -4.0, 8.0][: len(pred_offsets)]
    gt = [np.array([[x, 1.0, 0.0], [x, 110.0, 0.0]]) for x in xs]
    pred = [lane + [offset, 0.0, 0.0] for lane, offset in zip(gt, pred_offsets)]
    return Frame(gt, [np.ones(2)] * len(gt), [1] * len(gt), pred, [np.ones(2)] * len(pred),
                 [1] * len(pred))


def test_two_ranks_sum_their_states_instead_of_averaging_means():
    # Rank 0: one pair with |dx| = 1.0; rank 1: three pairs with |dx| = 0. The mean over the
    # four pairs is 0.25 (a mean of per-rank means would say 0.5); all 4 GT lanes are found.
    rank0, rank1 = straight_frame([1.0]), straight_frame([0.0, 0.0, 0.0])
    merged = metric_over([rank0], OpenLaneConfig())
    merged.merge_state(metric_over([rank1], OpenLaneConfig()))
    result = merged.compute()
    assert float(result["x_error_close"]) == pytest.approx(0.25)
    assert float(result["matched"]) == 4 and float(result["recall"]) == 1.0
    assert_same_numbers(result, summarize([rank0.evaluate(), rank1.evaluate()]))


def test_states_of_split_frames_sum_to_the_single_process_numbers():
    data = frames(3, 30)
    single = metric_over(data, OpenLaneConfig.long_range()).compute()
    first = metric_over(data[:11], OpenLaneConfig.long_range())
    first.merge_state(metric_over(data[11:], OpenLaneConfig.long_range()))
    assert_same_numbers(first.compute(), single)


def _rank(rank: int, world_size: int, init_file: str, out_file: str) -> None:
    """One process of the gloo test: half of the frames, then a synced compute()."""
    torch.set_num_threads(1)
    dist.init_process_group("gloo", init_method=f"file://{init_file}", rank=rank,
                            world_size=world_size)
    try:
        data = frames(4, 24)
        metric = metric_over(data[rank::world_size], OpenLaneConfig.long_range())
        result = {key: float(value) for key, value in metric.compute().items()}
        if rank == 0:
            with open(out_file, "w") as f:
                json.dump(result, f)
    finally:
        dist.destroy_process_group()


def test_two_gloo_processes_give_the_single_process_numbers(tmp_path):
    out_file = tmp_path / "result.json"
    # fork: the children inherit the imported modules instead of importing torch again.
    mp.start_processes(_rank, args=(2, str(tmp_path / "init"), str(out_file)), nprocs=2,
                       join=True, start_method="fork")
    expected = summarize(f.evaluate(OpenLaneConfig.long_range()) for f in frames(4, 24))
    assert_same_numbers(json.loads(out_file.read_text()), expected)
