import math

import pytest
import torch
from loss_setup import build_matcher

from lanelab.geometry import control_point_y, evaluate
from lanelab.lanes import LANE_CATEGORY_IDS
from lanelab.models.categories import BACKGROUND_INDEX, category_to_index

M, Y_RANGE = 6, (3.0, 53.0)
GT_Y = torch.linspace(3.0, 53.0, 11)


def control_points(x0: torch.Tensor) -> torch.Tensor:
    """(..., M, 4) gently curving visible lanes starting at x0 (...)."""
    y = control_point_y(M, *Y_RANGE)
    x = x0[..., None] + 2e-3 * (y - 3.0) ** 2
    return torch.stack([x, y.expand_as(x), 0.02 * y.expand_as(x), torch.ones_like(x)], -1)


def targets_from(points: torch.Tensor, mask: torch.Tensor, categories: torch.Tensor) -> dict:
    """The dataset batch of lanes whose curves are exactly those of points (B, G, M, 4)."""
    s = (GT_Y - Y_RANGE[0]) / (Y_RANGE[1] - Y_RANGE[0])
    curves = evaluate(points, s)
    visible = torch.ones_like(curves[..., 0]) * mask[..., None]
    return {"gt_y": GT_Y, "gt_x": curves[..., 0], "gt_z": curves[..., 2], "gt_vis": visible,
            "gt_category": categories, "gt_mask": mask}  # fmt: skip


def perfect_prediction(gt_points, gt_mask, categories, order, N: int) -> tuple[torch.Tensor, torch.Tensor]:
    """N proposals: ground-truth lane g at proposal order[g], confident in its category; the
    others far away and confidently background."""
    B, G = gt_mask.shape
    points = control_points(torch.full((B, N), 40.0))
    logits = torch.full((B, N, BACKGROUND_INDEX + 1), -10.0)
    logits[..., BACKGROUND_INDEX] = 10.0
    for g in range(G):
        points[:, order[g]] = torch.where(gt_mask[:, g, None, None], gt_points[:, g], points[:, order[g]])
        logits[:, order[g]] = torch.where(gt_mask[:, g, None], -10.0, logits[:, order[g]])
        index = category_to_index(categories[:, g])
        rows = torch.arange(B)
        logits[rows, order[g], index] = torch.where(gt_mask[:, g], 10.0, logits[rows, order[g], index])
    return logits, points


def test_a_perfect_prediction_matches_each_lane_to_its_proposal():
    G, N = 4, 7
    gt_points = control_points(torch.tensor([[-5.0, -1.5, 2.0, 5.5], [-3.0, 0.5, 0.0, 0.0]]))
    gt_mask = torch.tensor([[True, True, True, True], [True, True, False, False]])  # padded lanes
    categories = torch.tensor([[1, 2, 20, 21], [7, 8, 0, 0]])
    targets = targets_from(gt_points, gt_mask, categories)
    s = (GT_Y - Y_RANGE[0]) / (Y_RANGE[1] - Y_RANGE[0])
    matcher = build_matcher(cost_class=1.0, cost_reg=1.0, cost_vis=1.0)

    identity = torch.arange(G)
    logits, points = perfect_prediction(gt_points, gt_mask, categories, identity, N)
    matches = matcher(logits, evaluate(points, s), targets)
    assert [(p.tolist(), g.tolist()) for p, g in matches] == [([0, 1, 2, 3], [0, 1, 2, 3]), ([0, 1], [0, 1])]

    order = torch.tensor([5, 0, 3, 6])  # lane g sits at proposal order[g]
    logits, points = perfect_prediction(gt_points, gt_mask, categories, order, N)
    for b, (pred, gt) in enumerate(matches := matcher(logits, evaluate(points, s), targets)):
        assert torch.equal(order[gt], pred)
        assert gt_mask[b, gt].all()  # padded lanes are never matched
    assert [len(pred) for pred, _ in matches] == [4, 2]


