import dataclasses
import math

import pytest
import torch

from lanelab.geometry import sampling_matrix
from lanelab.models.sparselanestp.memory_queue import MemoryState
from lanelab.models.sparselanestp.spatio_temporal_attention import SpatioTemporalAttention
from lanelab.models.sparselanestp.sta_masks import curve_tangents, density, parallel_neighbours, sta_masks, temporal_neighbours

Y = torch.linspace(3.0, 103.0, 20, dtype=torch.float64)


def lanes(batch: int, lines: int, y: torch.Tensor, seed: int = 0, shift: float = 0.0) -> torch.Tensor:
    """(batch, lines, len(y), 4) roughly parallel, gently curving lanes 3.5 m apart, seen from
    ``shift`` metres further back (a static lane's points move back as the ego drives on)."""
    g = torch.Generator().manual_seed(seed)
    jitter = 0.2 * torch.rand(batch, lines, generator=g, dtype=y.dtype)
    offset = 3.5 * torch.arange(lines, dtype=y.dtype) - 1.75 * lines + jitter
    bend = 1e-4 * torch.randn(batch, 1, 1, generator=g, dtype=y.dtype)
    x = offset[..., None] + bend * (y + shift) ** 2
    return torch.stack([x, (y - shift).expand_as(x), 0.01 * y.expand_as(x), torch.ones_like(x)], dim=-1)


def random_memory(batch: int, lines: int, points: int, dim: int, dtype=torch.float64, seed: int = 0) -> MemoryState:
    g = torch.Generator().manual_seed(seed)
    K = lines * points
    xyz = 10 * torch.randn(batch, K, 3, generator=g, dtype=dtype)
    return MemoryState(
        embeddings=torch.randn(batch, K, dim, generator=g, dtype=dtype),
        points=torch.cat([xyz, torch.rand(batch, K, 1, generator=g, dtype=dtype)], -1),
        valid=torch.rand(batch, K, generator=g) > 0.2,
        age=torch.ones(batch, K, dtype=torch.long),
    )


def test_density_of_the_paper_configuration():
    """N = 40, M = 20, T = 3, M_TCA = 10 (supplementary C.2: ~10 % active relations). The paper
    gives no N_mem; 5 lines per frame (the most frequent number of markings per frame of its
    dataset, Fig. 12a) reproduces the ~10 %."""
    B, N, M, T, N_mem, M_tca = 1, 40, 20, 3, 5, 10
    points = lanes(B, N, Y)
    memory = torch.cat([lanes(B, N_mem, Y, seed=k, shift=1.5 * k) for k in range(1, T + 1)], dim=1)
    masks = sta_masks(points, memory.flatten(1, 2), None, None, 2, M_tca)
    per_query = {"sla": M, "pna": 2 * (N - 1), "tca": M_tca}
    for name, count in per_query.items():
        assert (masks[name].sum(-1) == count).all(), name
    union = torch.stack(list(masks.values())).any(0)
    assert (union.sum(-1) == sum(per_query.values())).all()  # 108 keys per query, no overlaps

    keys = N * M + T * N_mem * M
    fractions = density(masks)
    assert fractions["all"] == pytest.approx(108 / keys)  # 9.82 %
    assert fractions["all"] == pytest.approx(0.10, abs=0.005)
    print(f"\nSTA density N={N} M={M} T={T} N_mem={N_mem} M_TCA={M_tca}: "
          + ", ".join(f"{k} {100 * v:.2f}%" for k, v in fractions.items())
          + f"; without memory (SLA + PNA over N·M keys) {100 * (M + 2 * (N - 1)) / (N * M):.2f}%")  # fmt: skip


def test_sla_is_block_diagonal_per_line_and_skips_padded_lines():
    B, N, M = 2, 4, 5
    points = lanes(B, N, Y[:M])
    line_mask = torch.tensor([[True, True, True, True], [True, False, True, False]])
    sla = sta_masks(points, torch.zeros(B, 6, 4, dtype=torch.float64), None, line_mask)["sla"]
    block = torch.block_diag(*[torch.ones(M, M, dtype=torch.bool)] * N)
    assert torch.equal(sla[0, :, : N * M], block)
    assert not sla[..., N * M :].any()  # no memory column
    key_valid = line_mask.repeat_interleave(M, dim=1)
    assert torch.equal(sla[1, :, : N * M], block & key_valid[1][None, :])


