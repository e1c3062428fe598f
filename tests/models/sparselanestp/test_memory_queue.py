import math

import pytest
import torch

from lanelab.geometry import euler_to_rotation, invert, make_transform, transform_points
from lanelab.models.sparselanestp.memory_queue import MemoryQueue


def pose(x: float, y: float, yaw: float, pitch: float = 0.0) -> torch.Tensor:
    """T_world_lane (4, 4) float64: the lane frame at (x, y) in the world, yawed about z."""
    R = euler_to_rotation(torch.tensor(0.0, dtype=torch.float64), torch.tensor(pitch, dtype=torch.float64),
                          torch.tensor(yaw, dtype=torch.float64))  # fmt: skip
    return make_transform(R, torch.tensor([x, y, 0.5], dtype=torch.float64))


def ids(frame: int, B: int = 1, N: int = 4, M: int = 3, C: int = 2) -> torch.Tensor:
    """Embeddings (B, N, M, C) whose values name the frame and line: 10 · frame + line."""
    line = torch.arange(N, dtype=torch.float32)[None, :, None, None]
    return (10.0 * frame + line).expand(B, N, M, C).clone()


def test_propagation_puts_a_static_lane_where_the_current_frame_sees_it():
    # A curving lane fixed in the world, seen from frame t-1 and, after the ego drove 10 m
    # forward (+y of the lane frame) and yawed 0.2 rad, from frame t.
    T_before = pose(100.0, -40.0, 0.3)
    motion = make_transform(euler_to_rotation(*torch.tensor([0.0, 0.02, 0.2], dtype=torch.float64)),
                            torch.tensor([0.0, 10.0, 0.1], dtype=torch.float64))  # fmt: skip
    T_now = T_before @ motion
    y = torch.linspace(3.0, 60.0, 5, dtype=torch.float64)
    lane_before = torch.stack([1.5 + 1e-3 * y**2, y, 0.02 * y], -1)  # in frame t-1
    lane_world = transform_points(T_before, lane_before)
    visibility = torch.tensor([1.0, 1.0, 0.5, 0.0, 1.0], dtype=torch.float64)

    queue = MemoryQueue(num_frames=2, num_lines=1)
    control_points = torch.cat([lane_before, visibility[:, None]], -1).float()[None, None]  # (1, 1, 5, 4)
    queue.push(torch.zeros(1, 1, 5, 8), control_points, torch.ones(1, 1), T_before[None])
    state = queue.read(T_now[None])

    expected = transform_points(invert(T_now), lane_world)  # the lane as frame t sees it
    fresh = state.valid[0]  # age 1; the other slot is still empty
    assert fresh.sum() == 5 and (state.age[0][fresh] == 1).all()
    torch.testing.assert_close(state.points[0, fresh, :3], expected.float(), atol=1e-4, rtol=0)
    torch.testing.assert_close(state.points[0, fresh, 3], visibility.float())  # unchanged by eq. 10
    assert not torch.allclose(state.points[0, fresh, :3], control_points[0, 0, :, :3], atol=1.0)  # it did move


def test_fifo_keeps_the_most_confident_lines_of_the_last_frames():
    queue = MemoryQueue(num_frames=2, num_lines=2)
    scores = torch.tensor([[0.1, 0.9, 0.5, 0.2]])
    points = torch.zeros(1, 4, 3, 4)
    identity = torch.eye(4, dtype=torch.float64)[None]
    for frame in (1, 2, 3):
        queue.push(ids(frame), points, scores, identity)
    state = queue.read(identity)
    assert state.embeddings.shape == (1, 2 * 2 * 3, 2)  # K = T · N_mem · M
    lines = state.embeddings[0, :, 0].view(2, 2, 3)[..., 0]  # (slot, line)
    assert lines.tolist() == [[31.0, 32.0], [21.0, 22.0]]  # newest first; lines 1 and 2 by score; frame 1 gone
    assert state.age[0].view(2, 6)[:, 0].tolist() == [1, 2]
    assert state.valid.all()


def test_reset_empties_only_the_streams_that_start_a_clip():
    queue = MemoryQueue(num_frames=3, num_lines=1)
    identity = torch.eye(4, dtype=torch.float64).expand(2, 4, 4)
    scores = torch.ones(2, 4)
    queue.reset(torch.tensor([True, True]))  # before anything was pushed: nothing to do
    assert queue.read(identity) is None
    queue.push(ids(1, B=2), torch.zeros(2, 4, 3, 4), scores, identity)
    queue.push(ids(2, B=2), torch.zeros(2, 4, 3, 4), scores, identity)
    queue.reset(torch.tensor([True, False]))
    queue.push(ids(3, B=2), torch.zeros(2, 4, 3, 4), scores, identity)
    valid = queue.read(identity).valid.view(2, 3, 3)[..., 0]  # (stream, slot)
    assert valid.tolist() == [[True, False, False], [True, True, True]]

    with pytest.raises(ValueError):
        queue.reset(torch.tensor([True, False, True]))  # a new batch size needs a full reset
    queue.reset(torch.ones(3, dtype=torch.bool))
    assert queue.read(identity) is None


def test_contents_are_detached():
    queue = MemoryQueue(num_frames=1, num_lines=2)
    embeddings = torch.randn(1, 4, 3, 2, requires_grad=True)
    points = torch.randn(1, 4, 3, 4, requires_grad=True)
    queue.push(embeddings * 2, points * 2, torch.rand(1, 4, requires_grad=True), torch.eye(4)[None])
    state = queue.read(torch.eye(4)[None])
    assert not state.embeddings.requires_grad and not state.points.requires_grad


def test_no_frames_means_no_memory():
    queue = MemoryQueue(num_frames=0, num_lines=2)
    queue.push(ids(1), torch.zeros(1, 4, 3, 4), torch.ones(1, 4), torch.eye(4)[None])
    assert queue.read(torch.eye(4)[None]) is None


def test_yawed_ego_sees_a_point_ahead_rotate():
    """A point 10 m ahead, after a 90° left turn on the spot, lies 10 m to the right."""
    queue = MemoryQueue(num_frames=1, num_lines=1)
    point = torch.tensor([[[[0.0, 10.0, 0.0, 1.0]]]])
    queue.push(torch.zeros(1, 1, 1, 2), point, torch.ones(1, 1), pose(0.0, 0.0, 0.0)[None])
    state = queue.read(pose(0.0, 0.0, math.pi / 2)[None])
    torch.testing.assert_close(state.points[0, 0], torch.tensor([10.0, 0.0, 0.0, 1.0]), atol=1e-5, rtol=0)
