import math

import pytest
import torch
from loss_setup import LOSS, build_matcher

from lanelab.geometry import control_point_y, evaluate
from lanelab.models.categories import BACKGROUND_INDEX, category_to_index
from lanelab.models.parts import focal_loss
from lanelab.models.sparselanestp import TERMS, SparseLaneSTPLoss
from lanelab.models.sparselanestp.memory_queue import MemoryState
from lanelab.models.sparselanestp.priors import (
    curvature_excess,
    orthogonal_correspondence,
    parallelism_and_surface,
    temporal_consistency,
)

M, Y_RANGE = 6, (3.0, 53.0)
GT_Y = torch.linspace(3.0, 53.0, 11)
ALL_TERMS = {term: 1.0 for term in TERMS}


def lanes(x0: torch.Tensor, bend: float = 2e-3, shift: float = 0.0) -> torch.Tensor:
    """(..., M, 4) visible lanes x = x0 + bend (y - 3)^2 at the control points' y, moved ``shift``
    metres to the right."""
    y = control_point_y(M, *Y_RANGE, dtype=x0.dtype)
    x = x0[..., None] + bend * (y - 3.0) ** 2 + shift
    return torch.stack([x, y.expand_as(x), 0.02 * y.expand_as(x), torch.ones_like(x)], -1)


def batch() -> tuple[dict, torch.Tensor, torch.Tensor]:
    """Targets of 2 images (4 and 2 real lanes), their lanes' control points and category indices."""
    gt_points = lanes(torch.tensor([[-5.0, -1.5, 2.0, 5.5], [-3.0, 0.5, 0.0, 0.0]]))
    gt_mask = torch.tensor([[True, True, True, True], [True, True, False, False]])
    categories = torch.tensor([[1, 2, 20, 21], [7, 8, 0, 0]])
    curves = evaluate(gt_points, (GT_Y - Y_RANGE[0]) / (Y_RANGE[1] - Y_RANGE[0]))
    visible = gt_mask[..., None].float().expand(-1, -1, len(GT_Y))
    targets = {"gt_y": GT_Y, "gt_x": curves[..., 0], "gt_z": curves[..., 2], "gt_vis": visible,
               "gt_category": categories, "gt_mask": gt_mask}  # fmt: skip
    return targets, gt_points, category_to_index(categories)


def perfect_outputs(N: int = 6) -> tuple[dict, dict]:
    targets, gt_points, classes = batch()
    points = lanes(torch.full((2, N), 30.0))
    points[:, :4] = gt_points
    logits = torch.full((2, N, BACKGROUND_INDEX + 1), -20.0)
    logits[..., BACKGROUND_INDEX] = 20.0
    for b in range(2):
        for g in targets["gt_mask"][b].nonzero()[:, 0]:
            logits[b, g] = -20.0
            logits[b, g, classes[b, g]] = 20.0
    return {"layers": [{"control_points": points, "logits": logits}]}, targets


def criterion(**kwargs) -> SparseLaneSTPLoss:
    weights = kwargs.pop("weights", ALL_TERMS)
    return SparseLaneSTPLoss(build_matcher(), weights, y_range=Y_RANGE, num_control_points=M, **{**LOSS, **kwargs})


def test_focal_loss_by_hand():
    logits = torch.tensor([[[2.0, 0.0, -1.0], [0.5, 0.5, 0.0]]])  # 1 image, 2 proposals, K + 1 = 3
    target = torch.tensor([[0, 2]])

    def focal(row, k, gamma):
        p = math.exp(row[k]) / sum(math.exp(v) for v in row)
        return -((1 - p) ** gamma) * math.log(p)

    for gamma in (0.0, 2.0):
        expected = (focal([2.0, 0.0, -1.0], 0, gamma) + focal([0.5, 0.5, 0.0], 2, gamma)) / 2  # 1/N Σ_i
        assert math.isclose(focal_loss(logits, target, gamma).item(), expected, rel_tol=1e-6)


@pytest.mark.parametrize("representation", ["catmull_rom", "discrete"])
def test_a_perfect_prediction_costs_almost_nothing(representation):
    outputs, targets = perfect_outputs()
    if representation == "discrete":  # the points are the lane at the control y; linear between
        targets["gt_y"] = control_point_y(M, *Y_RANGE)
        points = outputs["layers"][0]["control_points"][:, :4]
        targets["gt_x"], targets["gt_z"] = points[..., 0], points[..., 2]
        targets["gt_vis"] = targets["gt_mask"][..., None].float().expand(-1, -1, M)
    losses = criterion(representation=representation)(outputs, targets)
    assert losses["reg"].item() == pytest.approx(0.0, abs=1e-5)
    assert losses["cls"].item() < 1e-6
    assert losses["vis"].item() < 1e-3  # the clamped BCE of visibility exactly 1
    assert losses["curvature"] == 0 and losses["temporal"] == 0  # gentle curves; no memory
    # Translated copies of a curve are only nearly parallel (2 % narrower where it turns).
    assert losses["parallel"] < 0.05 and losses["surface"] < 1e-3


