import torch

from lanelab.models.sparselanestp.instance_mask_loss import lane_masks
from lanelab.models.sparselanestp.lateral_search import LateralSearch

H, W, C = 96, 128, 4
K = torch.tensor([[100.0, 0.0, 64.0], [0.0, 100.0, 48.0], [0.0, 0.0, 1.0]])[None]
# Camera (x right, y down, z forward) 1.5 m above the lane frame's origin, looking along y.
T_LANE_CAM = torch.tensor([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])[None]


def marking_feature(x: float) -> torch.Tensor:
    """(1, C, H, W): channel 0 marks where a straight lane at lateral position x is seen."""
    y = torch.linspace(4.0, 60.0, 57)
    points = torch.stack([torch.full_like(y, x), y, torch.zeros_like(y)], -1)[None, None]
    marks = lane_masks(points, torch.ones(1, 1, 57, dtype=torch.bool), K, T_LANE_CAM, (H, W), (H, W))
    marks = torch.nn.functional.max_pool2d(marks, (1, 5), stride=1, padding=(0, 2))  # a few pixels wide, as features are
    return torch.cat([marks, torch.zeros(1, C - 1, H, W)], 1)


def searcher() -> LateralSearch:
    """A search whose query probe looks for channel 0 only, sharply."""
    search = LateralSearch(C, num_candidates=9, search_range=2.0)
    with torch.no_grad():
        search.value_proj.weight.copy_(torch.eye(C)[..., None, None])
        search.value_proj.bias.zero_()
        search.query_proj.weight.zero_()
        search.query_proj.bias.copy_(torch.tensor([40.0, 0.0, 0.0, 0.0]))
    return search


def test_points_move_onto_the_marking_they_see_and_points_out_of_sight_stay():
    """Control points 0.6 m left and 0.9 m right of a lane at x = 1 m, at 8 and 20 m ahead, move
    onto it (to the candidate nearest it, 0.5 m apart); a point behind the camera has
    no candidate in the image and does not move; the shift has a gradient (it trains the scores)."""
    points = torch.tensor([[[[0.4, 8.0, 0.0], [1.9, 20.0, 0.0], [1.0, -5.0, 0.0]]]])  # (B, N, M, 3)
    queries = torch.zeros(1, 1, 3, C)
    search = searcher()
    shift = search(queries, points, marking_feature(1.0), K, T_LANE_CAM, (H, W))
    moved = points[..., 0] + shift
    assert torch.allclose(moved[0, 0, :2], torch.tensor([1.0, 1.0]), atol=0.15), moved
    assert shift[0, 0, 2] == 0.0
    shift[0, 0, :2].sum().backward()
    assert search.query_proj.bias.grad.abs().sum() > 0


def test_without_a_marking_the_learned_bias_decides():
    """On a blank image every candidate reads the same, so the per-candidate bias alone picks
    the offset: zero at the start (symmetric), the favoured candidate when one is preferred."""
    points = torch.tensor([[[[0.0, 10.0, 0.0]]]])
    search = searcher()
    blank = torch.zeros(1, C, H, W)
    assert search(torch.zeros(1, 1, 1, C), points, blank, K, T_LANE_CAM, (H, W)).abs().item() < 1e-6
    with torch.no_grad():
        search.bias[-1] = 30.0
    assert abs(search(torch.zeros(1, 1, 1, C), points, blank, K, T_LANE_CAM, (H, W)).item() - 2.0) < 1e-3
