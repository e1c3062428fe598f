import pytest
import torch
from torch import nn

from lanelab.geometry import make_transform
from lanelab.models.categories import NUM_LANE_CATEGORIES
from lanelab.models.sparselanestp import SparseLaneSTP

B, F, H, W = 2, 3, 64, 96
N, M, L, C = 4, 6, 2, 32

TINY = dict(
    backbone_depth=18, backbone_width=8, embed_dim=C,
    num_lines=N, num_points=M, query_convs=2, mask_dim=16,
    num_layers=L, num_heads=4, ffn_dim=64, dropout=0.0, dca_levels=2, dca_points=2,
    attention="sparse", use_sla=True, use_pna=True, use_tca=True, pna_neighbors=2, tca_neighbors=4,
    num_memory_frames=2, num_memory_lines=2,
    num_classes=NUM_LANE_CATEGORIES, x_range=(-10.0, 10.0), y_range=(3.0, 103.0), z_range=(-2.0, 3.0),
    representation="catmull_rom", head_hidden_layers=2, ground_encoding=True, anchor_span=5.25, dca_content_weights=True,
    lateral_search={"num_candidates": 5, "search_range": 2.0},
)  # fmt: skip
BASELINE = {**TINY, "num_memory_frames": 0, "attention": "global", "representation": "discrete"}


def model(**overrides) -> SparseLaneSTP:
    torch.manual_seed(0)
    return SparseLaneSTP(**{**TINY, **overrides})