def test_pair_costs_by_hand():
    """One proposal, one lane of three samples, two of them visible."""
    targets = {
        "gt_x": torch.tensor([[[1.0, 2.0, 3.0]]]), "gt_z": torch.tensor([[[0.0, 0.0, 0.0]]]),
        "gt_vis": torch.tensor([[[1.0, 1.0, 0.0]]]), "gt_category": torch.tensor([[LANE_CATEGORY_IDS[2]]]),
        "gt_mask": torch.tensor([[True]]),
    }  # fmt: skip
    curves = torch.tensor([[[[1.5, 0.0, 0.0, 0.8], [2.0, 0.0, 1.0, 0.6], [9.0, 0.0, 9.0, 0.1]]]])  # (1, 1, 3, 4)
    logits = torch.log(torch.tensor([[[0.1, 0.2, 0.5] + [0.2 / 13] * 13]]))  # p(category index 2) = 0.5
    cost = build_matcher(cost_class=2.0, cost_reg=3.0, cost_vis=5.0, gamma=2.0).cost_matrix(logits, curves, targets)
    focal = -(0.5**2) * math.log(0.5)
    reg = (0.5 + (0.0 + 1.0)) / 2  # mean over the two visible samples; the invisible one is ignored
    vis = (0.2 + 0.4 + 0.1) / 3
    assert cost.shape == (1, 1, 1)
    assert math.isclose(cost.item(), 2 * focal + 3 * reg + 5 * vis, rel_tol=1e-5)


def test_matching_on_anchors_pairs_lanes_with_the_nearest_anchors_whatever_the_lines_predict():
    """Lanes at x = -1.9, 1.6, 5.0 m near the car, the first bending away to -12 m beyond 30 m;
    anchors every 3.5 m from -5.25. The lanes go to anchors 1, 2, 3, the nearest at near range
    (over all samples the first lane would be nearer anchor 0), whatever the lines predict."""
    S = 20
    y = torch.linspace(3, 103, S)
    x = torch.tensor([-1.9, 1.6, 5.0])[:, None].expand(3, S).clone()
    x[0, y > 30] = -12.0
    targets = {
        "gt_y": y, "gt_x": x[None], "gt_z": torch.zeros(1, 3, S), "gt_vis": torch.ones(1, 3, S),
        "gt_category": torch.full((1, 3), 2), "gt_mask": torch.ones(1, 3, dtype=torch.bool),
    }  # fmt: skip
    anchors = torch.tensor([-5.25, -1.75, 1.75, 5.25])
    logits = torch.zeros(1, 4, BACKGROUND_INDEX + 1)
    curves = torch.zeros(1, 4, S, 4)
    matcher = build_matcher(match_on="anchors", near_range=30.0)
    ((pred, gt),) = matcher(logits, curves, targets, anchors)
    assert dict(zip(gt.tolist(), pred.tolist())) == {0: 1, 1: 2, 2: 3}
    cost = matcher.anchor_cost(anchors, targets)
    torch.testing.assert_close(cost[0, 1, 0], torch.tensor(abs(-1.9 + 1.75)))  # near samples only
    assert build_matcher(match_on="anchors", near_range=200.0).anchor_cost(anchors, targets)[0, :, 0].argmin() == 0
    with pytest.raises(ValueError, match="anchor_span"):
        matcher(logits, curves, targets, None)
    with pytest.raises(ValueError, match="match_on"):
        build_matcher(match_on="nearest")


def test_3d_anchors_are_matched_by_their_euclidean_distance_in_x_and_z():
    """Bi²Lane's anchors: (x, z) at every ground-truth sample. A lane climbing 5 % goes to the
    anchor pitched like it, not to the flat one at the same x; the cost is Anchor3DLane's mean
    sqrt(dx² + dz²) over the visible samples."""
    S = 10
    y = torch.linspace(5, 50, S)
    targets = {
        "gt_y": y, "gt_x": torch.full((1, 1, S), 1.0), "gt_z": (0.05 * y)[None, None], "gt_vis": torch.ones(1, 1, S),
        "gt_category": torch.full((1, 1), 2), "gt_mask": torch.ones(1, 1, dtype=torch.bool),
    }  # fmt: skip
    flat = torch.stack([torch.full((S,), 1.0), torch.zeros(S)], -1)
    pitched = torch.stack([torch.full((S,), 1.3), 0.05 * y], -1)
    anchors = torch.stack([flat, pitched])[None]  # (B, N, S, 2)
    matcher = build_matcher(match_on="anchors", near_range=200.0)
    ((pred, gt),) = matcher(torch.zeros(1, 2, BACKGROUND_INDEX + 1), torch.zeros(1, 2, S, 4), targets, anchors)
    assert pred.tolist() == [1] and gt.tolist() == [0]
    cost = matcher.anchor_cost(anchors, targets)[0, :, 0]
    torch.testing.assert_close(cost, torch.stack([(0.05 * y).mean(), torch.tensor(0.3)]))


