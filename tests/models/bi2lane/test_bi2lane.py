"""Bi²Lane (lanelab.models.bi2lane): anchor geometry and sampling (eq. 1), temporal alignment of the
refinement (eq. 3-6), the ablation switches of Tables III-VII, streaming against windowed, gradients.

The model is the tiny preset (experiment=tiny model=bi2lane, as conf/ composes it) unless a test
changes a key."""

from __future__ import annotations

import math
from typing import Any

import pytest
import torch
import torch.nn.functional as F
from hydra.utils import instantiate
from omegaconf import OmegaConf

from lanelab.experiment.config import load_train_config
from lanelab.geometry import make_transform
import lanelab.models.bi2lane.anchors as bi2lane_anchors
import lanelab.models.bi2lane.model as bi2lane_model
from lanelab.models.bi2lane import (
    Bi2Lane,
    BiLevelAggregation,
    TemporalRefinement,
    anchor_families,
    refine,
    sample_features,
    sampling_grid,
)
from lanelab.models.bi2lane import Bi2LaneCriterion
from lanelab.runtime.operator_log import OperatorLog

H, W = 64, 96
K = torch.tensor([[70.0, 0.0, 48.0], [0.0, 70.0, 22.0], [0.0, 0.0, 1.0]])


def camera(pitch_down: float, position: tuple[float, float, float]) -> torch.Tensor:
    """T_lane_cam (4, 4) of a forward-looking camera at position (lane frame) pitched down (radians)."""
    c, s = math.cos(pitch_down), math.sin(pitch_down)
    axes = torch.tensor([[1.0, 0.0, 0.0], [0.0, -s, -c], [0.0, c, -s]])  # rows: camera x (right), y (down), z (forward)
    return make_transform(axes.T, torch.tensor(position))


T_LANE_CAM = camera(0.0, (0.0, 0.0, 1.5))


@pytest.fixture(scope="module")
def tiny_net() -> dict[str, Any]:
    """model.net of experiment=tiny model=bi2lane, as a plain dict."""
    cfg = load_train_config(["experiment=tiny", "model=bi2lane", "paths.output_dir=unused"])
    net = OmegaConf.to_container(cfg.model.net, resolve=True)
    del net["_target_"]
    return net


@pytest.fixture(scope="module")
def tiny_criterion() -> dict[str, Any]:
    cfg = load_train_config(["experiment=tiny", "model=bi2lane", "paths.output_dir=unused"])
    return cfg.model.criterion


def build(net: dict[str, Any], **changes: Any) -> Bi2Lane:
    """The net with these changes, its zero-initialised outputs (offsets of the refinement and of
    the proposals) made small and random as after some training, in eval mode."""
    torch.manual_seed(0)
    model = Bi2Lane(**{**net, **changes})
    offsets = [refinement.offsets for refinement in model.refinement if refinement.offsets is not None]
    for mlp in (model.x_head, model.z_head, *offsets):
        torch.nn.init.normal_(mlp[-1].weight, std=0.01)
    return model.eval()