def test_pna_picks_two_points_on_every_other_line():
    B, N, M = 2, 6, 7
    g = torch.Generator().manual_seed(1)
    points = torch.randn(B, N, M, 4, generator=g, dtype=torch.float64) * 10
    line_mask = torch.ones(B, N, dtype=torch.bool)
    line_mask[1, 2] = False
    pna = sta_masks(points, None, None, line_mask)["pna"]
    per_line = pna.view(B, N * M, N, M).sum(-1)  # keys of each query on each line
    own = torch.eye(N, dtype=torch.bool).repeat_interleave(M, dim=0)  # (N·M, N): the query's own line
    expected = torch.where(own, 0, 2)[None].repeat(B, 1, 1)
    expected[1, :, 2] = 0  # padded line: never a key
    assert torch.equal(per_line, expected)


def test_pna_neighbours_are_the_orthogonally_nearest_points():
    """Straight parallel lanes at 45° to y on the model's common y grid (5 m steps), 6 m
    apart along x. The normal plane of (i, m) cuts line i + 1 at y_m - 3 and line i + 2 at
    y_m - 6: the neighbours are the points around those places, not those at the same index."""
    y = torch.arange(0.0, 100.0, 5.0, dtype=torch.float64)
    x = y + 6.0 * torch.arange(3, dtype=torch.float64)[:, None]  # x = y + 6 i
    points = torch.stack([x, y.expand_as(x), torch.zeros_like(x)], -1)[None]  # (1, 3, 20, 3)
    picks = parallel_neighbours(points)  # (1, N, M, N, 2)
    m = 10
    assert set(picks[0, 0, m, 1].tolist()) == {m - 1, m}  # offsets -4 m and +6 m from the plane
    assert set(picks[0, 0, m, 2].tolist()) == {m - 2, m - 1}  # +2 m and -8 m
    assert set(picks[0, 2, m, 0].tolist()) == {m + 1, m + 2}  # the other way round
    assert set(picks[0, 0, 0, 1].tolist()) == {0, 1}  # at the start of the lines: the two nearest


def test_tca_picks_the_nearest_valid_memory_points():
    B, N, M, K, m_tca = 2, 3, 4, 30, 5
    g = torch.Generator().manual_seed(2)
    points = torch.randn(B, N, M, 4, generator=g, dtype=torch.float64)
    memory = torch.randn(B, K, 4, generator=g, dtype=torch.float64)
    valid = torch.rand(B, K, generator=g) > 0.3
    tca = sta_masks(points, memory, valid, None, 2, m_tca)["tca"][..., N * M :]
    assert (tca.sum(-1) == m_tca).all()
    distance = torch.cdist(points[..., :3].flatten(1, 2), memory[..., :3]).masked_fill(~valid[:, None], math.inf)
    nearest = distance.argsort(-1)[..., :m_tca]
    assert torch.equal(tca, torch.zeros_like(tca).scatter_(-1, nearest, True))

    few = torch.zeros(B, K, dtype=torch.bool)
    few[:, :3] = True  # fewer valid tokens than m_tca: all of them, nothing else
    tca = sta_masks(points, memory, few, None, 2, m_tca)["tca"][..., N * M :]
    assert torch.equal(tca, few[:, None].expand_as(tca))


def test_tca_neighbours_of_bf16_points_are_found_in_float32():
    # bf16 spaces values 0.5 m apart at 100 m, and cdist has no bf16 kernel (CPU or CUDA): the
    # distances are taken in float32, so bf16 points pick the neighbours their float32 values pick.
    g = torch.Generator().manual_seed(3)
    scale = torch.tensor([10.0, 100.0, 2.0])
    points = (torch.rand(1, 4, 6, 3, generator=g) * scale).bfloat16()
    memory = (torch.rand(1, 40, 3, generator=g) * scale).bfloat16()
    valid = torch.ones(1, 40, dtype=torch.bool)
    index, found = temporal_neighbours(points, memory, valid, 5)
    expected, _ = temporal_neighbours(points.float(), memory.float(), valid, 5)
    assert found.all() and torch.equal(index, expected)


