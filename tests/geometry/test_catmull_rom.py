import pytest
import torch

from lanelab.geometry import (
    CR_MATRIX,
    control_point_y,
    cr_matrix,
    curve_arguments,
    evaluate,
    fit_control_points,
    sampling_matrix,
)

# Eq. 15 of the SparseLaneSTP supplementary, written out again independently of the module.
PAPER_M_CR = 0.5 * torch.tensor(
    [[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]], dtype=torch.float64
)
Y_START, Y_END = 3.0, 103.0


def curvy_control_points(num: int = 10, dtype=torch.float64) -> torch.Tensor:
    """(num, 3) control points x, z, visibility of a curving, climbing lane at control_point_y."""
    y = control_point_y(num, Y_START, Y_END, dtype=torch.float64)
    x = 0.5e-3 * (y - Y_START) ** 2 + 0.2 * torch.sin(y / 15)
    z = 0.01 * y + 0.3 * torch.cos(y / 30)
    visibility = torch.linspace(1.0, 0.0, num, dtype=torch.float64)
    return torch.stack([x, z, visibility], -1).to(dtype)


def test_cr_matrix_is_the_papers():
    assert CR_MATRIX.dtype == torch.float64
    assert torch.equal(CR_MATRIX, PAPER_M_CR)
    assert cr_matrix(torch.float32).dtype == torch.float32


@pytest.mark.parametrize("num", [2, 3, 4, 7])
def test_curve_passes_through_control_points(num):
    P = torch.randn(num, 2, dtype=torch.float64)
    knots = torch.arange(num, dtype=torch.float64) / (num - 1)
    torch.testing.assert_close(evaluate(P, knots), P)


def test_interior_rows_are_the_papers_basis():
    M = 7
    s = torch.linspace(2 / 6 + 1e-9, 3 / 6 - 1e-9, 13, dtype=torch.float64)  # segment k = 2
    t = s * 6 - 2
    local = torch.stack([t**3, t**2, t, torch.ones_like(t)], -1) @ PAPER_M_CR
    expected = torch.zeros(13, M, dtype=torch.float64)
    expected[:, 1:5] = local  # p_{k-1} .. p_{k+2}
    torch.testing.assert_close(sampling_matrix(M, s), expected)


def test_end_segments_use_linearly_extrapolated_phantoms():
    M = 5
    s = torch.tensor([0.1, 0.9], dtype=torch.float64)
    t = torch.tensor([0.4, 0.6], dtype=torch.float64)  # local arguments in the first and last segments
    w = torch.stack([t**3, t**2, t, torch.ones_like(t)], -1) @ PAPER_M_CR
    # p_{-1} = 2 p_0 - p_1 and p_M = 2 p_{M-1} - p_{M-2}
    first = torch.tensor([w[0, 1] + 2 * w[0, 0], w[0, 2] - w[0, 0], w[0, 3], 0, 0], dtype=torch.float64)
    last = torch.tensor([0, 0, w[1, 0], w[1, 1] - w[1, 3], w[1, 2] + 2 * w[1, 3]], dtype=torch.float64)
    torch.testing.assert_close(sampling_matrix(M, s), torch.stack([first, last]))


@pytest.mark.parametrize("num", [2, 3, 5, 12])
def test_partition_of_unity_and_straight_lines(num):
    s = torch.linspace(0, 1, 101, dtype=torch.float64)
    A = sampling_matrix(num, s)
    torch.testing.assert_close(A.sum(-1), torch.ones(101, dtype=torch.float64))
    # uniformly spaced control points on a line give the line itself, end segments included
    start = torch.tensor([1.0, -2.0, 0.5], dtype=torch.float64)
    direction = torch.tensor([3.0, 1.0, -1.0], dtype=torch.float64)
    knots = torch.linspace(0, 1, num, dtype=torch.float64)
    P = start + knots[:, None] * direction
    torch.testing.assert_close(A @ P, start + s[:, None] * direction)
    # derivatives of a line: constant slope, no curvature
    torch.testing.assert_close(evaluate(P, s, derivative=1), direction.expand(101, 3))
    torch.testing.assert_close(evaluate(P, s, derivative=2), torch.zeros(101, 3, dtype=torch.float64))