def poses(F: int, step: float = 2.0, drift: float = 0.3, yaw: float = 0.02) -> torch.Tensor:
    """T_world_lane (F, 4, 4) float64 of an ego driving forward step m per frame, drifting sideways
    and turning (radians per frame)."""
    out = []
    for f in range(F):
        a = yaw * f
        R = torch.tensor([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
        out.append(make_transform(R, torch.tensor([drift * math.sin(f), step * f, 0.0])))
    return torch.stack(out).double()


def window_batch(B: int, F: int, seed: int = 0, moving: bool = True) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    T_world_lane = poses(F) if moving else torch.eye(4, dtype=torch.float64).expand(F, 4, 4)
    return {
        "images": torch.randn(B, F, 3, H, W, generator=g),
        "K": K.expand(B, F, 3, 3),
        "T_lane_cam": T_LANE_CAM.expand(B, F, 4, 4),
        "T_world_lane": T_world_lane.expand(B, F, 4, 4).clone(),
        "valid": torch.ones(B, F, dtype=torch.bool),
    }


# ------------------------------------------------------------------ anchors and sampling (eq. 1)
def test_anchor_families_are_rays_with_their_yaw_and_pitch():
    y = torch.tensor([5.0, 10.0, 20.0])
    anchors = anchor_families(y, (-10.0, 10.0), num_x=3, yaws=[0.0, 10.0], pitches=[2.0])
    # start x -10 (yaw 0: on the range's edge, dropped; yaw 10: enters it), 0, 10 (yaw 10 leaves the range: dropped)
    assert anchors.shape == (3, 3, 3)
    starts_and_yaws = [(-10.0, 10.0), (0.0, 0.0), (0.0, 10.0)]
    for anchor, (start, yaw) in zip(anchors, starts_and_yaws):
        torch.testing.assert_close(anchor[:, 0], start + y * math.tan(math.radians(yaw)))
        torch.testing.assert_close(anchor[:, 1], y)
        torch.testing.assert_close(anchor[:, 2], y * math.tan(math.radians(2.0)))


def test_a_known_anchor_projects_where_the_pinhole_camera_says_and_samples_the_feature_there():
    T = camera(0.08, (0.4, 1.2, 1.6))
    point = torch.tensor([2.5, 14.0, 0.3])
    # The camera model, written out: camera coordinates along the camera's axes, then K.
    d = point - T[:3, 3]
    X, Y, Z = (d @ T[:3, 0], d @ T[:3, 1], d @ T[:3, 2])
    u, v = 70.0 * X / Z + 48.0, 70.0 * Y / Z + 22.0
    grid = sampling_grid(point.view(1, 1, 1, 3), K[None], T[None], (H, W))
    torch.testing.assert_close(grid[0, 0, 0], torch.stack([2 * u / W - 1, 2 * v / H - 1]))

    # A stride-8 feature map whose two channels hold the pixel coordinates of the cells' centres:
    # bilinear sampling of a linear map returns the point's own pixel.
    h, w = H // 8, W // 8
    cu = ((torch.arange(w) + 0.5) * 8.0).expand(h, w)
    cv = ((torch.arange(h) + 0.5) * 8.0)[:, None].expand(h, w)
    features = torch.stack([cu, cv])[None]
    sampled = sample_features(features, grid)[0, 0, 0]
    torch.testing.assert_close(sampled, torch.stack([u, v]))

    behind = sampling_grid(torch.tensor([0.0, -5.0, 0.0]).view(1, 1, 1, 3), K[None], T[None], (H, W))
    assert sample_features(features, behind).abs().sum() == 0  # behind the camera: no feature


def test_sampling_on_the_cpu_equals_grid_sample_values_and_gradients(monkeypatch):
    """The CPU path for large samples (a weighted sum of four neighbours) is grid_sample's
    bilinear interpolation with zero padding: inside, across the border, outside and behind the
    camera, and its gradients with respect to the features and to the sampling points, which
    training follows."""
    monkeypatch.setattr(bi2lane_anchors, "_LARGE_SAMPLE", 0)  # this small sample takes the large samples' path
    torch.manual_seed(0)
    features = torch.randn(2, 5, 6, 9, dtype=torch.float64, requires_grad=True)
    grid = (torch.rand(2, 7, 4, 2, dtype=torch.float64) * 2.6 - 1.3)
    grid[0, 0, 0] = torch.tensor([-2.0, -2.0], dtype=torch.float64)  # where sampling_grid puts points behind the camera
    grid.requires_grad_(True)
    expected = F.grid_sample(features, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    expected = expected.permute(0, 2, 3, 1)
    sampled = sample_features(features, grid)
    torch.testing.assert_close(sampled, expected)
    assert sampled.is_contiguous()
    weights = torch.randn_like(expected)
    want = torch.autograd.grad((expected * weights).sum(), (features, grid))
    got = torch.autograd.grad((sampled * weights).sum(), (features, grid))
    torch.testing.assert_close(got[0], want[0])
    torch.testing.assert_close(got[1], want[1])


# ---------------------------------------------------------------- temporal alignment (eq. 3-6)
@pytest.mark.parametrize("alignment", [True, False])
def test_refinement_keeps_anchors_on_the_same_world_lane_when_aligned(alignment):
    F, M = 4, 5
    T_world_lane = poses(F)[None]  # (1, F, 4, 4)
    world = torch.stack([torch.full((M,), 1.75), torch.linspace(10.0, 50.0, M), torch.zeros(M)], -1).double()

    def seen_from(frame: int) -> torch.Tensor:  # the static world lane in that frame's lane frame
        T = torch.linalg.inv(T_world_lane[0, frame])
        return (world @ T[:3, :3].T + T[:3, 3]).float()

    refinement = TemporalRefinement(8, M, 16, 1, alignment)  # offsets start at zero: anchors only move
    features = torch.zeros(1, F, 8, H // 8, W // 8)
    inputs = (features, K.expand(1, F, 3, 3), T_LANE_CAM.expand(1, F, 4, 4), T_world_lane,
              torch.ones(1, F, dtype=torch.bool), (H, W))  # fmt: skip
    forward = refinement(seen_from(0)[None], list(range(F)), *inputs)
    reverse = refinement(seen_from(F - 1)[None], list(range(F - 1, -1, -1)), *inputs)
    for step, frame in enumerate(range(F)):
        expected = seen_from(frame) if alignment else seen_from(0)
        torch.testing.assert_close(forward.anchors[step][0, 0], expected, atol=1e-4, rtol=0)
    for step, frame in enumerate(range(F - 1, -1, -1)):
        expected = seen_from(frame) if alignment else seen_from(F - 1)
        torch.testing.assert_close(reverse.anchors[step][0, 0], expected, atol=1e-4, rtol=0)
    # Each step's detection, brought into the current frame with the true ego motion: on the lane
    # when the anchors followed it, elsewhere when they did not.
    on_lane = torch.allclose(forward.detections[0, :, 0], seen_from(F - 1).expand(F - 1, M, 3), atol=1e-4)
    assert on_lane == alignment
    assert not torch.allclose(seen_from(0), seen_from(F - 1), atol=0.1)  # the ego did move


def test_a_padded_frame_passes_the_anchors_on_unrefined():
    M = 3
    refinement = TemporalRefinement(4, M, 8, 1, alignment=True)
    torch.nn.init.normal_(refinement.offsets[-1].weight)  # non-zero offsets
    anchors = torch.stack([torch.zeros(M), torch.linspace(10.0, 30.0, M), torch.zeros(M)], -1)[None]
    features = torch.randn(1, 3, 4, H // 8, W // 8)
    valid = torch.tensor([[False, True, True]])
    refined = refinement(anchors, [0, 1, 2], features, K.expand(1, 3, 3, 3), T_LANE_CAM.expand(1, 3, 4, 4),
                         poses(3)[None], valid, (H, W))  # fmt: skip
    torch.testing.assert_close(refined.anchors[1][0], anchors)  # frame 1 (the clip's first) starts from the anchors
    assert not torch.allclose(refined.anchors[2][0], anchors)
    assert refined.detection_valid.tolist() == [[False, True]]


def test_a_step_moves_each_point_by_its_offsets_from_the_head():
    """Eq. 2: the head's 2M outputs are the M points' Δx, then their Δz (the layout checkpoints
    hold); a step adds them to the anchor's x and z, and leaves y alone."""
    M = 4
    torch.manual_seed(3)
    refinement = TemporalRefinement(4, M, 8, 1, alignment=False)
    torch.nn.init.normal_(refinement.offsets[-1].weight, std=0.1)
    torch.nn.init.normal_(refinement.offsets[-1].bias, std=0.1)
    anchors = torch.stack([torch.full((M,), 1.0), torch.linspace(8.0, 30.0, M), torch.zeros(M)], -1)[None]
    features = torch.randn(1, 2, 4, H // 8, W // 8)
    refined = refinement(anchors, [0, 1], features, K.expand(1, 2, 3, 3), T_LANE_CAM.expand(1, 2, 4, 4),
                         poses(2)[None], torch.ones(1, 2, dtype=torch.bool), (H, W))  # fmt: skip
    offsets = refinement.offsets(refined.features[0].flatten(-2))[0, 0]  # (2M,) of the first step's lane
    moved = refined.anchors[1][0, 0] - anchors[0]
    torch.testing.assert_close(moved[:, 0], offsets[:M])
    torch.testing.assert_close(moved[:, 2], offsets[M:])
    assert torch.equal(moved[:, 1], torch.zeros(M))


def test_two_directions_in_lockstep_compute_what_each_computes_alone():
    M, F, B = 4, 3, 2
    torch.manual_seed(1)
    forward, reverse = TemporalRefinement(4, M, 8, 1, alignment=True), TemporalRefinement(4, M, 8, 1, alignment=True)
    for refinement in (forward, reverse):  # distinct, non-zero heads
        torch.nn.init.normal_(refinement.offsets[-1].weight, std=0.05)
    anchors = torch.stack([torch.full((M,), -1.5), torch.linspace(8.0, 30.0, M), torch.zeros(M)], -1)[None]
    features = torch.randn(B, F, 4, H // 8, W // 8)
    inputs = (features, K.expand(B, F, 3, 3), T_LANE_CAM.expand(B, F, 4, 4), poses(F)[None].expand(B, F, 4, 4),
              torch.tensor([[True, True, True], [False, True, True]]), (H, W))  # fmt: skip
    orders = [[0, 1, 2], [2, 1, 0]]
    together = refine([forward, reverse], anchors, orders, *inputs)
    for direction, order, joint in zip((forward, reverse), orders, together):
        alone = direction(anchors, order, *inputs)
        torch.testing.assert_close(joint.detections, alone.detections, atol=1e-5, rtol=1e-5)
        assert torch.equal(joint.detection_valid, alone.detection_valid)
        for got, want in zip([*joint.features, *joint.anchors], [*alone.features, *alone.anchors]):
            torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)
    assert not torch.allclose(together[0].anchors[1], together[1].anchors[1])  # the two chains did differ
    with pytest.raises(ValueError, match="lockstep"):
        refine([forward, reverse], anchors, [[0, 1, 2], [2, 1]], *inputs)
    unaligned = TemporalRefinement(4, M, 8, 1, alignment=False)
    with pytest.raises(ValueError, match="one temporal alignment"):
        refine([forward, unaligned], anchors, orders, *inputs)


def test_streaming_writes_the_lanes_into_one_stack_that_equals_the_trained_ones():
    """Without autograd the chains write each step's lanes straight into the stack BLFA reads (no
    copy of the history there); with it they are stacked after the chain. Both give the same lanes."""
    M, F = 4, 3
    torch.manual_seed(2)
    directions = [TemporalRefinement(4, M, 8, 1, alignment=True) for _ in range(2)]
    for refinement in directions:
        torch.nn.init.normal_(refinement.offsets[-1].weight, std=0.05)
    anchors = torch.stack([torch.full((M,), 0.5), torch.linspace(8.0, 30.0, M), torch.zeros(M)], -1)[None]
    inputs = (torch.randn(1, F, 4, H // 8, W // 8), K.expand(1, F, 3, 3), T_LANE_CAM.expand(1, F, 4, 4),
              poses(F)[None], torch.ones(1, F, dtype=torch.bool), (H, W))  # fmt: skip
    orders = [[0, 1, 2], [2, 1, 0]]
    trained = refine(directions, anchors, orders, *inputs)
    with torch.no_grad():
        streamed = refine(directions, anchors, orders, *inputs)
    for got, want in zip(streamed, trained):
        assert got.features.shape == (F, 1, 1, M, 4)
        torch.testing.assert_close(got.features, want.features.detach())


# -------------------------------------------------------------------------- ablation switches
def test_aggregation_in_chunks_of_anchors_equals_one_call(tiny_net, monkeypatch):
    """On a CPU, BLFA runs over chunks of anchors (each anchor's aggregation is its own); the
    detections and their gradients are those of one call over all anchors."""
    net = build(tiny_net, num_history_frames=2).train()
    batch = window_batch(2, 3, seed=5)
    results = []
    for chunk in (10_000, 7):  # one call for the tiny size's 71 anchors, then chunks with a remainder
        monkeypatch.setattr(bi2lane_model, "_CPU_AGGREGATION_CHUNK", chunk)
        net.zero_grad()
        torch.manual_seed(0)
        out = net(batch)
        (out["points"].sum() + out["logits"].sum()).backward()
        results.append((out["points"], out["logits"], [p.grad.clone() for p in net.aggregation.parameters()]))
    (points, logits, grads), (chunked_points, chunked_logits, chunked_grads) = results
    torch.testing.assert_close(chunked_points, points, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(chunked_logits, logits, atol=1e-5, rtol=1e-5)
    for got, want in zip(chunked_grads, grads):
        torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-4)


def changes_output(net: Bi2Lane, batch: dict, frames: list[int]) -> bool:
    """Whether new images in these frames of the window change the net's proposals or classes."""
    with torch.no_grad():
        before = net(batch)
        other = dict(batch, images=batch["images"].clone())
        other["images"][:, frames] = torch.randn_like(other["images"][:, frames])
        after = net(other)
    return not (torch.allclose(before["points"], after["points"]) and torch.allclose(before["logits"], after["logits"]))


@pytest.mark.parametrize(
    ("changes", "reads_history"),
    [
        ({"direction": "reverse", "aggregation": "none"}, False),  # reverse features of the current frame alone
        ({"direction": "reverse", "aggregation": "line"}, False),  # line level: within the current frame
        ({"direction": "reverse", "aggregation": "point"}, True),  # point level: to the history frames
        ({"direction": "reverse", "aggregation": "bilevel"}, True),
        ({"direction": "forward", "aggregation": "none"}, True),  # forward refinement walks through history
        ({"num_history_frames": 0, "direction": "forward", "aggregation": "bilevel"}, False),  # the baseline
    ],
)
def test_what_each_aggregation_and_direction_reads(tiny_net, changes, reads_history):
    net = build(tiny_net, **changes)
    batch = window_batch(2, 4)
    assert changes_output(net, batch, [0, 1, 2]) == reads_history
    assert changes_output(net, batch, [3])  # the current frame always counts


def test_the_number_of_history_frames_is_how_far_back_the_model_reads(tiny_net):
    batch = window_batch(1, 6)
    for n in (1, 3, 5):
        net = build(tiny_net, num_history_frames=n)
        if n < 5:
            assert not changes_output(net, batch, list(range(5 - n)))  # older than N frames back: not read
        assert changes_output(net, batch, [5 - n])
        assert net(batch)["detections"].shape[1] == 2 * n  # n steps per direction
    with pytest.raises(ValueError, match="needs windows of at least 4 frames"):
        build(tiny_net, num_history_frames=3)(window_batch(1, 2))


def test_temporal_alignment_changes_only_what_ego_motion_moves(tiny_net):
    aligned, unaligned = build(tiny_net, temporal_alignment=True), build(tiny_net, temporal_alignment=False)
    unaligned.load_state_dict(aligned.state_dict())
    with torch.no_grad():
        parked = window_batch(1, 4, moving=False)
        torch.testing.assert_close(aligned(parked)["points"], unaligned(parked)["points"])
        driving = window_batch(1, 4, moving=True)
        assert not torch.allclose(aligned(driving)["points"], unaligned(driving)["points"])


def test_without_the_bev_branch_there_is_no_bev_output_and_no_seg_loss(tiny_net, tiny_criterion):
    net = build(tiny_net, bev=None).train()
    outputs = net(window_batch(1, 4))
    assert "bev_logits" not in outputs
    criterion = instantiate(tiny_criterion)
    with pytest.raises(ValueError, match="needs the model's BEV branch"):
        criterion(outputs, {})


# ------------------------------------------------------------------------------ streaming
def test_streaming_with_the_cache_equals_the_windowed_computation(tiny_net):
    net = build(tiny_net, num_history_frames=2)
    clip = window_batch(2, 5, seed=3)  # two streams, 5 frames each
    net.reset(torch.ones(2, dtype=torch.bool))
    with torch.no_grad():
        streamed = [net.step({key: clip[key][:, f] for key in ("images", "K", "T_lane_cam", "T_world_lane")})
                    for f in range(5)]  # fmt: skip
        for f in range(5):
            positions = [max(p, 0) for p in range(f - 2, f + 1)]  # the dataset pads a clip's start with its first frame
            window = {key: clip[key][:, positions] for key in ("images", "K", "T_lane_cam", "T_world_lane")}
            window["valid"] = torch.tensor([p >= 0 for p in range(f - 2, f + 1)]).expand(2, 3)
            windowed = net(window)
            torch.testing.assert_close(streamed[f]["points"], windowed["points"], atol=1e-5, rtol=1e-5)
            torch.testing.assert_close(streamed[f]["logits"], windowed["logits"], atol=1e-5, rtol=1e-5)
        # A reset of one stream: it starts again, the other goes on.
        step = {key: clip[key][:, 0] for key in ("images", "K", "T_lane_cam", "T_world_lane")}
        restarted = net.step({**step, "reset": torch.tensor([True, False])})
        fresh = build(tiny_net, num_history_frames=2)
        fresh.load_state_dict(net.state_dict())
        torch.testing.assert_close(restarted["points"][:, 0], fresh.step(step)["points"][:, 0], atol=1e-5, rtol=1e-5)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device (run on a device machine)")
@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16])
def test_bi2lane_streaming_with_graphs_equals_it_without(tiny_net, dtype):
    eager = build(tiny_net, num_history_frames=2, cuda_graphs=False).cuda()
    graphed = build(tiny_net, num_history_frames=2).cuda()
    graphed.load_state_dict(eager.state_dict())
    clip = {key: value.cuda() for key, value in window_batch(2, 6, seed=5).items()}
    tolerance = 1e-5 if dtype == torch.float32 else 2e-2
    with torch.no_grad(), torch.autocast("cuda", dtype=dtype, enabled=dtype != torch.float32):
        for f in range(6):
            frame = {key: clip[key][:, f] for key in ("images", "K", "T_lane_cam", "T_world_lane")}
            if f == 4:  # one stream starts again: the reset happens outside the graphs
                frame["reset"] = torch.tensor([True, False], device="cuda")
            want, got = eager.step(frame), graphed.step(frame)
            for key in ("points", "logits", "detections"):
                torch.testing.assert_close(got[key].float(), want[key].float(), atol=tolerance, rtol=tolerance)
    assert graphed._graphed is not None and eager._graphed is None
    graphed.cpu()  # a move drops the graphs, which read the parameters where they were
    assert graphed._graphed is None


def test_what_the_cuda_graphs_capture_touches_no_host_data(tiny_net):
    """A CUDA graph cannot capture a host-to-device copy or a read back to the host: the calls
    that streaming replays from graphs (_encode, _detect) must hold neither. Checked on the CPU,
    so that CI catches what only a GPU would otherwise show."""
    net = build(tiny_net, num_history_frames=2).eval()
    spy = OperatorLog()

    def watched(fn):
        def call(*args):
            with spy:
                return fn(*args)
        return call

    net._encode, net._detect = watched(net._encode), watched(net._detect)
    clip = window_batch(2, 3, seed=5)
    with torch.no_grad():
        for f in range(3):
            net.step({key: clip[key][:, f] for key in ("images", "K", "T_lane_cam", "T_world_lane")})
    assert spy.operators  # the calls ran under the log
    assert spy.host_transfers() == []


def test_a_history_frame_adds_a_chain_step_of_few_kernels_and_no_copy_of_its_lanes(tiny_net):
    """At batch 1 on a GPU a history frame costs its BDTR step's kernel launches more than their
    arithmetic (benchmarks/RESULTS.md): what does not depend on the refined anchors is prepared
    once for all steps, and a step stays near fifteen operators (stop 32's took 47.5). What is
    left is memory traffic: BLFA reads the history where BDTR wrote it, so a history frame writes
    about seven times its lanes (stop 33's, which stacked the history again, eight)."""
    kernels, written = {}, {}
    for n in (1, 3):
        net = build(tiny_net, num_history_frames=n)
        batch = window_batch(1, n + 1)
        with torch.no_grad(), OperatorLog() as log:
            net(batch)
        kernels[n], written[n] = log.kernels(), log.bytes_written()
    assert (kernels[3] - kernels[1]) / 2 <= 18, kernels
    lanes = 2 * len(net.anchors) * tiny_net["num_points"] * tiny_net["embed_dim"] * 4  # a step's, both directions
    assert (written[3] - written[1]) / 2 <= 7.5 * lanes, (written, lanes)


# ------------------------------------------------------------------------------ gradients
def test_every_parameter_receives_gradient(tiny_net, tiny_criterion):
    net = build(tiny_net).train()  # (build makes the zero-initialised outputs non-zero: they pass gradient back)
    criterion: Bi2LaneCriterion = instantiate(tiny_criterion)
    B, F, S = 2, 4, 20
    batch = window_batch(B, F)
    y = torch.linspace(3.0, 60.0, S)
    batch.update({
        "labeled": torch.ones(B, F, dtype=torch.bool), "padding": torch.zeros(B, dtype=torch.bool),
        "gt_y": y.expand(B, S), "gt_x": torch.tensor([-1.75, 1.75])[None, :, None].expand(B, 2, S).clone(),
        "gt_z": torch.full((B, 2, S), 0.1), "gt_vis": torch.ones(B, 2, S), "gt_category": torch.full((B, 2), 2),
        "gt_mask": torch.ones(B, 2, dtype=torch.bool),
    })  # fmt: skip
    losses = criterion(net(batch), batch)
    assert set(losses) == {"total", "cls", "reg", "vis", "refine", "seg"}
    losses["total"].backward()
    silent = [name for name, p in net.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0]
    assert silent == []


def test_a_batch_without_scored_frames_costs_nothing_but_reaches_every_output(tiny_net, tiny_criterion):
    net = build(tiny_net).train()
    batch = window_batch(2, 4)
    batch.update({"labeled": torch.ones(2, 4, dtype=torch.bool), "padding": torch.ones(2, dtype=torch.bool)})
    losses = instantiate(tiny_criterion)(net(batch), batch)
    assert set(losses) == {"total"} and float(losses["total"]) == 0.0
    losses["total"].backward()  # DDP ranks stay in step: every parameter that made an output has a gradient
    assert all(p.grad is not None for p in net.parameters())


def test_the_point_level_is_a_transformer_decoder_layer_over_the_history_frames():
    """BLFA's point level (eq. 7-8), computed without projecting the history keys, equals the plain
    layer: each point's query (plus the current frame's age embedding) attends with
    nn.MultiheadAttention to the same point of the real history frames (keys plus their ages)."""
    torch.manual_seed(0)
    B, A, M, N, C = 2, 3, 4, 3, 16
    aggregation = BiLevelAggregation(C, M, N, "point", 2, 32, 0.0).eval()
    current, history = torch.randn(B, A, M, C), torch.randn(B, A, M, N, C)
    valid = torch.tensor([[True, False, True], [False, False, False]])  # stream 1 has no real history
    got = aggregation(current, history, valid)
    layer, age = aggregation.point, aggregation.age
    query = (current[0] + age[0]).reshape(A * M, 1, C)
    keys = (history[0] + age[1 : N + 1]).reshape(A * M, N, C)
    attended, _ = layer.attention(query, keys, history[0].reshape(A * M, N, C), key_padding_mask=~valid[0].expand(A * M, N))
    x = layer.norm1(query + attended)
    expected = layer.norm2(x + layer.ffn(x)).reshape(A, M, C)
    assert torch.allclose(got[0], expected, atol=1e-5)
    assert torch.equal(got[1], current[1])  # no real history frame: the current feature as it is
    # The forward direction hands its history oldest first: the same keys, each with its own age.
    oldest_first = aggregation(current, history.flip(3), valid.flip(1), oldest_first=True)
    torch.testing.assert_close(oldest_first, got, atol=1e-6, rtol=1e-6)
