"""Does a trained detector read a bend from the image, or predict the bends it was trained on?

    python benchmarks/bend_probe.py CHECKPOINT STORE [--split test] [--every 2]

For every ``--every``-th frame of the store's split, the bend of a frame's lanes is the mean
second difference b = x(60 m) - 2 x(35 m) + x(10 m) over its lanes seen at all three distances
that start within 8 m of the ego (x(10 m)); metres, negative to the left. The detector runs on
each frame twice, single-frame (memory reset): on the image as it is, and on its mirror image
(image, intrinsics, poses mirrored as ``lanelab.data.mirror`` does for training), its lanes
mirrored back. Printed per variant: the slope and correlation of the predicted against the true
bend, and the mean predicted bend. A detector that reads the bend scores a slope near 1 both
ways; one that predicts a bend it learnt as a prior scores near 0, and its mean bend changes
sign under the mirror.
"""

from __future__ import annotations

import numpy as np
import torch

from lanelab.data.mirror import mirror_intrinsics, mirror_transforms
from lanelab.data.targets import LaneTargets
from lanelab.deploy.trained import TrainedDetector, load_trained
from lanelab.lightning.predictions import predicted_lanes
from lanelab.store import FrameRecord
from probe import probe_parser, probed_frames

BEND_AT_M = (10.0, 35.0, 60.0)
NEAR_EGO_M = 8.0


def bend(x: np.ndarray, visible: np.ndarray, y: np.ndarray) -> float:
    """Mean bend (m) of lanes x (L, S) at y (S,) visible (L, S) at BEND_AT_M and starting within
    NEAR_EGO_M of the ego; NaN when no lane qualifies."""
    at = [int(np.argmin(np.abs(y - distance))) for distance in BEND_AT_M]
    near, middle, far = x[:, at].T
    kept = visible[:, at].all(axis=1) & (np.abs(near) < NEAR_EGO_M)
    return float(np.mean((far - 2 * middle + near)[kept])) if kept.any() else float("nan")


def predicted_bend(detector: TrainedDetector, record: FrameRecord, mirrored: bool) -> float:
    """The bend of the detector's lanes on one frame, run on its mirror image if ``mirrored``
    (and its lanes mirrored back)."""
    frame = detector.model_input(record)
    if mirrored:
        width = frame["images"].shape[-1]
        frame["images"] = frame["images"].flip(-1)
        frame["K"] = torch.from_numpy(mirror_intrinsics(frame["K"].cpu().numpy(), width)).to(frame["K"])
        for key in ("T_lane_cam", "T_world_lane"):
            frame[key] = torch.from_numpy(mirror_transforms(frame[key].cpu().numpy())).to(frame[key])
    frame["reset"] = torch.ones(1, dtype=torch.bool, device=detector.device)
    with torch.no_grad():
        outputs = detector.net.step(frame)
    threshold = detector.module.metric_config.visibility_threshold
    lanes = predicted_lanes(detector.net, outputs, detector.y, threshold, None)
    x = lanes.points[0, ..., 0].float().cpu().numpy()
    visible = (lanes.visibility[0].float().cpu().numpy() > threshold) & lanes.valid[0].cpu().numpy()[:, None]
    return bend(-x if mirrored else x, visible, detector.y.cpu().numpy())


def main() -> None:
    args = probe_parser(__doc__).parse_args()
    detector = load_trained(args.checkpoint)
    y = detector.y.cpu().numpy()
    targets = LaneTargets(y)
    rows = []
    for record in probed_frames(args):
        truth = targets(record.lanes)
        rows.append((bend(truth["gt_x"], truth["gt_vis"] > 0, y),
                     predicted_bend(detector, record, False), predicted_bend(detector, record, True)))
    bends = np.array(rows)
    bends = bends[np.isfinite(bends).all(axis=1)]
    print(f"{args.checkpoint}: {len(bends)} frames of {args.store} ({args.split}) with a bend to compare; "
          f"true mean bend {bends[:, 0].mean():+.2f} m")
    print("| image | slope on the true bend | correlation | mean predicted bend (m) |\n|---|---:|---:|---:|")
    for name, column in (("as it is", 1), ("mirrored, lanes mirrored back", 2)):
        slope = np.polyfit(bends[:, 0], bends[:, column], 1)[0]
        correlation = np.corrcoef(bends[:, 0], bends[:, column])[0, 1]
        print(f"| {name} | {slope:.2f} | {correlation:.2f} | {bends[:, column].mean():+.2f} |")


if __name__ == "__main__":
    main()