def test_every_term_is_finite_and_has_gradient():
    targets, gt_points, _ = batch()
    g = torch.Generator().manual_seed(0)
    N, L = 6, 2
    layers = []
    for _ in range(L):
        points = lanes(torch.linspace(-6.0, 6.0, N).expand(2, N).clone(), bend=1e-2)
        points = points + 0.3 * torch.randn(points.shape, generator=g) * torch.tensor([1.0, 0.0, 0.3, 0.0])
        points[..., 3] = torch.rand(2, N, M, generator=g)  # visibility in (0, 1)
        logits = torch.randn(2, N, BACKGROUND_INDEX + 1, generator=g)
        layers.append({"control_points": points.requires_grad_(), "logits": logits.requires_grad_()})
    # Memory: the current lanes seen from 1 and 2 frames back, 0.2 m off.
    memory_lines = torch.cat([lanes(torch.linspace(-6.0, 6.0, 3).expand(2, 3), 1e-2, 0.2 * k) for k in (1, 2)], 1)
    memory = MemoryState(torch.zeros(2, 6 * M, 8), memory_lines.flatten(1, 2), torch.ones(2, 6 * M, dtype=torch.bool),
                         torch.arange(1, 3).repeat_interleave(3 * M).expand(2, -1))  # fmt: skip
    outputs = {"layers": layers, "temporal": {"current": layers[-1]["control_points"], "propagated_memory": memory}}
    losses = criterion(max_curvature=0.01)(outputs, targets)
    assert set(losses) == set(TERMS) | {"total", "matches"}
    # The last layer's pairs, one (line, lane) pair per real lane of each image (G <= N).
    assert [len(pred) for pred, _ in losses["matches"]] == targets["gt_mask"].sum(-1).tolist()
    assert float(losses["denoise"]) == 0.0  # no noised lanes in the outputs (tests/.../test_query_denoising.py)
    for term in (term for term in TERMS if term != "denoise"):
        value = losses[term]
        assert value.isfinite() and value > 0, term
        inputs = [t for layer in layers for t in layer.values()]
        grads = torch.autograd.grad(value, inputs, retain_graph=True, allow_unused=True)
        assert any(gr is not None and gr.abs().sum() > 0 for gr in grads), term
        assert all(gr is None or gr.isfinite().all() for gr in grads), term
    total = sum(losses[term] for term in TERMS)
    torch.testing.assert_close(losses["total"], total)


def test_deep_supervision_sums_the_layers_and_weights_scale_terms():
    outputs, targets = perfect_outputs()
    layer = outputs["layers"][0]
    layer = {"control_points": layer["control_points"] + 0.5, "logits": layer["logits"] * 0.1}
    one = criterion(weights={"cls": 2.0, "reg": 3.0})({"layers": [layer]}, targets)
    two = criterion(weights={"cls": 2.0, "reg": 3.0})({"layers": [layer, layer]}, targets)
    torch.testing.assert_close(two["cls"], 2 * one["cls"])
    torch.testing.assert_close(two["total"], 2 * one["total"])
    torch.testing.assert_close(one["total"], 2.0 * one["cls"] + 3.0 * one["reg"])
    assert one["parallel"] == 0 and one["temporal"] == 0  # weight 0: skipped
    with pytest.raises(ValueError):
        criterion(weights={"regression": 1.0})


def test_regression_loss_by_hand():
    """One image, N = 2 proposals; the matched one is 1 m right and 0.5 m low at every sample."""
    targets, gt_points, classes = batch()
    targets = {k: v[:1, :1] if v.dim() > 1 else v for k, v in targets.items()}
    points = torch.stack([gt_points[0, 0] + torch.tensor([1.0, 0.0, -0.5, 0.0]), lanes(torch.tensor(40.0))], 0)[None]
    logits = torch.zeros(1, 2, BACKGROUND_INDEX + 1)
    losses = criterion()({"layers": [{"control_points": points, "logits": logits}]}, targets)
    assert losses["reg"].item() == pytest.approx(1.5)  # eq. 23: Σ over the 11 visible samples, / 11