@pytest.mark.parametrize("derivative", [1, 2])
def test_derivatives_match_finite_differences(derivative):
    M, h = 6, 1e-5
    P = torch.randn(M, 2, dtype=torch.float64)
    # away from knots, where the second derivative jumps
    s = torch.tensor([0.05, 0.13, 0.31, 0.5, 0.77, 0.95], dtype=torch.float64)
    lower = evaluate(P, s - h, derivative - 1)
    upper = evaluate(P, s + h, derivative - 1)
    torch.testing.assert_close(evaluate(P, s, derivative), (upper - lower) / (2 * h), atol=1e-6, rtol=1e-6)


def test_c1_continuity_across_knots():
    M, eps = 6, 1e-9
    P = torch.randn(M, 3, dtype=torch.float64)
    knots = torch.arange(1, M - 1, dtype=torch.float64) / (M - 1)
    for derivative in (0, 1):
        torch.testing.assert_close(
            evaluate(P, knots - eps, derivative), evaluate(P, knots + eps, derivative), atol=1e-6, rtol=0
        )


def test_s_equal_one_is_the_end_of_the_last_segment():
    P = torch.randn(4, 2, dtype=torch.float64)
    s = torch.tensor([1.0 - 1e-12, 1.0, 1.0 + 5e-7], dtype=torch.float64)  # the last one is clamped
    out = evaluate(P, s)
    torch.testing.assert_close(out, P[-1].expand(3, 2))
    torch.testing.assert_close(evaluate(P, s, 1)[0], evaluate(P, s, 1)[1])


def test_invalid_arguments_raise():
    s = torch.linspace(0, 1, 5)
    with pytest.raises(ValueError, match="at least 2 control points"):
        sampling_matrix(1, s)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        sampling_matrix(4, torch.tensor([0.5, 1.01]))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        sampling_matrix(4, torch.tensor([-1e-3]))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        sampling_matrix(4, torch.tensor([float("nan")]))
    with pytest.raises(ValueError, match="derivative"):
        sampling_matrix(4, s, derivative=3)


def test_batch_of_curves_is_one_matmul():
    M = 8
    P = torch.randn(2, 5, M, 4, dtype=torch.float64)
    s = torch.rand(33, dtype=torch.float64)
    batched = sampling_matrix(M, s) @ P
    assert batched.shape == (2, 5, 33, 4)
    for i in range(2):
        for j in range(5):
            torch.testing.assert_close(batched[i, j], evaluate(P[i, j], s))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_dtypes_are_kept(dtype):
    s = torch.linspace(0, 1, 21, dtype=dtype)
    for derivative in (0, 1, 2):
        assert sampling_matrix(6, s, derivative).dtype == dtype
    P = curvy_control_points(6, dtype)
    out = evaluate(P, torch.linspace(0, 1, 21, dtype=torch.float64))
    assert out.dtype == dtype
    torch.testing.assert_close(out, evaluate(P.double(), s.double()).to(dtype))
    assert control_point_y(6, Y_START, Y_END, dtype=dtype).dtype == dtype


def test_curve_arguments_and_control_point_y():
    y = control_point_y(5, Y_START, Y_END, dtype=torch.float64)
    torch.testing.assert_close(y, torch.tensor([3.0, 28.0, 53.0, 78.0, 103.0], dtype=torch.float64))
    torch.testing.assert_close(curve_arguments(y, Y_START, Y_END), torch.linspace(0, 1, 5, dtype=torch.float64))


