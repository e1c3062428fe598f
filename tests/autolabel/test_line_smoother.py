"""The along-line smoother: closer to the line than the measurements, and bridging gaps."""

from __future__ import annotations

import numpy as np

from data_ingest.autolabel.line_smoother import smooth_line


def test_a_noisy_curved_line_gets_closer_to_the_truth_and_a_gap_is_bridged():
    s = np.arange(0.0, 200.0)
    truth = 2.0 + 0.01 * s + 2e-4 * (s - 80) ** 2 / 2  # a gentle curve
    rng = np.random.default_rng(0)
    sigma = np.full(len(s), 0.15)
    measured = truth + rng.normal(0, sigma)
    var = sigma**2
    var[90:110] = np.inf  # an occlusion: no measurement there
    smoothed = smooth_line(s, measured, var, curvature_noise=0.003)
    seen = np.isfinite(var)
    assert np.abs(smoothed - truth)[seen].mean() < 0.5 * np.abs(measured - truth)[seen].mean()
    assert np.abs(smoothed - truth)[90:110].max() < 0.1
