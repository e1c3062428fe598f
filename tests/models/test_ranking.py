import pytest
import torch

from lanelab.models.ranking import largest, smallest


def test_equal_values_are_taken_lower_index_first() -> None:
    values = torch.tensor([[3.0, 1.0, 2.0, 1.0, 2.0, 0.5]])
    assert smallest(values, 4)[1].tolist() == [[5, 1, 3, 2]]
    assert largest(values, 3)[1].tolist() == [[0, 2, 4]]
    assert smallest(values, 4)[0].tolist() == [[0.5, 1.0, 1.0, 2.0]]


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16])
def test_distinct_values_are_ranked_as_topk_ranks_them(dtype: torch.dtype) -> None:
    values = torch.randn(4, 7, 50, generator=torch.Generator().manual_seed(0)).to(dtype)
    # Values compared, not indices: bf16 may round two of them to the same value.
    for k in (1, 5, 50):
        got, index = smallest(values, k)
        assert torch.equal(got, values.topk(k, largest=False).values) and torch.equal(values.gather(-1, index), got)
        assert torch.equal(largest(values, k)[0], values.topk(k).values)
    with_inf = values.float().masked_fill(torch.rand(values.shape, generator=torch.Generator().manual_seed(1)) < 0.5,
                                          torch.inf)  # fmt: skip
    assert torch.equal(smallest(with_inf, 10)[0], with_inf.topk(10, largest=False).values)