def dense_samples(P: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    return evaluate(P, curve_arguments(y, Y_START, Y_END))


def test_fit_recovers_exact_control_points():
    M = 10
    P = curvy_control_points(M)
    y = torch.linspace(Y_START, Y_END, 200, dtype=torch.float64)
    values = dense_samples(P, y)
    torch.testing.assert_close(fit_control_points(y, values, M, Y_START, Y_END, smoothness=0.0), P, atol=1e-9, rtol=0)
    # The default smoothing biases a curved lane slightly (second differences of ~0.1 m here).
    torch.testing.assert_close(fit_control_points(y, values, M, Y_START, Y_END), P, atol=1e-4, rtol=0)
    torch.testing.assert_close(
        fit_control_points(y, values, M, Y_START, Y_END, smoothness=1e-6), P, atol=1e-7, rtol=0
    )


def test_fit_batched_lanes_with_partial_coverage():
    M, num_samples = 10, 150
    P = torch.stack([curvy_control_points(M), -curvy_control_points(M), 0.5 * curvy_control_points(M)])
    ranges = [(Y_START, Y_END), (20.0, 60.0), (50.0, Y_END)]
    y = torch.stack([torch.linspace(a, b, num_samples, dtype=torch.float64) for a, b in ranges])
    values = torch.stack([dense_samples(P[i], y[i]) for i in range(3)])
    fitted = fit_control_points(y, values, M, Y_START, Y_END)
    assert fitted.shape == (3, M, 3) and torch.isfinite(fitted).all()
    refit = torch.stack([dense_samples(fitted[i], y[i]) for i in range(3)])
    # the observed part matches, to the small bias of the default smoothing
    torch.testing.assert_close(refit, values, atol=2e-3, rtol=0)
    # control points nobody observed continue the lane in a straight line
    unobserved = fitted[1, -3:]  # y = 69.7 .. 103 for a lane observed on 20 .. 60
    torch.testing.assert_close(unobserved[2] - unobserved[1], unobserved[1] - unobserved[0])
    # the same lanes one by one give the same answer
    for i in range(3):
        torch.testing.assert_close(fitted[i], fit_control_points(y[i], values[i], M, Y_START, Y_END))


def test_fit_ignores_masked_samples_and_handles_padding():
    M = 8
    P = curvy_control_points(M)
    y = torch.linspace(Y_START, Y_END, 120, dtype=torch.float64)
    values = dense_samples(P, y)
    clean = fit_control_points(y, values, M, Y_START, Y_END)
    # outliers that are masked out, outside the y range, or NaN must not change the fit
    y_noisy = torch.cat([y, torch.tensor([50.0, 200.0, -10.0, 60.0], dtype=torch.float64)])
    values_noisy = torch.cat([values, torch.full((4, 3), 99.0, dtype=torch.float64)])
    values_noisy[-1, 0] = float("nan")
    weights = torch.cat([torch.ones(120, dtype=torch.float64), torch.tensor([0.0, 1.0, 1.0, 1.0], dtype=torch.float64)])
    torch.testing.assert_close(fit_control_points(y_noisy, values_noisy, M, Y_START, Y_END, weights), clean)
    # a padded batch: an empty lane and a single-sample lane come back NaN, the rest is unaffected
    y_batch = torch.stack([y, y, y])
    w_batch = torch.ones(3, 120, dtype=torch.float64)
    w_batch[1] = 0
    w_batch[2, 1:] = 0
    fitted = fit_control_points(y_batch, values.expand(3, 120, 3), M, Y_START, Y_END, w_batch)
    torch.testing.assert_close(fitted[0], clean)
    assert torch.isnan(fitted[1:]).all()


def test_fit_weights_pull_towards_heavier_samples():
    y = torch.tensor([10.0, 10.0, 90.0], dtype=torch.float64)
    values = torch.tensor([[0.0], [1.0], [0.0]], dtype=torch.float64)
    light = fit_control_points(y, values, 2, Y_START, Y_END, torch.tensor([1.0, 1.0, 1.0], dtype=torch.float64))
    heavy = fit_control_points(y, values, 2, Y_START, Y_END, torch.tensor([1.0, 3.0, 1.0], dtype=torch.float64))
    s = curve_arguments(torch.tensor([10.0], dtype=torch.float64), Y_START, Y_END)
    torch.testing.assert_close(evaluate(light, s), torch.tensor([[0.5]], dtype=torch.float64))
    torch.testing.assert_close(evaluate(heavy, s), torch.tensor([[0.75]], dtype=torch.float64))


def test_fit_float32():
    M = 10
    P = curvy_control_points(M, torch.float32)
    y = torch.linspace(Y_START, Y_END, 200)
    fitted = fit_control_points(y, dense_samples(P, y), M, Y_START, Y_END)
    assert fitted.dtype == torch.float32
    torch.testing.assert_close(fitted, P, atol=1e-4, rtol=0)


def test_sampling_matrix_keeps_full_precision_under_autocast():
    s = torch.linspace(0, 1, 7)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        A = sampling_matrix(5, s)
    assert A.dtype == torch.float32
    torch.testing.assert_close(A, sampling_matrix(5, s))
