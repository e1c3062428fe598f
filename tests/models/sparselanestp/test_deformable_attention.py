import torch
from torch import nn

from lanelab.geometry import backproject_to_lane, make_transform
from lanelab.models.sparselanestp.deformable_attention import DeformableCrossAttention

HEIGHT, WIDTH = 64, 96
STRIDES = (8, 16)
C, HEADS, LEVELS, POINTS = 4, 2, 2, 3
# Feature channel c at image pixel (u, v) is GRADIENT[c] . (u, v, 1): a constant gradient.
GRADIENT = torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, -0.25, 3.0], [-1.0, 2.0, -7.0]], dtype=torch.float64)


def camera() -> tuple[torch.Tensor, torch.Tensor]:
    """K (1, 3, 3) and T_lane_cam (1, 4, 4) of a level camera 1.5 m above the lane frame origin."""
    K = torch.tensor([[[50.0, 0.0, 48.0], [0.0, 50.0, 32.0], [0.0, 0.0, 1.0]]], dtype=torch.float64)
    # optical x -> lane x, optical y -> lane -z, optical z -> lane y
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=torch.float64)
    return K, make_transform(R, torch.tensor([0.0, 0.0, 1.5], dtype=torch.float64))[None]


def gradient_features() -> list[torch.Tensor]:
    """Per level (1, C, H / s, W / s): each feature pixel holds the linear map at its centre."""
    maps = []
    for stride in STRIDES:
        v, u = torch.meshgrid(
            (torch.arange(HEIGHT // stride, dtype=torch.float64) + 0.5) * stride,
            (torch.arange(WIDTH // stride, dtype=torch.float64) + 0.5) * stride,
            indexing="ij",
        )
        uv1 = torch.stack([u, v, torch.ones_like(u)])
        maps.append(torch.einsum("ck,khw->chw", GRADIENT, uv1)[None])
    return maps


def expected(uv: torch.Tensor) -> torch.Tensor:
    return torch.cat([uv, torch.ones_like(uv[..., :1])], -1) @ GRADIENT.T


def probe_attention() -> DeformableCrossAttention:
    """Identity value/output projections, zero offsets, uniform weights."""
    attention = DeformableCrossAttention(C, HEADS, LEVELS, POINTS).double()
    with torch.no_grad():
        for linear in (attention.value_proj, attention.output_proj):
            linear.weight.copy_(torch.eye(C))
            linear.bias.zero_()
        for parameter in (*attention.sampling_offsets.parameters(), *attention.attention_weights.parameters()):
            parameter.zero_()
    return attention


def lane_points(uv: list[list[float]], depth: list[float]) -> torch.Tensor:
    K, T = camera()
    uv_t = torch.tensor([uv], dtype=torch.float64)
    return backproject_to_lane(uv_t, torch.tensor([depth], dtype=torch.float64), K, T)


def run(attention: DeformableCrossAttention, points: torch.Tensor, queries: torch.Tensor | None = None) -> torch.Tensor:
    K, T = camera()
    if queries is None:
        queries = torch.randn(1, points.shape[1], C, dtype=torch.float64)
    return attention(queries, points, gradient_features(), K, T, (HEIGHT, WIDTH))


def test_zero_offsets_sample_the_projected_pixel():
    # Pixel centres of the stride-8 level, a point between them, at different depths.
    uv = [[60.0, 44.0], [12.0, 20.0], [37.3, 29.9]]
    out = run(probe_attention(), lane_points(uv, [10.0, 25.0, 4.0]))
    torch.testing.assert_close(out, expected(torch.tensor([uv], dtype=torch.float64)))


def test_offsets_are_in_pixels_of_each_level():
    attention = probe_attention()
    # Head 0 shifts by (+1, 0) level pixels, head 1 by (0, -0.5), on every level and point;
    # weights keep only level 1 (stride 16): a shift of 16 px and -8 px in the image.
    shift = torch.tensor([[1.0, 0.0], [0.0, -0.5]], dtype=torch.float64)
    level_logits = torch.tensor([-1e4, 0.0], dtype=torch.float64)
    with torch.no_grad():
        attention.sampling_offsets.bias.copy_(shift[:, None, None, :].expand(HEADS, LEVELS, POINTS, 2).flatten())
        attention.attention_weights.bias.copy_(level_logits[None, :, None].expand(HEADS, LEVELS, POINTS).flatten())
    uv = torch.tensor([[40.0, 30.0]], dtype=torch.float64)
    out = run(attention, lane_points(uv.tolist(), [8.0]))
    head_dim = C // HEADS  # channels 0, 1 belong to head 0, channels 2, 3 to head 1
    target_head0 = expected(uv + torch.tensor([16.0, 0.0], dtype=torch.float64))[:, :head_dim]
    target_head1 = expected(uv + torch.tensor([0.0, -8.0], dtype=torch.float64))[:, head_dim:]
    torch.testing.assert_close(out[0], torch.cat([target_head0, target_head1], -1))


def test_multi_scale_levels_are_averaged_by_the_weights():
    attention = probe_attention()
    # Level 0 sampled one level pixel (8 px) right, level 1 one level pixel (16 px) right.
    offsets = torch.tensor([[1.0, 0.0], [1.0, 0.0]], dtype=torch.float64)
    with torch.no_grad():
        attention.sampling_offsets.bias.copy_(offsets[None, :, None, :].expand(HEADS, LEVELS, POINTS, 2).flatten())
    uv = torch.tensor([[40.0, 30.0]], dtype=torch.float64)
    out = run(attention, lane_points(uv.tolist(), [8.0]))
    mean = (expected(uv + torch.tensor([8.0, 0.0], dtype=torch.float64)) + expected(uv + torch.tensor([16.0, 0.0], dtype=torch.float64))) / 2
    torch.testing.assert_close(out[0], mean)


def test_points_behind_the_camera_read_nothing_and_points_outside_read_the_border():
    attention = DeformableCrossAttention(C, HEADS, LEVELS, POINTS).double()
    nn.init.normal_(attention.sampling_offsets.weight)
    nn.init.normal_(attention.attention_weights.weight)
    # A visible point, the same point mirrored behind the camera, one on the camera plane
    # (projection at infinity), one left of the image and the border point it clamps to.
    visible = lane_points([[50.0, 40.0]], [10.0])
    behind = visible.clone()
    behind[..., 1] = -behind[..., 1]
    on_plane = torch.tensor([[[1.0, 0.0, 1.0]]], dtype=torch.float64)
    outside = lane_points([[-30.0, 40.0]], [10.0])
    border = lane_points([[0.0, 40.0]], [25.0])
    points = torch.cat([visible, behind, on_plane, outside, border], 1).requires_grad_(True)
    query = torch.randn(1, 1, C, dtype=torch.float64)
    queries = torch.cat([torch.randn(1, 3, C, dtype=torch.float64), query, query], 1).requires_grad_(True)
    out = run(attention, points, queries)
    torch.testing.assert_close(out[0, 1:3], attention.output_proj.bias.expand(2, C))  # an all-zero read
    assert not torch.allclose(out[0, 0], attention.output_proj.bias)
    assert not torch.allclose(out[0, 3], attention.output_proj.bias)
    torch.testing.assert_close(out[0, 3], out[0, 4])
    out.sum().backward()
    assert torch.isfinite(queries.grad).all() and torch.isfinite(points.grad).all()


def test_batch_and_queries_are_independent():
    attention = DeformableCrossAttention(C, HEADS, LEVELS, POINTS).double()
    nn.init.normal_(attention.sampling_offsets.weight, std=0.3)
    nn.init.normal_(attention.attention_weights.weight)
    K, T = camera()
    points = lane_points([[50.0, 40.0], [20.0, 50.0], [70.0, 10.0]], [10.0, 6.0, 30.0])
    queries = torch.randn(1, 3, C, dtype=torch.float64)
    features = [f.expand(2, -1, -1, -1) * torch.tensor([1.0, -2.0], dtype=torch.float64)[:, None, None, None] for f in gradient_features()]
    together = attention(queries.expand(2, -1, -1), points.expand(2, -1, -1), features, K.expand(2, -1, -1), T.expand(2, -1, -1), (HEIGHT, WIDTH))
    for b in range(2):
        for q in range(3):
            alone = attention(queries[:, q : q + 1], points[:, q : q + 1], [f[b : b + 1] for f in features], K, T, (HEIGHT, WIDTH))
            torch.testing.assert_close(together[b, q], alone[0, 0])


def test_content_weights_pick_the_sample_that_answers_the_query():
    """One of the samples around a point reads a bright marking. With query-only weights the read
    is linear in the features (a fixed blend: it cannot tell which sample saw the marking); with
    content weights the sample whose value matches the query's probe takes the weight."""
    torch.manual_seed(0)
    K, T = camera()
    point = lane_points([[44.0, 36.0]], [10.0])
    features = [torch.zeros(1, C, HEIGHT // s, WIDTH // s, dtype=torch.float64) for s in STRIDES]
    marking = [f.clone() for f in features]
    marking[0][0, :, 4, 6] = 5.0  # the stride-8 cell under the point: cell (4, 5); one to its right
    query = torch.randn(1, 1, C, dtype=torch.float64)

    def read(attention: DeformableCrossAttention, maps: list[torch.Tensor]) -> torch.Tensor:
        return attention(query, point, maps, K, T, (HEIGHT, WIDTH))[0, 0]

    plain = DeformableCrossAttention(C, HEADS, LEVELS, POINTS).double()
    torch.testing.assert_close(read(plain, [2 * m for m in marking]) - read(plain, features),
                               2 * (read(plain, marking) - read(plain, features)))  # fmt: skip
    content = DeformableCrossAttention(C, HEADS, LEVELS, POINTS, content_weights=True).double()
    content.load_state_dict(plain.state_dict(), strict=False)  # the same projections, plus the probe
    with torch.no_grad():  # the probe looks for the marking's value
        content.content_proj.weight.zero_()
        content.content_proj.bias.copy_(content.value_proj(torch.full((C,), 5.0, dtype=torch.float64)))
    torch.testing.assert_close(read(content, features), read(plain, features))  # nothing to prefer
    # Query-only weights give the marking's sample 1/6 of a head's weight (3 points x 2 levels,
    # uniform at initialisation); content weights give it nearly all.
    plain_gain = (read(plain, marking) - read(plain, features)).norm()
    assert (read(content, marking) - read(content, features)).norm() > 4 * plain_gain