def test_a_lane_far_from_every_free_anchor_is_no_lines_target():
    """Anchors at -1.75 and 1.75 m; lanes at -1.5, 2.1 and 7.0 m. Without a threshold the third
    lane takes the only line left however far it is (every lane is matched when G <= N); with
    max_anchor_distance = 2 m it is dropped, the line stays background, and the near lanes keep
    their anchors."""
    S = 10
    y = torch.linspace(3, 48, S)
    x = torch.tensor([-1.5, 2.1, 7.0])[:, None].expand(3, S)
    targets = {
        "gt_y": y, "gt_x": x[None], "gt_z": torch.zeros(1, 3, S), "gt_vis": torch.ones(1, 3, S),
        "gt_category": torch.full((1, 3), 2), "gt_mask": torch.ones(1, 3, dtype=torch.bool),
    }  # fmt: skip
    anchors = torch.tensor([-1.75, 1.75, 12.0])
    logits, curves = torch.zeros(1, 3, BACKGROUND_INDEX + 1), torch.zeros(1, 3, S, 4)
    ((pred, gt),) = build_matcher(match_on="anchors")(logits, curves, targets, anchors)
    assert dict(zip(gt.tolist(), pred.tolist())) == {0: 0, 1: 1, 2: 2}  # 5 m from its line
    ((pred, gt),) = build_matcher(match_on="anchors", max_anchor_distance=2.0)(logits, curves, targets, anchors)
    assert dict(zip(gt.tolist(), pred.tolist())) == {0: 0, 1: 1}
    with pytest.raises(ValueError, match="max_anchor_distance"):  # it would be silently ignored
        build_matcher(match_on="predictions", max_anchor_distance=2.0)


def test_one_to_many_gives_a_lane_every_anchor_near_it_and_a_lone_lane_its_nearest_free_one():
    """Anchor3DLane's assignment (positive_distance = 1 m), anchors at -3, -1, 1, 3 m: the lane at
    -1.2 m takes the anchor at -1; the lane at 2 m both anchors 1 m away; the lane at -4.5 m has
    none within 1 m and takes the nearest free one within max_anchor_distance (-3); the lane at
    8 m is 5 m from every anchor and stays unassigned."""
    S = 10
    y = torch.linspace(3, 30, S)
    x = torch.tensor([-1.2, 2.0, -4.5, 8.0])[:, None].expand(4, S)
    targets = {
        "gt_y": y, "gt_x": x[None], "gt_z": torch.zeros(1, 4, S), "gt_vis": torch.ones(1, 4, S),
        "gt_category": torch.full((1, 4), 2), "gt_mask": torch.ones(1, 4, dtype=torch.bool),
    }  # fmt: skip
    anchors = torch.tensor([-3.0, -1.0, 1.0, 3.0])
    logits, curves = torch.zeros(1, 4, BACKGROUND_INDEX + 1), torch.zeros(1, 4, S, 4)
    matcher = build_matcher(match_on="anchors", max_anchor_distance=2.0, positive_distance=1.0)
    ((pred, gt),) = matcher(logits, curves, targets, anchors)
    pairs = sorted(zip(pred.tolist(), gt.tolist()))
    assert pairs == [(0, 2), (1, 0), (2, 1), (3, 1)]


def test_one_to_many_never_gives_a_line_two_lanes_when_lanes_outnumber_lines():
    """Two anchors, four lanes, no max_anchor_distance: the two lines take one lane each and the
    other lanes stay unassigned (no line is handed out twice)."""
    S = 5
    y = torch.linspace(3, 30, S)
    x = torch.tensor([-1.0, 1.0, 6.0, 9.0])[:, None].expand(4, S)
    targets = {
        "gt_y": y, "gt_x": x[None], "gt_z": torch.zeros(1, 4, S), "gt_vis": torch.ones(1, 4, S),
        "gt_category": torch.full((1, 4), 2), "gt_mask": torch.ones(1, 4, dtype=torch.bool),
    }  # fmt: skip
    logits, curves = torch.zeros(1, 2, BACKGROUND_INDEX + 1), torch.zeros(1, 2, S, 4)
    ((pred, gt),) = build_matcher(match_on="anchors", positive_distance=0.5)(
        logits, curves, targets, torch.tensor([-1.0, 1.0])
    )
    assert sorted(zip(pred.tolist(), gt.tolist())) == [(0, 0), (1, 1)]