def test_orthogonal_correspondence_on_parallel_lines():
    """Straight lines at 45°, 6 m apart along x: the normal plane of (y, x = y) cuts the
    neighbour x = y + 6 at (y + 3, y - 3) (if that lies on it); distance 6 / √2."""
    y = torch.arange(0.0, 50.0, 5.0, dtype=torch.float64)
    x = y + 6.0 * torch.arange(2, dtype=torch.float64)[:, None]
    points = torch.stack([x, y.expand_as(x), torch.zeros_like(x), torch.ones_like(x)], -1)[None]
    corr, hit = orthogonal_correspondence(points, points)
    m = 4  # y = 20: cuts line 1 at y = 17
    assert hit[0, 0, m, 1]
    torch.testing.assert_close(corr[0, 0, m, 1, :3], torch.tensor([23.0, 17.0, 0.0], dtype=torch.float64))
    assert not hit[0, 0, 0, 1]  # at y = 0 the plane meets line 1 before its first point


def test_spatial_priors_see_what_they_should():
    x0 = torch.tensor([[-3.5, 0.0, 3.5]], dtype=torch.float64)
    lines = torch.ones(1, 3, dtype=torch.bool)
    parallel, surface = parallelism_and_surface(lanes(x0, bend=0.0), lines)
    assert parallel.item() == pytest.approx(0.0, abs=1e-9) and surface.item() == pytest.approx(0.0, abs=1e-9)
    tilted = lanes(x0, bend=0.0)
    tilted[..., 2] += 0.05 * tilted[..., 0]  # a banked, still planar road: smooth
    assert parallelism_and_surface(tilted, lines)[1].item() == pytest.approx(0.0, abs=1e-9)

    diverging = lanes(x0, bend=0.0)
    diverging[0, 2, :, 0] += torch.linspace(0.0, 3.0, M, dtype=torch.float64)
    assert parallelism_and_surface(diverging, lines)[0] > 0.3
    warped = lanes(x0, bend=0.0)
    warped[0, 2, 3:, 2] += 1.0  # the right lane steps up: the surface kinks
    # The normal turns by atan(1 / 3.5) = 16° once in 5 steps, on one of the two pairs.
    assert parallelism_and_surface(warped, lines)[1].item() == pytest.approx((0.276 + 0.039) / 10, rel=0.05)

    gentle = lanes(x0, bend=1e-3)  # radius ~500 m
    sharp = lanes(x0, bend=5e-2)  # radius ~10 m at the start
    assert curvature_excess(gentle, lines, max_curvature=0.01) == 0
    assert curvature_excess(sharp, lines, max_curvature=0.01) > 1


def test_temporal_consistency_pulls_towards_the_averaged_past():
    alpha, N = 0.5, 3
    current = lanes(torch.tensor([[-3.5, 0.0, 3.5]]), bend=0.0)
    past = torch.cat([lanes(torch.tensor([[-3.5, 0.0, 3.5]]), bend=0.0, shift=-0.3)] * 2, dim=1)  # 2 frames, 0.3 m left
    K = past.shape[1] * M
    memory = MemoryState(torch.zeros(1, K, 4), past.flatten(1, 2), torch.ones(1, K, dtype=torch.bool),
                         torch.arange(1, 3).repeat_interleave(N * M)[None])  # fmt: skip
    loss = temporal_consistency(current, memory, alpha, max_distance=1.0)
    # Every point: EMA of the past = 0.3 m left; target = α f + (1 - α) EMA; weight v̄ = 1.
    assert loss.item() == pytest.approx((1 - alpha) * 0.3, rel=1e-4)
    assert temporal_consistency(current, memory, alpha, max_distance=0.2) == 0  # too far: not the same lane

    # The EMA runs oldest first: frame t - 2 at 0.4 m, t - 1 at 0.2 m -> 0.8 · 0.2 + 0.2 · 0.4.
    past = torch.cat([lanes(torch.tensor([[-3.5, 0.0, 3.5]]), bend=0.0, shift=-s) for s in (0.2, 0.4)], dim=1)
    ordered = MemoryState(memory.embeddings, past.flatten(1, 2), memory.valid, memory.age)
    ema = 0.8 * 0.2 + 0.2 * 0.4
    assert temporal_consistency(current, ordered, 0.8, max_distance=1.0).item() == pytest.approx(0.2 * ema, rel=1e-4)

    memory.valid[:] = False
    assert temporal_consistency(current, memory, alpha, max_distance=1.0) == 0
    assert temporal_consistency(current, None, alpha, max_distance=1.0) == 0
