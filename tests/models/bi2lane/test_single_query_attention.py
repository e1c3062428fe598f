"""single_query_attention computes nn.MultiheadAttention's result, gradients included, without projecting the keys."""

import pytest
import torch
from torch import nn

from lanelab.models.bi2lane.single_query_attention import single_query_attention


def _inputs(batch: int = 64, keys: int = 5, channels: int = 16, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    query = torch.randn(batch, 1, channels, generator=generator)
    key = torch.randn(batch, keys, channels, generator=generator)
    value = torch.randn(batch, keys, channels, generator=generator)
    mask = torch.rand(batch, keys, generator=generator) < 0.4
    mask[:, 0] = False  # every sample keeps a key (an all-masked softmax is undefined in both)
    return query, key, value, mask


@pytest.mark.parametrize("heads", [1, 2, 4])
def test_equals_multihead_attention_with_a_padding_mask(heads: int) -> None:
    torch.manual_seed(heads)
    attention = nn.MultiheadAttention(16, heads, batch_first=True).eval()
    nn.init.normal_(attention.in_proj_bias)  # biases of zero would hide a wrong bias term
    nn.init.normal_(attention.out_proj.bias)
    query, key, value, mask = _inputs()
    expected, _ = attention(query, key, value, key_padding_mask=mask, need_weights=False)
    got = single_query_attention(attention, query, key, value, mask)
    assert torch.allclose(got, expected, atol=1e-5)
    # The mask matters: without it the result differs.
    assert not torch.allclose(single_query_attention(attention, query, key, value), expected, atol=1e-3)


def test_gradients_equal_multihead_attentions() -> None:
    torch.manual_seed(0)
    attention = nn.MultiheadAttention(16, 2, batch_first=True)
    nn.init.normal_(attention.in_proj_bias)
    query, key, value, mask = _inputs()
    grads = []
    for run in (lambda q, k, v: attention(q, k, v, key_padding_mask=mask, need_weights=False)[0],
                lambda q, k, v: single_query_attention(attention, q, k, v, mask)):  # fmt: skip
        attention.zero_grad()
        inputs = [tensor.clone().requires_grad_() for tensor in (query, key, value)]
        (run(*inputs) ** 2).sum().backward()
        grads.append([tensor.grad for tensor in inputs] + [p.grad.clone() for p in attention.parameters()])
    for ours, reference in zip(*grads):
        assert torch.allclose(ours, reference, atol=1e-4)


def test_attention_dropout_drops_weights_as_multihead_attention_does() -> None:
    """In training the attention weights are dropped; with every weight dropped only the biases remain."""
    attention = nn.MultiheadAttention(16, 2, dropout=1.0, batch_first=True).train()
    query, key, value, _ = _inputs()
    got = single_query_attention(attention, query, key, value)
    assert torch.allclose(got, attention.out_proj.bias.expand_as(got))


def test_refuses_a_module_without_the_default_projections() -> None:
    attention = nn.MultiheadAttention(16, 2, bias=False, batch_first=True)
    with pytest.raises(ValueError, match="default projections"):
        single_query_attention(attention, *_inputs()[:3])


def test_key_offset_and_leading_sample_dimensions() -> None:
    """Keys (..., S, C) with several sample dimensions and a per-slot offset (an embedding) equal
    nn.MultiheadAttention over the flattened samples with the offset added to the keys."""
    torch.manual_seed(1)
    attention = nn.MultiheadAttention(16, 2, batch_first=True).eval()
    query, key, value, mask = _inputs(batch=24)
    offset = torch.randn(5, 16)
    shape = (2, 3, 4)
    got = single_query_attention(attention, query.view(*shape, 1, 16), key.view(*shape, 5, 16),
                                 value.view(*shape, 5, 16), mask.view(*shape, 5), key_offset=offset)  # fmt: skip
    expected, _ = attention(query, key + offset, value, key_padding_mask=mask, need_weights=False)
    assert torch.allclose(got.reshape(24, 1, 16), expected, atol=1e-5)