def window(valid: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """A batch of F frames of a camera 1.5 m up, driving 2 m forward per frame while turning."""
    generator = torch.Generator().manual_seed(1)
    K = torch.tensor([[50.0, 0.0, 48.0], [0.0, 50.0, 32.0], [0.0, 0.0, 1.0]])
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # optical -> lane axes
    T_lane_cam = make_transform(R, torch.tensor([0.0, 0.0, 1.5]))
    yaw = torch.arange(F) * 0.05
    rotation = torch.zeros(F, 3, 3)
    rotation[:, 0, 0], rotation[:, 0, 1], rotation[:, 1, 0], rotation[:, 1, 1] = yaw.cos(), -yaw.sin(), yaw.sin(), yaw.cos()
    rotation[:, 2, 2] = 1
    T_world_lane = make_transform(rotation, torch.stack([torch.zeros(F), 2.0 * torch.arange(F), torch.zeros(F)], -1))
    return {
        "images": torch.randn(B, F, 3, H, W, generator=generator),
        "K": K.expand(B, F, 3, 3),
        "T_lane_cam": T_lane_cam.expand(B, F, 4, 4),
        "T_world_lane": T_world_lane.expand(B, F, 4, 4),
        "valid": torch.ones(B, F, dtype=torch.bool) if valid is None else valid,
    }


def frame(batch: dict[str, torch.Tensor], f: int) -> dict[str, torch.Tensor]:
    return {key: value[:, f] for key, value in batch.items() if key != "valid"}


def test_output_layout():
    net = model().eval()  # eval: batch norm statistics must not depend on how frames are batched
    out = net(window())
    assert out["points"].shape == (L, B, N, M, 4)
    assert out["logits"].shape == (L, B, N, NUM_LANE_CATEGORIES + 1)
    assert out["init_points"].shape == (B, N, M, 4)
    assert out["masks"].shape == (B, N, H // 8, W // 8)
    dense = net.decode(out, torch.linspace(3.0, 103.0, 11))
    assert dense.shape == (B, N, 11, 4)
    everything = net(window(), all_frames=True)
    assert everything["points"].shape == (L, B, F, N, M, 4)
    assert everything["masks"].shape == (B, F, N, H // 8, W // 8)
    torch.testing.assert_close(everything["points"][:, :, -1], out["points"])


@pytest.mark.parametrize("config", [TINY, BASELINE], ids=["sparselanestp", "baseline"])
def test_every_parameter_receives_gradient_in_a_windowed_step(config):
    net = model(**config)
    for branch in (net.head.x_mlp, net.head.z_mlp, net.query_generator.initial_points):
        nn.init.normal_(branch[-1].weight, std=0.1)  # zero at init (no gradient behind them): as after a step
    batch = window()
    batch["images"].requires_grad_(True)
    out = net(batch)
    loss = out["points"].square().mean() + out["logits"].square().mean() + out["masks"].square().mean()
    loss.backward()
    missing = [name for name, p in net.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0]
    assert not missing
    # Only the current frame is differentiable; the history only fills the memory.
    assert batch["images"].grad[:, :-1].abs().sum() == 0
    assert batch["images"].grad[:, -1].abs().sum() > 0


def test_streaming_equals_windowed_inference():
    net = model().eval()
    # Sample 1's window starts with a padding frame: its clip starts at frame 1.
    valid = torch.tensor([[True, True, True], [False, True, True]])
    batch = window(valid)
    with torch.no_grad():
        windowed = net(batch, all_frames=True)
        starts = [torch.tensor([True, True]), torch.tensor([False, True]), torch.tensor([False, False])]
        streamed = [net.step({**frame(batch, f), "reset": starts[f]}) for f in range(F)]
    torch.testing.assert_close(windowed.pop("anchors"), streamed[-1]["anchors"])
    for key in windowed:
        axis = 2 if key in ("points", "logits") else 1
        for f in (1, 2):  # frame 0 of sample 1 is padding, so compare from frame 1 on
            torch.testing.assert_close(windowed[key].select(axis, f), streamed[f][key], rtol=1e-5, atol=1e-5)


def test_the_memory_changes_the_current_frame_and_resets_forget_it():
    net = model().eval()
    batch = window()
    with torch.no_grad():
        with_history = net(batch)["points"]
        alone = net({key: value[:, -1:] for key, value in batch.items()})["points"]
        padded = net({**batch, "valid": torch.tensor([[False, False, True]] * B)})["points"]
    assert not torch.allclose(with_history, alone, atol=1e-4)
    torch.testing.assert_close(padded, alone, rtol=1e-5, atol=1e-5)


def test_streaming_carries_the_memory_across_calls():
    net = model().eval()
    batch = window()
    with torch.no_grad():
        net.reset(torch.ones(B, dtype=torch.bool))
        net.step(frame(batch, 0))
        carried = net.step(frame(batch, 1))["points"]
        net.reset(torch.tensor([True, False]))
        fresh = net.step(frame(batch, 1))["points"]
    # Sample 0 was reset: it sees an empty memory again (as after a clip start); sample 1 was
    # not and now has two past frames.
    net_again = model().eval()
    with torch.no_grad():
        net_again.reset(torch.ones(B, dtype=torch.bool))
        first = net_again.step(frame(batch, 1))["points"]
    torch.testing.assert_close(fresh[:, 0], first[:, 0], rtol=1e-5, atol=1e-5)
    assert not torch.allclose(carried[:, 0], first[:, 0], atol=1e-4)


def test_baseline_is_single_frame_and_discrete():
    net = model(**BASELINE).eval()
    batch = window()
    with torch.no_grad():
        out = net(batch)
        alone = net({key: value[:, -1:] for key, value in batch.items()})
    torch.testing.assert_close(out["points"], alone["points"], rtol=1e-5, atol=1e-5)
    assert net.head.representation == "discrete"
    points = out["points"][-1]
    y = torch.tensor([13.0, 23.0])  # halfway between control points 0 and 1, and on point 1
    dense = net.decode(out, y)
    torch.testing.assert_close(dense[..., 0, :3], (points[..., 0, :3] + points[..., 1, :3]) / 2)
    torch.testing.assert_close(dense[..., 1, :], points[..., 1, :])


def test_dense_reference_attention_gives_the_same_model_outputs():
    sparse = model().eval()
    dense = model(attention="dense").eval()
    dense.load_state_dict(sparse.state_dict())
    batch = window()
    with torch.no_grad():
        torch.testing.assert_close(dense(batch)["points"], sparse(batch)["points"], rtol=1e-5, atol=1e-5)
