import math

import pytest
import torch
from test_sparselanestp import H, W, model, window

from lanelab.geometry import intersect_ground, make_transform, project_lane_points
from lanelab.models.sparselanestp.lateral_offset import LateralOffsetReader
from lanelab.models.sparselanestp.lateral_offset_loss import LateralOffsetLoss, lateral_offset_targets

READER = {"stride": 4, "hidden": 16, "read_range": (5.0, 30.0), "num_reads": 12, "iterations": 3}
Y = torch.linspace(3.0, 103.0, 100)
# The demo's camera at its 96 x 128 input: 1.5 m up, 1.8 m ahead of the ego origin, pitched 2° down.
IMAGE, MAP_SIZE = (96, 128), (24, 32)


def camera() -> tuple[torch.Tensor, torch.Tensor]:
    K = torch.tensor([[110.85, 0.0, 64.0], [0.0, 110.85, 48.0], [0.0, 0.0, 1.0]])
    pitch = torch.tensor(math.radians(2.0))
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, -pitch.sin(), pitch.cos()], [0.0, -pitch.cos(), -pitch.sin()]])
    return K.expand(2, 3, 3), make_transform(R, torch.tensor([0.0, 1.8, 1.5])).expand(2, 4, 4)


def lanes(*xs: torch.Tensor) -> dict[str, torch.Tensor]:
    """Ground truth of two frames with the given lanes' x at Y, flat and visible."""
    x = torch.stack(xs)[None].expand(2, -1, -1).clone()
    return {
        "gt_y": Y.expand(2, -1), "gt_x": x, "gt_z": torch.zeros_like(x), "gt_vis": torch.ones_like(x),
        "gt_mask": torch.ones(2, len(xs), dtype=torch.bool),
    }  # fmt: skip


def exact_map(targets: dict[str, torch.Tensor]) -> torch.Tensor:
    """The map a perfect reader head would predict: the targets, sure where they are confident."""
    offset, _, confident, _ = lateral_offset_targets(targets, *camera(), IMAGE, MAP_SIZE, 2.5, 40.0)
    return torch.stack([offset, confident * 20 - 10], 1)


def line_shifts(reader: LateralOffsetReader, offset_map: torch.Tensor, x0: float) -> torch.Tensor:
    """The reader's shifts (B, 1, M) of a straight flat line at x0 with control points at Y[::10]
    (linear in between)."""
    y = Y[::10]
    hat = (1 - (reader.read_y[:, None] - y).abs() / (y[1] - y[0])).clamp_min(0)  # (S, M) linear interpolation

    def curve(shifts: torch.Tensor) -> torch.Tensor:
        x = (x0 + shifts + torch.zeros(2, 1, len(y))) @ hat.T
        return torch.stack([x, reader.read_y.expand_as(x), torch.zeros_like(x)], -1)

    return reader.line_shifts(offset_map, curve, y, *camera(), IMAGE)


def test_targets_point_across_the_image_to_the_nearest_lane():
    targets = lanes(torch.full_like(Y, -1.75), torch.full_like(Y, 1.75))
    K, T_lane_cam = camera()
    offset, metres_per_width, confident, trained = lateral_offset_targets(targets, K, T_lane_cam, IMAGE, MAP_SIZE, 2.5, 40.0)
    row = MAP_SIZE[0] - 3  # on the road, a few metres ahead
    assert trained[0, row].all() and not trained[0, 0].any()  # the top row is above the horizon
    # Each confident cell's offset, in metres, takes it onto the nearest of the two lanes.
    v = (row + 0.5) * IMAGE[0] / MAP_SIZE[0]
    for column in range(MAP_SIZE[1]):
        u = (column + 0.5) * IMAGE[1] / MAP_SIZE[1]
        target_u = u + float(offset[0, row, column]) * IMAGE[1]
        lane_u = project_lane_points(torch.tensor([[[-1.75, 0, 0], [1.75, 0, 0]]]) + _ground_y(u, v), K[:1], T_lane_cam[:1])[0]
        nearest = lane_u[0, (lane_u[0, :, 0] - u).abs().argmin(), 0]
        if confident[0, row, column]:
            assert target_u == pytest.approx(float(nearest), abs=1e-3)
    assert confident[0, row].sum() > 2
    assert (metres_per_width[0, row][confident[0, row] > 0] > 0).all()


def _ground_y(u: float, v: float) -> torch.Tensor:
    point, _ = intersect_ground(torch.tensor([[[u, v]]]), *(t[:1] for t in camera()))
    return torch.tensor([0.0, float(point[0, 0, 1]), 0.0])


@pytest.mark.parametrize("lateral", [-1.0, 0.6, 1.2])
def test_reading_an_exact_map_puts_a_line_on_its_lane(lateral):
    """A line 1.2 m or less beside a gently turning lane follows it: the read is the position."""
    reader = model(lateral_offset=READER).reader
    lane = lateral + 0.02 * Y
    shifts = line_shifts(reader, exact_map(lanes(lane)), 0.0)
    near = Y[::10] <= 33
    torch.testing.assert_close(shifts[0, 0, near], lane[::10][near], atol=0.15, rtol=0.0)


def test_an_untrained_reader_moves_no_line():
    net = model(lateral_offset=READER)
    out = net(window())
    torch.testing.assert_close(out["init_points"][..., 0], net.anchors()[:, None].expand_as(out["init_points"][..., 0]))
    assert out["offsets"].shape == (2, 2, H // 4, W // 4)


def painted(lane_x: float) -> torch.Tensor:
    """A dark road image (3, 96, 128) with a bright straight line at lane_x, seen by camera()."""
    points = torch.stack([torch.full((400,), lane_x), torch.linspace(4.0, 60.0, 400), torch.zeros(400)], -1)
    uv, _, _ = project_lane_points(points[None], *(t[:1] for t in camera()))
    image = torch.full((3, *IMAGE), -1.0)
    for offset in (-1, 0, 1):  # three pixels wide
        u = (uv[0, :, 0] + offset).long().clamp(0, IMAGE[1] - 1)
        image[:, uv[0, :, 1].long().clamp(0, IMAGE[0] - 1), u] = 2.0
    return image


@pytest.mark.slow
def test_the_loss_teaches_the_map_to_read_the_image():
    """Two images of one road whose line lies 1 m apart: after training the dense loss on both,
    each one's read puts a line on its own marking (a map of positions alone could not)."""
    torch.manual_seed(0)
    net = model(lateral_offset=READER)
    K, T_lane_cam = camera()
    sides = (0.8, 1.8)
    images = torch.stack([painted(x) for x in sides])[:, None]
    targets = lanes(torch.full_like(Y, sides[0]))
    targets["gt_x"][1] = sides[1]
    loss = LateralOffsetLoss(offset_weight=2.0, confidence_weight=1.0, max_offset=2.5, max_distance=40.0)
    optimiser = torch.optim.Adam(net.parameters(), lr=3e-3)

    def offset_map() -> torch.Tensor:
        return net._encode(images, K[:, None], T_lane_cam[:, None])[0].offsets

    for _ in range(150):
        terms = loss(offset_map(), targets, K, T_lane_cam, IMAGE)
        optimiser.zero_grad()
        terms["total"].backward()
        optimiser.step()
    with torch.no_grad():
        shifts = line_shifts(net.reader, offset_map(), 1.3)
    near = shifts[:, 0, 1]  # the control point at 13 m, from a line half-way between the two positions
    torch.testing.assert_close(1.3 + near, torch.tensor(sides), atol=0.25, rtol=0.0)
