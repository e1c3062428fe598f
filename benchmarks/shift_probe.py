"""Does a trained detector read where a lane lies across the road, or place it where lanes usually are?

    python benchmarks/shift_probe.py CHECKPOINT STORE [--split test] [--every 2] [--shifts -1 -0.5 0.5 1]

For every ``--every``-th frame of the store's split the detector runs single-frame (memory reset)
on the image as it is and on the image seen by an ego moved sideways by d metres
(``lanelab.data.lateral_shift``: exact for the road surface, so every marking moves by -d). For
each ground-truth lane visible at 15 m within 8 m of the ego, the predicted lane nearest to it
there (within 1 m) is followed into the shifted run (the prediction nearest to where it should
have moved). Its response is how far it moved over how far the lane moved, (x_d - x_0) / -d:
1 for a detector that reads the position, 0 for one that predicts positions as a prior (a lane
that lost its prediction counts as 0 too). Printed per d: the mean response of the ego's own lane
lines (|x| < 2.5 m) and of the outer lines, and the near-range error of the followed lanes after
the shift.
"""

from __future__ import annotations

import numpy as np
import torch

from lanelab.data.lateral_shift import shift_images, shift_targets
from lanelab.data.targets import LaneTargets
from lanelab.deploy.trained import TrainedDetector, load_trained
from probe import probe_parser, probed_frames

AT_M = 15.0
NEAR_EGO_M = 8.0
EGO_LINES_M = 2.5
FOLLOW_M = 1.0


def lanes_at(detector: TrainedDetector, frame: dict[str, torch.Tensor], shift: float, at: int) -> np.ndarray:
    """x (L,) at the grid index ``at`` of the detector's lanes visible there, on the frame (its
    ``model_input``) seen by an ego moved ``shift`` metres to the right."""
    frame = dict(frame)
    if shift:
        K, T_lane_cam = (frame[key].cpu().double().numpy() for key in ("K", "T_lane_cam"))
        images = frame["images"].permute(0, 2, 3, 1).cpu().numpy()  # normalised: 0 is the mean colour
        moved = shift_images(images, K, T_lane_cam, shift, border=(0.0, 0.0, 0.0))
        frame["images"] = torch.from_numpy(moved).permute(0, 3, 1, 2).to(frame["images"])
    frame["reset"] = torch.ones(1, dtype=torch.bool, device=detector.device)
    with torch.no_grad():
        lanes = detector.module.predictions(detector.net.step(frame), detector.y)
    threshold = detector.module.metric_config.visibility_threshold
    visible = (lanes.visibility[0, :, at].float() > threshold) & lanes.valid[0]
    return lanes.points[0, visible, at, 0].float().cpu().numpy()


def nearest(candidates: np.ndarray, x: float) -> float:
    return float(candidates[np.argmin(np.abs(candidates - x))]) if len(candidates) else float("nan")


def main() -> None:
    parser = probe_parser(__doc__)
    parser.add_argument("--shifts", type=float, nargs="+", default=[-1.0, -0.5, 0.5, 1.0], help="metres, right")
    args = parser.parse_args()
    detector = load_trained(args.checkpoint)
    y = detector.y.cpu().numpy()
    at = int(np.argmin(np.abs(y - AT_M)))
    targets = LaneTargets(y)
    rows = []  # (shift, ego line?, response, error after the shift)
    for record in probed_frames(args):
        truth = targets(record.lanes)
        kept = (truth["gt_vis"][:, at] > 0) & (np.abs(truth["gt_x"][:, at]) < NEAR_EGO_M)
        frame = detector.model_input(record)
        K, image_size = frame["K"][0].cpu().double().numpy(), tuple(frame["images"].shape[-2:])
        plain = lanes_at(detector, frame, 0.0, at)
        for shift in args.shifts:
            moved = lanes_at(detector, frame, shift, at)
            # lanes that stay in view: the others cannot be followed
            still = shift_targets(truth, y, K, record.T_lane_cam, image_size, shift)["gt_track_id"]
            for x, track in zip(truth["gt_x"][kept, at], truth["gt_track_id"][kept]):
                start = nearest(plain, x)
                if not abs(start - x) < FOLLOW_M or track not in still:
                    continue
                end = nearest(moved, start - shift)
                response = (end - start) / -shift if abs(end - (start - shift)) < 2 * abs(shift) else 0.0
                rows.append((shift, abs(x) < EGO_LINES_M, response, abs(end - (x - shift))))
    rows = np.array(rows, dtype=float)
    print(f"{args.checkpoint} on {args.store} ({args.split}), every {args.every}th frame, lanes at {y[at]:.1f} m")
    print("| shift d (m) | lanes | response, ego lines | response, outer lines | median error after the shift (m) |")
    print("|---:|---:|---:|---:|---:|")
    for shift in args.shifts:
        mine = rows[rows[:, 0] == shift]
        ego, outer = mine[mine[:, 1] == 1], mine[mine[:, 1] == 0]
        print(f"| {shift:+.1f} | {len(mine)} | {ego[:, 2].mean():.2f} | {outer[:, 2].mean():.2f} | "
              f"{np.nanmedian(mine[:, 3]):.2f} |")


if __name__ == "__main__":
    main()
