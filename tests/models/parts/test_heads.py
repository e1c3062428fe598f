import pytest
import torch
from torch import nn

from lanelab.geometry import evaluate
from lanelab.lanes import LANE_CATEGORY_IDS
from lanelab.models.categories import BACKGROUND_INDEX, NUM_LANE_CATEGORIES, category_to_index, index_to_category
from lanelab.models.parts.heads import LaneHead

C, M, CLASSES = 16, 6, NUM_LANE_CATEGORIES
X_RANGE, Y_RANGE, Z_RANGE = (-10.0, 10.0), (3.0, 103.0), (-2.0, 3.0)


def head(representation: str = "catmull_rom") -> LaneHead:
    torch.manual_seed(0)
    return LaneHead(C, M, CLASSES, X_RANGE, Y_RANGE, Z_RANGE, representation, num_hidden=2)


def test_points_lie_in_the_configured_ranges_and_y_is_fixed_uniform():
    lane_head = head()
    for branch in (lane_head.x_mlp, lane_head.z_mlp):  # zero at init (see the next test)
        nn.init.normal_(branch[-1].weight)
    queries = 100 * torch.randn(3, 4, M, C)  # large, to push the sigmoids into saturation
    logits = lane_head.refine(queries, torch.zeros(3, 4, M, 3))
    points = lane_head.control_points(logits)
    assert points.shape == (3, 4, M, 4)
    x, y, z, v = points.unbind(-1)
    assert X_RANGE[0] <= x.min() and x.max() <= X_RANGE[1]
    assert Z_RANGE[0] <= z.min() and z.max() <= Z_RANGE[1]
    assert 0 <= v.min() and v.max() <= 1
    assert (x.max() - x.min()) > 0.9 * (X_RANGE[1] - X_RANGE[0])  # saturating both ways
    assert torch.equal(y, torch.tensor([3.0, 23.0, 43.0, 63.0, 83.0, 103.0]).expand(3, 4, M))


def test_refinement_starts_as_the_identity_on_x_and_z():
    logits = torch.randn(3, 4, M, 3)
    refined = head().refine(torch.randn(3, 4, M, C), logits)
    torch.testing.assert_close(refined[..., :2], logits[..., :2])


def test_zero_logits_give_the_middle_of_the_ranges_and_normalise_inverts_the_scaling():
    lane_head = head()
    points = lane_head.control_points(torch.zeros(1, 1, M, 3))
    torch.testing.assert_close(points[0, 0, :, 0], torch.zeros(M))
    torch.testing.assert_close(points[0, 0, :, 2], torch.full((M,), 0.5))
    unit = lane_head.normalise(points)
    torch.testing.assert_close(unit[..., [0, 2, 3]], torch.full((1, 1, M, 3), 0.5))
    torch.testing.assert_close(unit[0, 0, :, 1], torch.linspace(0, 1, M))


def test_refine_corrects_x_and_z_and_predicts_visibility_afresh():
    lane_head = head()
    queries = torch.randn(2, 3, M, C)
    previous = torch.randn(2, 3, M, 3)
    fresh = lane_head.refine(queries, torch.zeros_like(previous))
    refined = lane_head.refine(queries, previous)
    torch.testing.assert_close(refined[..., :2], previous[..., :2] + fresh[..., :2])
    torch.testing.assert_close(refined[..., 2], fresh[..., 2])


def test_classification_averages_the_queries_of_a_line():
    lane_head = head()
    queries = torch.randn(2, 3, M, C)
    logits = lane_head.classify(queries)
    assert logits.shape == (2, 3, CLASSES + 1)
    torch.testing.assert_close(lane_head.classify(queries[:, :, torch.randperm(M)]), logits)
    torch.testing.assert_close(lane_head.classify(queries.mean(2, keepdim=True)), logits)


def curved_lane() -> torch.Tensor:
    y = torch.linspace(*Y_RANGE, M)
    return torch.stack([0.001 * (y - 40) ** 2, y, 0.01 * y, torch.linspace(1, 0, M)], -1)


@pytest.mark.parametrize("representation", ["catmull_rom", "discrete"])
def test_decode_passes_through_the_points_at_their_y(representation):
    lane = curved_lane()
    dense = head(representation).decode(lane[None], lane[:, 1])
    torch.testing.assert_close(dense[0], lane)


def test_discrete_interpolates_linearly_and_catmull_rom_follows_the_spline():
    lane = curved_lane()
    y = torch.tensor([13.0, 50.0, 97.5])  # between control points
    discrete = head("discrete").decode(lane, y)
    catmull_rom = head("catmull_rom").decode(lane, y)
    # Discrete: the chord between neighbouring points (13 = 3 + 0.5 * 20, ...).
    for row, (j, t) in zip(discrete, [(0, 0.5), (2, 0.35), (4, 0.725)]):
        torch.testing.assert_close(row, (1 - t) * lane[j] + t * lane[j + 1])
    # Catmull-Rom: the geometry core's spline, which bends with the parabola.
    s = (y - Y_RANGE[0]) / (Y_RANGE[1] - Y_RANGE[0])
    torch.testing.assert_close(catmull_rom, evaluate(lane, s))
    assert (catmull_rom[:, 0] < discrete[:, 0]).all()  # a convex lane lies below its chords
    torch.testing.assert_close(catmull_rom[:, 1], y)


def test_decode_is_batched_and_rejects_positions_outside_the_range():
    lane_head = head()
    lanes = curved_lane().expand(2, 3, M, 4)
    assert lane_head.decode(lanes, torch.linspace(3, 103, 11)).shape == (2, 3, 11, 4)
    with pytest.raises(ValueError, match="y must lie"):
        lane_head.decode(lanes, torch.tensor([1.0, 50.0]))


def test_category_mapping_round_trips():
    ids = torch.tensor(LANE_CATEGORY_IDS)
    index = category_to_index(ids)
    assert torch.equal(index, torch.arange(NUM_LANE_CATEGORIES))
    assert torch.equal(index_to_category(index), ids)
    assert BACKGROUND_INDEX == NUM_LANE_CATEGORIES
    with pytest.raises(ValueError):
        category_to_index(torch.tensor([13]))


def test_points_stay_float32_under_bf16_autocast():
    # 8 mantissa bits of a logit would be decimetres of x.
    lane_head = head()
    with torch.autocast("cpu", dtype=torch.bfloat16):
        logits = lane_head.refine(torch.randn(1, 2, M, C), torch.zeros(1, 2, M, 3, dtype=torch.bfloat16))
        points = lane_head.control_points(logits)
        dense = lane_head.decode(points, torch.linspace(3.0, 103.0, 7))
    assert logits.dtype == points.dtype == dense.dtype == torch.float32


def test_visibility_is_interpolated_linearly_so_a_lane_end_stays_in_0_1_and_keeps_its_gradient():
    points = torch.zeros(1, M, 4)
    points[0, :, 1] = torch.linspace(3.0, 103.0, M)
    points[0, :, 3] = torch.tensor([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])  # the lane ends between 43 and 63 m
    points.requires_grad_(True)
    y = torch.linspace(3.0, 103.0, 101)
    v = head().decode(points, y)[0, :, 3]
    assert 0 <= v.min() and v.max() <= 1 and (v.diff() <= 1e-6).all()  # no overshoot: monotone
    torch.testing.assert_close(v[y == 53.0], torch.tensor([0.5]))
    v.sum().backward()
    assert (points.grad[0, :, 3] > 0).all()