def attention_pair(dtype: torch.dtype, **flags) -> tuple[SpatioTemporalAttention, SpatioTemporalAttention]:
    torch.manual_seed(0)
    sparse = SpatioTemporalAttention(16, 4, impl="sparse", **flags).to(dtype)
    dense = SpatioTemporalAttention(16, 4, impl="dense", **flags).to(dtype)
    dense.load_state_dict(sparse.state_dict())
    return sparse, dense


def run(layer, inputs: dict) -> tuple[torch.Tensor, dict]:
    """Output and gradients of every input and parameter for a fixed random upstream gradient."""
    layer.zero_grad(set_to_none=True)
    # Points choose the neighbours (discrete), so no gradient reaches them.
    inputs = {
        k: v.clone().requires_grad_(k != "points") if isinstance(v, torch.Tensor) and v.is_floating_point() else v
        for k, v in inputs.items()
    }
    memory = inputs.pop("memory")
    if memory is not None:
        memory = MemoryState(memory.embeddings.clone().requires_grad_(), memory.points, memory.valid, memory.age)
    out = layer(
        inputs["queries"], inputs["query_pos"], inputs["points"], memory, inputs["memory_pos"], inputs["line_mask"]
    )
    upstream = torch.randn(out.shape, generator=torch.Generator().manual_seed(3), dtype=out.dtype)
    (out * upstream).sum().backward()
    grads = {name: p.grad for name, p in layer.named_parameters()}
    grads.update({k: v.grad for k, v in inputs.items() if isinstance(v, torch.Tensor) and v.requires_grad})
    if memory is not None:
        grads["memory.embeddings"] = memory.embeddings.grad
    return out, grads


def sta_inputs(dtype, memory: str = "some", padded: bool = True) -> dict:
    B, N, M, C = 2, 5, 6, 16
    g = torch.Generator().manual_seed(4)
    points = lanes(B, N, Y[::3][:M]).to(dtype)
    points[1, ..., 0] = 10 * torch.randn(N, M, generator=g, dtype=torch.float64)  # an untrained model's mess
    line_mask = torch.ones(B, N, dtype=torch.bool)
    if padded:
        line_mask[1, 3:] = False
    state = None if memory == "none" else random_memory(B, 4, M, C, dtype)
    if memory == "invalid":
        state.valid[:] = False
    return {
        "queries": torch.randn(B, N, M, C, generator=g, dtype=torch.float64).to(dtype),
        "query_pos": torch.randn(B, N, M, C, generator=g, dtype=torch.float64).to(dtype),
        "points": points,
        "memory": state,
        "memory_pos": None if state is None else torch.randn(B, 4 * M, C, generator=g, dtype=torch.float64).to(dtype),
        "line_mask": line_mask,
    }


RELATIONS = [
    {"use_sla": True, "use_pna": True, "use_tca": True},
    {"use_sla": True, "use_pna": False, "use_tca": False},
    {"use_sla": False, "use_pna": True, "use_tca": False},
    {"use_sla": True, "use_pna": True, "use_tca": False},
    {"use_sla": False, "use_pna": False, "use_tca": True},
]


@pytest.mark.parametrize("dtype, tolerance", [(torch.float64, 1e-10), (torch.float32, 2e-5)])
@pytest.mark.parametrize("flags", RELATIONS)
def test_sparse_equals_dense_reference(dtype, tolerance, flags):
    sparse, dense = attention_pair(dtype, **flags)
    for memory in ("some", "none", "invalid"):
        inputs = sta_inputs(dtype, memory)
        out_sparse, grads_sparse = run(sparse, inputs)
        out_dense, grads_dense = run(dense, inputs)
        assert out_sparse.isfinite().all()
        torch.testing.assert_close(out_sparse, out_dense, atol=tolerance, rtol=tolerance)
        assert grads_sparse.keys() == grads_dense.keys()
        for name, grad in grads_sparse.items():
            if grad is None:  # inputs that do not matter here (memory without TCA, ...)
                assert grads_dense[name] is None, name
                continue
            assert grad.isfinite().all(), name
            torch.testing.assert_close(grad, grads_dense[name], atol=tolerance, rtol=tolerance, msg=name)


