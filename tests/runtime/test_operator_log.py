import torch

from lanelab.runtime.operator_log import OperatorLog


def test_it_counts_what_computes_a_tensor_and_not_views():
    x = torch.randn(4, 3)
    with OperatorLog() as log:
        y = x.t().reshape(-1)  # a view, then a copy (the transpose is not contiguous)
        y = y.view(3, 4)[:, :2]  # views
        y.relu_()  # in place: it computes
        torch.empty(3), x.new_empty(2), torch.empty_like(x)  # allocations launch nothing
    assert log.kernels() == 2
    assert log.bytes_written() == 12 * 4 + 6 * 4  # the copy's 12 floats, relu_'s 6 (its view's)
    assert [str(op) for op in log.operators if "relu" in str(op)] == ["aten.relu_.default"]


def test_it_shows_what_moves_data_between_host_and_device():
    x = torch.randn(3)
    with OperatorLog() as log:
        x + torch.tensor([1.0, 2.0, 3.0])  # a tensor made from host data
        float(x.sum())  # a value read back
    assert log.host_transfers() == ["aten.lift_fresh.default", "aten._local_scalar_dense.default"]


CONSTANT = torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)  # host memory, on a GPU


def test_given_its_sources_it_shows_copies_of_tensors_from_elsewhere_and_boolean_masks():
    x = torch.randn(3)
    with OperatorLog(sources=[x]) as log:
        y = x.double() * 2  # a copy of a source
        y.float().exp()  # of a tensor made inside
        x + CONSTANT.float()  # of a constant from elsewhere: host data on a GPU
        x[x > 0]  # a boolean mask: the result's size is read back
    assert log.host_transfers() == [
        "aten._to_copy.default of a tensor from elsewhere",
        "aten.index.Tensor by a boolean mask",
    ]
