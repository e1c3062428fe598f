"""The ground positional encoding tags each feature cell with where its pixel's ray meets the road."""

import torch
from torch import nn

from lanelab.geometry import make_transform
from lanelab.models.sparselanestp.ground_encoding import GroundPositionalEncoding

HEIGHT, WIDTH = 64, 96
X_RANGE, Y_RANGE, Z_RANGE = (-10.0, 10.0), (3.0, 103.0), (-2.0, 3.0)


class Recorder(nn.Module):
    """Stands in for the sinusoid encoding: returns its input, padded to C channels."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.channels = channels

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return torch.cat([points, points.new_zeros(*points.shape[:-1], self.channels - 4)], -1)


def camera() -> tuple[torch.Tensor, torch.Tensor]:
    """A level camera 1.5 m above the lane frame origin, looking along +y."""
    K = torch.tensor([[[50.0, 0.0, 48.0], [0.0, 50.0, 32.0], [0.0, 0.0, 1.0]]], dtype=torch.float64)
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=torch.float64)
    return K, make_transform(R, torch.tensor([0.0, 0.0, 1.5], dtype=torch.float64))[None]


def test_cells_below_the_horizon_encode_their_ground_point_and_the_sky_encodes_nothing():
    encoding = GroundPositionalEncoding(8, X_RANGE, Y_RANGE, Z_RANGE).double()
    encoding.encoding = Recorder(8)
    features = torch.randn(1, 8, 8, 12, dtype=torch.float64)  # stride 8
    K, T = camera()
    (code,) = encoding([torch.zeros_like(features)], K, T, (HEIGHT, WIDTH))  # x, y, z normalised, on-ground flag, zeros
    (out,) = encoding([features], K, T, (HEIGHT, WIDTH))
    torch.testing.assert_close(out, features + code)
    x, y, z, on_ground = code[0, 0], code[0, 1], code[0, 2], code[0, 3]
    # The horizon is row 32 (cy): rows 0..3 of cells look at the sky, rows 4..7 at the road.
    assert (on_ground[:4] == 0).all() and (code[0, :3, :4] == 0).all()
    assert (on_ground[4:] == 1).all()
    # Cell (row 7, col 9): pixel (76, 60) meets the ground at depth 1.5 * 50 / 28 m.
    depth = 1.5 * 50.0 / (60.0 - 32.0)
    expected_x, expected_y = (76.0 - 48.0) / 50.0 * depth, depth
    torch.testing.assert_close(x[7, 9], torch.tensor((expected_x - X_RANGE[0]) / 20.0, dtype=torch.float64))
    torch.testing.assert_close(y[7, 9], torch.tensor((expected_y - Y_RANGE[0]) / 100.0, dtype=torch.float64))
    torch.testing.assert_close(z[4:], torch.full_like(z[4:], (0.0 - Z_RANGE[0]) / 5.0))
    assert (y[4:-1] > y[5:]).all()  # lower rows are nearer
    assert (x[4:, :6] < 0.5).all() and (x[4:, 6:] > 0.5).all()  # left of the centre is left
    assert code[0, 4:].abs().max() == 0  # nothing else is added
