"""The TF buffer: chains composed in either direction, interpolation (linear + slerp), time ranges."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from data_ingest.ingest.messages import Transform
from data_ingest.ingest.tf_tree import TfTree
from lanelab.geometry import (
    compose,
    euler_to_rotation,
    interpolate_pose,
    invert,
    make_transform,
    rotation_to_quaternion,
)


def pose(yaw: float, x: float, y: float) -> torch.Tensor:
    R = euler_to_rotation(torch.tensor(0.01), torch.tensor(-0.02), torch.tensor(yaw, dtype=torch.float64))
    return make_transform(R.to(torch.float64), torch.tensor([x, y, 0.5], dtype=torch.float64))


def transform(stamp: int, parent: str, child: str, T: torch.Tensor) -> Transform:
    return Transform(stamp, parent, child, tuple(T[:3, 3].tolist()), tuple(rotation_to_quaternion(T[:3, :3]).tolist()))


@pytest.fixture
def tree():
    """odom -> base_link at 0 and 1 s, base_link -> camera and odom -> landmark static."""
    tf = TfTree()
    tf.add(transform(0, "odom", "base_link", pose(0.1, 100.0, -50.0)), static=False)
    tf.add(transform(1_000_000_000, "odom", "base_link", pose(0.4, 110.0, -48.0)), static=False)
    tf.add(transform(0, "base_link", "camera", pose(-1.2, 1.8, 0.1)), static=True)
    tf.add(transform(0, "odom", "landmark", pose(2.0, 5.0, 5.0)), static=True)
    return tf


def test_interpolates_linearly_and_by_slerp(tree):
    T, valid, faults = tree.lookup("odom", "base_link", np.array([0, 250_000_000, 1_000_000_000]))
    assert valid.all() and faults == {}
    expected = interpolate_pose(pose(0.1, 100.0, -50.0), pose(0.4, 110.0, -48.0), torch.tensor([0.0, 0.25, 1.0]))
    np.testing.assert_allclose(T, expected.numpy(), atol=1e-12)


def test_composes_chains_through_the_common_ancestor_both_ways(tree):
    t = np.array([400_000_000])
    T_odom_base = interpolate_pose(pose(0.1, 100.0, -50.0), pose(0.4, 110.0, -48.0), 0.4)
    T_odom_camera = compose(T_odom_base, pose(-1.2, 1.8, 0.1))
    np.testing.assert_allclose(tree.lookup("odom", "camera", t)[0][0], T_odom_camera.numpy(), atol=1e-12)
    np.testing.assert_allclose(tree.lookup("camera", "odom", t)[0][0], invert(T_odom_camera).numpy(), atol=1e-12)
    T_landmark_camera = compose(invert(pose(2.0, 5.0, 5.0)), T_odom_camera)
    np.testing.assert_allclose(tree.lookup("landmark", "camera", t)[0][0], T_landmark_camera.numpy(), atol=1e-12)


def test_outside_the_samples_is_undefined(tree):
    _, valid, faults = tree.lookup("camera", "odom", np.array([-1, 500_000_000, 1_000_000_001]))
    assert valid.tolist() == [False, True, False] and list(faults) == [("base_link", "outside")]
    assert tree.time_range("base_link") == "0.000-1.000 s" and tree.time_range("camera") == "static"


def test_unconnected_frames_and_second_parents(tree):
    assert not tree.connected("odom", "map")
    with pytest.raises(KeyError):
        tree.lookup("map", "camera", np.array([0]))
    tree.add(transform(0, "map", "base_link", pose(0.0, 0.0, 0.0)), static=True)
    assert tree.conflicts == {("base_link", "map"): 1} and tree.parent("base_link") == "odom"
    assert tree.describe() == ("odom -> base_link (2 samples), base_link -> camera (static), "
                               "odom -> landmark (static)")


def test_a_gap_longer_than_the_limit_is_not_bridged(tree):
    """Issue 37, case 5: the samples at 0 and 1 s are 1 s apart."""
    stamps = np.array([0, 500_000_000, 1_000_000_000])
    _, valid, faults = tree.lookup("odom", "camera", stamps, max_gap_ns=500_000_000)
    assert valid.tolist() == [True, False, True]  # at a sample nothing is interpolated
    assert {key: mask.tolist() for key, mask in faults.items()} == {("base_link", "gap"): [False, True, False]}
    assert tree.lookup("odom", "camera", stamps, max_gap_ns=1_000_000_000)[1].all()


def test_a_clock_that_jumps_back_makes_the_claimed_times_ambiguous():
    """Issue 37, case 3: samples every 0.1 s, the stamps after 0.5 s moved back 0.3 s."""
    tf = TfTree(agreement=0.05)
    for k in range(11):
        t = k * 100_000_000
        tf.add(transform(t - (300_000_000 if k > 5 else 0), "odom", "base_link", pose(0.0, k * 2.0, 0.0)), static=False)
    stamps = np.arange(0, 700_000_001, 50_000_000)
    _, valid, faults = tf.lookup("odom", "base_link", stamps)
    # 0.3 s (received after 0.5 s) to 0.5 s are claimed twice; stamps between 0.2 and 0.6 s use such samples.
    assert stamps[~valid].tolist() == [250_000_000, 300_000_000, 350_000_000, 400_000_000, 450_000_000,
                                       500_000_000, 550_000_000]
    assert list(faults) == [("base_link", "ambiguous")]
    assert tf.problems() == ["TF odom -> base_link: 2 sample(s) stamped before one received earlier and off the "
                             "others' path (largest step back 0.200 s, at 0.500 s: the clock jumped back?); 3 stamp(s) "
                             "with two different "
                             "transforms (first at 0.300 s)"]


def test_two_transforms_at_one_stamp_are_ambiguous_and_repeated_ones_are_not(tree):
    tree.add(transform(1_000_000_000, "odom", "base_link", pose(0.4, 110.0, -48.0)), static=False)  # the same again
    assert tree.lookup("odom", "base_link", np.array([500_000_000]))[1].all() and tree.problems() == []
    tree.add(transform(2_000_000_000, "odom", "base_link", pose(0.4, 130.0, -48.0)), static=False)
    tree.add(transform(2_000_000_000, "odom", "base_link", pose(0.4, 120.0, -48.0)), static=False)
    _, valid, faults = tree.lookup("odom", "base_link", np.array([500_000_000, 1_000_000_000, 1_500_000_000]))
    assert valid.tolist() == [True, True, False] and list(faults) == [("base_link", "ambiguous")]
    assert tree.problems() == ["TF odom -> base_link: 1 stamp(s) with two different transforms (first at 2.000 s)"]


def test_a_late_sample_on_the_path_of_the_others_is_used():
    """Messages out of order (the sample at 0.2 s received after the one at 0.3 s) are not a clock jump."""
    tf = TfTree(agreement=0.05)
    for k in (0, 1, 3, 2, 4):
        tf.add(transform(k * 100_000_000, "odom", "base_link", pose(0.0, k * 2.0, 0.0)), static=False)
    _, valid, faults = tf.lookup("odom", "base_link", np.arange(0, 400_000_001, 50_000_000))
    assert valid.all() and faults == {} and tf.problems() == []
