import torch

from lanelab.models.ranking import largest, smallest


def test_values_in_the_same_step_are_taken_lower_index_first() -> None:
    values = torch.tensor([[3.0, 1.0, 2.0, 1.0004, 2.0, 0.5]])
    assert smallest(values, 4, 1e-3)[1].tolist() == [[5, 1, 3, 2]]  # 1.0 and 1.0004 share a millimetre
    assert smallest(values, 4, 1e-5)[1].tolist() == [[5, 1, 3, 2]]
    assert smallest(torch.tensor([[1.0004, 1.0]]), 1, 1e-3)[1].tolist() == [[0]]
    assert smallest(torch.tensor([[1.0004, 1.0]]), 1, 1e-5)[1].tolist() == [[1]]
    assert largest(values, 3, 1e-3)[1].tolist() == [[0, 2, 4]]
    assert smallest(values, 2, 1e-3)[0].tolist() == [[0.5, 1.0]]  # the values themselves, not rounded


def test_noise_below_the_resolution_does_not_change_the_choice() -> None:
    generator = torch.Generator().manual_seed(0)
    values = torch.randint(0, 50, (8, 40), generator=generator).float() * 0.01  # many exact ties
    noisy = values + 1e-7 * torch.randn(values.shape, generator=generator)
    assert torch.equal(smallest(values, 10, 1e-3)[1], smallest(noisy, 10, 1e-3)[1])
    assert torch.equal(largest(values, 10, 1e-3)[1], largest(noisy, 10, 1e-3)[1])


def test_distinct_values_are_ranked_as_topk_ranks_them() -> None:
    values = torch.randn(4, 7, 50, generator=torch.Generator().manual_seed(0))
    values = values.masked_fill(torch.rand(values.shape, generator=torch.Generator().manual_seed(1)) < 0.3, torch.inf)
    for k in (1, 5, 30):
        got, index = smallest(values, k, 1e-9)
        assert torch.equal(got, values.topk(k, largest=False).values) and torch.equal(values.gather(-1, index), got)
    finite = values.nan_to_num(posinf=0.0)
    assert torch.equal(largest(finite, 5, 1e-9)[0], finite.topk(5).values)
