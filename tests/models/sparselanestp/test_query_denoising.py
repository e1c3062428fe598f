import numpy as np
import pytest
import torch

from lanelab.models.sparselanestp.criterion import SparseLaneSTPCriterion, detection_inputs
from lanelab.models.sparselanestp.deep_supervision import SparseLaneSTPLoss
from lanelab.models.sparselanestp.instance_mask_loss import InstanceMaskLoss
from lanelab.models.sparselanestp.query_denoising import QueryDenoising
from loss_setup import build_matcher
from test_sparselanestp import BASELINE, TINY, B, F, L, M, model, window

DENOISING = {"groups": 2, "max_shift": 1.5, "max_angle": 2.0}
G, S = 3, 21


def with_lanes(batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Three lanes (one of them padding in the second sample), curving and rising a little."""
    y = torch.linspace(3.0, 103.0, S)
    x = torch.tensor([-1.8, 1.8, 5.4])[:, None] + 1e-4 * y**2
    vis = (y <= 80.0).float().expand(G, S).clone()
    return {
        **batch,
        "gt_y": y.expand(B, S),
        "gt_x": x.expand(B, G, S).clone(),
        "gt_z": (0.01 * y).expand(B, G, S).clone(),
        "gt_vis": vis.expand(B, G, S).clone(),
        "gt_category": torch.tensor([1, 2, 1]).expand(B, G).clone(),
        "gt_mask": torch.tensor([[True, True, True], [True, True, False]]),
    }


def criterion(representation: str, denoise: float = 1.0) -> SparseLaneSTPLoss:
    weights = {"cls": 5.0, "reg": 1.0, "vis": 1.0, "denoise": denoise}
    return SparseLaneSTPLoss(
        build_matcher(), weights, y_range=(3.0, 103.0), num_control_points=M, gamma=2.0, representation=representation,
        max_curvature=0.1, temporal_alpha=0.5, temporal_max_distance=1.0,
    )  # fmt: skip


def test_unnoised_lanes_are_interpolated_and_held_at_the_ends_like_np_interp():
    gt_y = torch.tensor([[0.0, 10.0, 30.0, 60.0]])
    x = torch.tensor([[[1.0, 2.0, 0.0, -3.0]]])  # (1, 1, 4)
    targets = {"gt_y": gt_y, "gt_x": x, "gt_z": 0 * x, "gt_vis": 1 + 0 * x, "gt_mask": torch.ones(1, 1, dtype=torch.bool)}
    y = torch.tensor([-5.0, 0.0, 5.0, 20.0, 59.0, 75.0])
    points, _ = QueryDenoising(8, len(y), groups=1, max_shift=0.0, max_angle=0.0).noised_points(targets, y)
    expected = np.interp(y.numpy(), gt_y[0].numpy(), x[0, 0].numpy())
    np.testing.assert_allclose(points[0, 0, :, 0].numpy(), expected, rtol=1e-6)


def test_noised_lanes_are_the_lanes_moved_sideways_within_the_noise_per_copy():
    batch = with_lanes(window())
    y = torch.linspace(3.0, 103.0, M)
    exact, mask = QueryDenoising(8, M, groups=3, max_shift=0.0, max_angle=0.0).noised_points(batch, y)
    assert exact.shape == (B * 3, G, M, 4) and mask.shape == (B * 3, G)
    expected = [np.interp(y.numpy(), batch["gt_y"][0].numpy(), lane.numpy()) for lane in batch["gt_x"][0]]
    np.testing.assert_allclose(exact[0, :, :, 0].numpy(), np.stack(expected), rtol=1e-6)
    torch.testing.assert_close(mask, batch["gt_mask"].repeat_interleave(3, 0))

    torch.manual_seed(0)
    noised, _ = QueryDenoising(8, M, groups=3, max_shift=1.5, max_angle=2.0).noised_points(batch, y)
    moved = noised[..., 0] - exact[..., 0]  # (B 3, G, M)
    near = moved[..., 0]
    assert near.abs().max() <= 1.5 and near.abs().max() > 0.3
    turn = (moved[..., -1] - moved[..., 0]) / (y[-1] - y[0])
    assert turn.abs().max() <= np.tan(np.radians(2.0)) + 1e-6 and turn.abs().max() > 0
    assert not torch.allclose(moved[0], moved[1])  # every copy its own noise
    torch.testing.assert_close(noised[..., 1:], exact[..., 1:])  # only x moves


def test_point_logits_invert_control_points():
    net = model()
    points = net.head.control_points(torch.randn(2, 3, M, 3))
    torch.testing.assert_close(net.head.control_points(net.head.point_logits(points)), points, atol=1e-4, rtol=0)


@pytest.mark.parametrize("config", [TINY, BASELINE], ids=["sparselanestp", "baseline"])
def test_noised_lanes_leave_the_detection_untouched_and_are_absent_in_inference(config):
    batch = with_lanes(window())
    plain = model(**config).train()
    noised = model(**config, denoising=DENOISING).train()
    noised.load_state_dict(plain.state_dict(), strict=False)
    out, reference = noised(batch), plain(batch)
    torch.testing.assert_close(out["points"], reference["points"])
    torch.testing.assert_close(out["logits"], reference["logits"])
    assert out["denoising"]["points"].shape == (L, B, 2 * G, M, 4)
    assert "denoising" not in noised.eval()(batch)


def test_padded_lanes_and_the_other_copies_do_not_reach_a_noised_lane():
    net = model(**BASELINE, denoising={**DENOISING, "max_shift": 0.0, "max_angle": 0.0}).train()
    batch = with_lanes(window())
    first = net(batch)["denoising"]["points"]
    moved = {**batch, "gt_x": batch["gt_x"].clone()}
    moved["gt_x"][1, 2] += 3.0  # the second sample's padding
    second = net(moved)["denoising"]["points"]
    torch.testing.assert_close(second[:, 1, :2], first[:, 1, :2])  # its real lanes, first copy
    torch.testing.assert_close(second[:, 0], first[:, 0])


@pytest.mark.parametrize("config", [TINY, BASELINE], ids=["sparselanestp", "baseline"])
def test_the_denoising_term_trains_the_noised_lanes_onto_their_lanes(config):
    """A few steps on the denoising term alone bring the noised lanes nearer to the lanes they came
    from, and padding lanes are in no term."""
    torch.manual_seed(0)
    net = model(**config, denoising=DENOISING).train()
    loss = criterion(config["representation"])
    batch = with_lanes(window())
    targets = {key: batch[key] for key in ("gt_y", "gt_x", "gt_z", "gt_vis", "gt_category", "gt_mask")}
    optimiser = torch.optim.Adam(net.parameters(), lr=3e-3)
    terms = []
    for _ in range(30):
        torch.manual_seed(1)  # the same noise every step: the term must fall
        out = net(batch)
        denoise = loss(detection_inputs(out, torch.ones(B, dtype=torch.bool)), targets)["denoise"]
        optimiser.zero_grad()
        denoise.backward()
        optimiser.step()
        terms.append(denoise.item())
    assert terms[-1] < 0.7 * terms[0]

    out = {key: value.detach() for key, value in net(batch)["denoising"].items()}
    padded = {"points": out["points"].clone(), "logits": out["logits"].clone()}
    padded["points"][:, 1, 2] += 5.0  # the second sample's padding lane, first copy
    padded["logits"][:, 1, 2] = 0.0
    values = [
        loss._denoising_loss(o, loss.curves.bases(batch["gt_y"]), targets) for o in (out, padded)
    ]
    torch.testing.assert_close(values[0], values[1])


def test_the_criterion_logs_the_denoising_term_only_where_lanes_were_noised():
    full = SparseLaneSTPCriterion(criterion("discrete"), InstanceMaskLoss(dice_weight=2.0, bce_weight=5.0))
    batch = {**with_lanes(window()), "labeled": torch.ones(B, F, dtype=torch.bool), "padding": torch.zeros(B, dtype=torch.bool)}
    for denoising, expected in ((None, False), (DENOISING, True)):
        net = model(**BASELINE, denoising=denoising).train()
        assert ("denoise" in full(net(batch), batch)) is expected