def test_every_parameter_gets_gradient_and_keyless_queries_are_zero():
    sparse, _ = attention_pair(torch.float64)
    _, grads = run(sparse, sta_inputs(torch.float64))
    assert all(grads[name].abs().sum() > 0 for name, _ in sparse.named_parameters())

    only_memory, _ = attention_pair(torch.float64, use_sla=False, use_pna=False, use_tca=True)
    inputs = sta_inputs(torch.float64, memory="invalid")  # TCA only, no valid memory: no key at all
    out, grads = run(only_memory, inputs)
    bias = only_memory.out_proj.bias
    torch.testing.assert_close(out, bias.expand_as(out))  # zero attention, then the projection
    assert all(g.isfinite().all() for g in grads.values())


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(
    not torch.cuda.is_available(), reason="needs a CUDA device (run on a device machine)"))])  # fmt: skip
def test_auto_runs_the_sparse_path_on_a_cpu_and_the_fused_dense_one_on_a_gpu(device, monkeypatch):
    """Both compute the same (test_sparse_equals_dense_reference); auto picks the faster where it runs."""
    ran = []
    for path in ("_sparse", "_dense"):
        original = getattr(SpatioTemporalAttention, path)
        monkeypatch.setattr(SpatioTemporalAttention, path,
                            lambda self, *args, _o=original, _p=path: ran.append(_p) or _o(self, *args))  # fmt: skip
    layer = SpatioTemporalAttention(16, 4, impl="auto").double().to(device)
    inputs = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in sta_inputs(torch.float64).items()}
    memory = MemoryState(*(t.to(device) for t in dataclasses.astuple(inputs["memory"])))
    with torch.no_grad():
        layer(inputs["queries"], inputs["query_pos"], inputs["points"], memory, inputs["memory_pos"],
              inputs["line_mask"])  # fmt: skip
    assert ran == (["_sparse"] if device == "cpu" else ["_dense"])


def test_global_mode_is_full_self_attention():
    torch.manual_seed(0)
    layer = SpatioTemporalAttention(16, 4, impl="global").double()
    inputs = sta_inputs(torch.float64, padded=False)
    q, pos = inputs["queries"], inputs["query_pos"]
    out = layer(q, pos, inputs["points"], inputs["memory"], inputs["memory_pos"])
    # Reference: torch's multi-head attention with the same weights, keys = queries + pos.
    mha = torch.nn.MultiheadAttention(16, 4, batch_first=True).double()
    with torch.no_grad():
        mha.in_proj_weight.copy_(torch.cat([layer.q_proj.weight, layer.k_proj.weight, layer.v_proj.weight]))
        mha.in_proj_bias.copy_(torch.cat([layer.q_proj.bias, layer.k_proj.bias, layer.v_proj.bias]))
        mha.out_proj.load_state_dict(layer.out_proj.state_dict())
    tokens, tokens_pos = q.flatten(1, 2), (q + pos).flatten(1, 2)
    expected = mha(tokens_pos, tokens_pos, tokens, need_weights=False)[0].view_as(out)
    torch.testing.assert_close(out, expected)


def test_rejects_a_layer_without_relations():
    with pytest.raises(ValueError):
        SpatioTemporalAttention(16, 4, use_sla=False, use_pna=False, use_tca=False)
    with pytest.raises(ValueError):
        SpatioTemporalAttention(16, 4, impl="flash")


def test_positional_encoding_of_points():
    from lanelab.models.sparselanestp.positional_encoding import PointPositionalEncoding

    torch.manual_seed(0)
    encoding = PointPositionalEncoding(32)
    points = torch.rand(2, 5, 6, 4)  # normalised (x, y, z, v)
    assert encoding(points).shape == (2, 5, 6, 32)
    assert encoding(torch.zeros(2, 0, 4)).shape == (2, 0, 32)  # an empty memory
    moved = points.clone()
    moved[..., 3] = 1 - moved[..., 3]  # only the visibility changes
    assert not torch.allclose(encoding(points), encoding(moved))


@pytest.mark.parametrize("num_points", [2, 3, 10])
def test_curve_tangents_are_the_catmull_rom_derivative_at_the_control_points(num_points):
    points = torch.randn(2, 3, num_points, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    knots = torch.linspace(0.0, 1.0, num_points, dtype=torch.float64)
    derivative = sampling_matrix(num_points, knots, derivative=1) @ points[..., :3]
    torch.testing.assert_close(curve_tangents(points), derivative / derivative.norm(dim=-1, keepdim=True))
