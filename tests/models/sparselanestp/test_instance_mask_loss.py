"""The query generator's auxiliary instance-mask loss (lanelab.models.sparselanestp.instance_mask_loss):
ground-truth lane masks where the camera sees the lanes, matching, and what the loss rewards."""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from lanelab.geometry import project_lane_points
from lanelab.models.sparselanestp.instance_mask_loss import InstanceMaskLoss, lane_masks

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "lightning"))
from tiny_setup import HEIGHT, T_LANE_CAM, WIDTH, K  # noqa: E402

MASK = (HEIGHT // 8, WIDTH // 8)
Y = torch.arange(3.0, 61.0, 3.0, dtype=torch.float64)


def targets(xs: list[float], visible_from: float = 0.0) -> dict[str, torch.Tensor]:
    """One frame of straight lanes at these x (m), visible beyond visible_from (m), plus a padding row."""
    G, S = len(xs) + 1, len(Y)
    x = torch.zeros(1, G, S)
    x[0, : len(xs)] = torch.tensor(xs)[:, None]
    vis = torch.zeros(1, G, S)
    vis[0, : len(xs)] = (Y >= visible_from).float()
    return {"gt_y": Y.float()[None], "gt_x": x, "gt_z": torch.zeros(1, G, S), "gt_vis": vis,
            "gt_mask": torch.arange(G)[None] < len(xs)}  # fmt: skip


def render(t: dict[str, torch.Tensor]) -> torch.Tensor:
    points = torch.stack([t["gt_x"], t["gt_y"][:, None].expand_as(t["gt_x"]), t["gt_z"]], -1)
    camera = torch.tensor(K)[None], torch.tensor(T_LANE_CAM)[None]
    return lane_masks(points, t["gt_vis"] > 0.5, *camera, (HEIGHT, WIDTH), MASK)


def loss_and_camera() -> tuple[InstanceMaskLoss, tuple[torch.Tensor, torch.Tensor]]:
    """LATR's weights; the tiny camera's K and T_lane_cam as float32 batches of one."""
    camera = torch.tensor(K, dtype=torch.float32)[None], torch.tensor(T_LANE_CAM, dtype=torch.float32)[None]
    return InstanceMaskLoss(dice_weight=2.0, bce_weight=5.0), camera


def test_masks_mark_the_cells_the_lanes_are_seen_in():
    masks = render(targets([-1.75, 1.75]))
    assert masks.shape == (1, 3, *MASK) and masks[0, 2].sum() == 0  # the padding row stays empty
    for lane, x in enumerate((-1.75, 1.75)):
        fine = torch.stack([torch.full((1000,), x), torch.linspace(3.0, 60.0, 1000), torch.zeros(1000)], -1)
        uv, _, _ = project_lane_points(fine.double(), torch.tensor(K), torch.tensor(T_LANE_CAM))
        expected = torch.zeros(MASK)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < WIDTH) & (uv[:, 1] < HEIGHT)
        expected[(uv[inside, 1] / 8).long(), (uv[inside, 0] / 8).long()] = 1
        torch.testing.assert_close(masks[0, lane].float(), expected)


def test_hidden_samples_are_not_drawn():
    near = render(targets([1.75]))[0, 0]
    far_only = render(targets([1.75], visible_from=30.0))[0, 0]
    assert far_only.sum() < near.sum() and (far_only <= near).all()


def test_the_loss_matches_masks_to_lanes_and_rewards_the_right_ones():
    t = targets([-1.75, 1.75])
    gt = render(t)[0, :2].float()
    loss, camera = loss_and_camera()
    # Proposals 3 and 1 draw the two lanes (in the other order), 0 and 2 draw nothing.
    perfect = torch.full((1, 4, *MASK), -20.0)
    perfect[0, 3], perfect[0, 1] = 40 * gt[0] - 20, 40 * gt[1] - 20
    good = loss(perfect, t, *camera, (HEIGHT, WIDTH))
    assert good["dice"] < 1e-6 and good["bce"] < 1e-6

    logits = torch.zeros(1, 4, *MASK, requires_grad=True)
    bad = loss(logits, t, *camera, (HEIGHT, WIDTH))
    torch.testing.assert_close(bad["total"], 2.0 * bad["dice"] + 5.0 * bad["bce"])
    bad["total"].backward()
    assert bad["dice"] > 0.5 and (logits.grad.flatten(2).abs().sum(-1) > 0).sum() == 2  # two matched masks


def test_given_matches_pair_masks_as_the_detection_loss_paired_them():
    """With the detection loss's pairs (line 0 <-> lane 1, line 2 <-> lane 0) the masks are
    scored against those lanes, not re-matched by their dice cost; an unmatched line pays nothing."""
    t = targets([-1.75, 1.75])
    gt = render(t)[0, :2].float()
    loss, camera = loss_and_camera()
    drawn = torch.full((1, 3, *MASK), -20.0)
    drawn[0, 0], drawn[0, 2] = 40 * gt[1] - 20, 40 * gt[0] - 20
    matches = [(torch.tensor([0, 2]), torch.tensor([1, 0]))]
    assert loss(drawn, t, *camera, (HEIGHT, WIDTH), matches)["dice"] < 1e-6
    swapped = [(torch.tensor([0, 2]), torch.tensor([0, 1]))]
    assert loss(drawn, t, *camera, (HEIGHT, WIDTH), swapped)["dice"] > 0.9  # the dice cost alone would swap back
    assert loss(drawn, t, *camera, (HEIGHT, WIDTH))["dice"] < 1e-6
    logits = torch.zeros(1, 3, *MASK, requires_grad=True)
    loss(logits, t, *camera, (HEIGHT, WIDTH), [(torch.tensor([1]), torch.tensor([0]))])["total"].backward()
    assert (logits.grad.flatten(2).abs().sum(-1)[0] > 0).tolist() == [False, True, False]
