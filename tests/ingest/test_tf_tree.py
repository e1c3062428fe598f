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
    T, valid, gap = tree.lookup("odom", "base_link", np.array([0, 250_000_000, 1_000_000_000]))
    assert valid.all() and gap is None
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
    _, valid, gap = tree.lookup("camera", "odom", np.array([-1, 500_000_000, 1_000_000_001]))
    assert valid.tolist() == [False, True, False] and gap == "base_link"
    assert tree.time_range("base_link") == "0.000-1.000 s" and tree.time_range("camera") == "static"


def test_unconnected_frames_and_second_parents(tree):
    assert not tree.connected("odom", "map")
    with pytest.raises(KeyError):
        tree.lookup("map", "camera", np.array([0]))
    tree.add(transform(0, "map", "base_link", pose(0.0, 0.0, 0.0)), static=True)
    assert tree.conflicts == {("base_link", "map"): 1} and tree.parent("base_link") == "odom"
    assert tree.describe() == ("odom -> base_link (2 samples), base_link -> camera (static), "
                               "odom -> landmark (static)")
