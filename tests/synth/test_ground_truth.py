"""Ground truth: 3D lanes in the lane frame, their visibility, 2D detections and scenario tags."""

import numpy as np
import pytest
import torch

from data_ingest.synth import cross_section
from data_ingest.synth.config import load_synth_config
from data_ingest.synth.cross_section import ExtraLane
from data_ingest.synth.drive import EGO_START_M, SyntheticDrive
from data_ingest.synth.road import Road
from data_ingest.synth.traffic import Vehicle
from lanelab.geometry.camera import in_image, project_lane_points
from lanelab.geometry.frames import extrinsic_base_to_lane
from lanelab.lanes import LANE_CATEGORY_IDS


def ego_lane_lines(frame):
    """The two labels bounding the ego's lane: nearest left and right at 10 m ahead."""
    x = {lane.track_id: np.interp(10.0, lane.points[:, 1], lane.points[:, 0]) for lane in frame.lanes}
    left = max((t for t in x if x[t] < 0), key=lambda t: x[t])
    right = min((t for t in x if x[t] > 0), key=lambda t: x[t])
    return [lane for lane in frame.lanes if lane.track_id in (left, right)]


def visibility_between(lane, y0: float, y1: float) -> np.ndarray:
    return lane.visibility[(lane.points[:, 1] > y0) & (lane.points[:, 1] < y1)]


def test_a_vehicle_ahead_hides_the_lines_behind_it(clear_cfg, straight_road):
    truck = Vehicle.in_lane(straight_road, 1, EGO_START_M + 30.0, speed=0.0, kind="truck")
    blocked = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[truck]).frame(0)
    free = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[]).frame(0)
    for with_truck, without in zip(ego_lane_lines(blocked), ego_lane_lines(free)):
        assert with_truck.track_id == without.track_id
        assert (visibility_between(with_truck, 45.0, 90.0) == 0).all()
        assert (visibility_between(without, 45.0, 90.0) == 1).all()
        assert (visibility_between(with_truck, 8.0, 20.0) == 1).all()  # nearer than the truck
    assert blocked.tags["occlusion"] != "none" and free.tags["occlusion"] == "none"


def test_points_past_a_crest_are_hidden(clear_cfg, crest_road, straight_road):
    over_crest = SyntheticDrive(clear_cfg, 0, road=crest_road, ego_lane=1, vehicles=[], scenery=False).frame(0)
    flat = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[], scenery=False).frame(0)
    for lane in ego_lane_lines(over_crest):
        assert (visibility_between(lane, 8.0, 60.0) == 1).all()
        assert (visibility_between(lane, 130.0, 200.0) == 0).all()
    for lane in ego_lane_lines(flat):
        assert (visibility_between(lane, 8.0, 200.0) == 1).all()
    assert over_crest.tags["slope"] == "up_down" and flat.tags["slope"] == "flat"


def test_points_outside_the_image_are_invisible(clear_cfg):
    wide = Road.from_profiles(800.0, cross_section.highway(5, 3.5))
    drive = SyntheticDrive(clear_cfg, 0, road=wide, ego_lane=0, vehicles=[])
    frame = drive.frame(0)
    T_lane_cam = extrinsic_base_to_lane(torch.from_numpy(drive.camera.T_base_cam))
    outside = 0
    for lane in frame.lanes:
        uv, _, in_front = project_lane_points(torch.from_numpy(lane.points), torch.from_numpy(drive.camera.K),
                                              T_lane_cam)
        inside = (in_front & in_image(uv, drive.camera.width, drive.camera.height)).numpy()
        assert (lane.visibility[~inside] == 0).all()
        outside += (~inside).sum()
    assert outside > 50  # near points below the image, the far right lines beside it


def test_labels_are_well_formed_and_track_ids_stable():
    cfg = load_synth_config(["camera.width=160", "camera.height=120", "duration_s=1.0", "fps=10"])
    for log_index in range(6):
        drive = SyntheticDrive(cfg, log_index)
        previous = None
        for frame in (drive.frame(i) for i in range(4)):
            for lane in frame.lanes:
                assert lane.category in LANE_CATEGORY_IDS
                assert lane.points.shape == (len(lane.visibility), 3) and lane.points.dtype == np.float64
                assert lane.visibility.dtype == np.float32 and set(np.unique(lane.visibility)) <= {0.0, 1.0}
                assert (np.diff(lane.points[:, 1]) > 0).all()
                assert 0 <= lane.points[0, 1] and lane.points[-1, 1] <= cfg.world.max_range_m
            ids = [lane.track_id for lane in frame.lanes]
            assert len(ids) == len(set(ids))
            if previous is not None:
                before = {lane.track_id: lane for lane in previous.lanes}
                for lane in frame.lanes:
                    if lane.track_id in before:  # the same line: same category, same place at 20 m ahead
                        old = before[lane.track_id]
                        assert lane.category == old.category
                        x_now = np.interp(20.0, lane.points[:, 1], lane.points[:, 0])
                        x_before = np.interp(20.0, old.points[:, 1], old.points[:, 0])
                        assert abs(x_now - x_before) < 0.5
                assert len(set(ids) & set(before)) >= len(ids) - 1
            previous = frame


def test_lanes_reach_the_configured_range(clean_drive, clear_cfg):
    frame = clean_drive.frame(0)
    assert sorted(lane.category for lane in frame.lanes) == [1, 1, 2, 8, 20, 21]
    for lane in frame.lanes:
        assert lane.points[-1, 1] > clear_cfg.world.max_range_m - 2.5
        assert lane.points[0, 1] < 1.0
        assert np.abs(lane.points[:, 2]).max() < 1e-6  # flat road, ego level on it


def test_lines_start_and_end_at_merges_and_splits(clear_cfg):
    extra = ExtraLane(start=EGO_START_M + 60.0, end=EGO_START_M + 260.0, taper=60.0, width=3.5)
    road = Road.from_profiles(900.0, cross_section.highway(2, 3.5, extra_lanes=(extra,)))
    drive = SyntheticDrive(clear_cfg, 0, road=road, ego_lane=1, vehicles=[])
    first = drive.frame(0)
    separator = next(lane for lane in first.lanes if lane.category == 1 and lane.points[0, 1] > 50.0)
    assert 60.0 < separator.points[0, 1] < 90.0 and 220.0 > separator.points[-1, 1] > 150.0
    edge = next(lane for lane in first.lanes if lane.category == 2)
    widening = np.interp([40.0, 150.0], edge.points[:, 1], edge.points[:, 0])
    assert widening[1] - widening[0] == pytest.approx(3.5, abs=0.3)  # the edge line diverges by a lane
    assert first.tags["merge_split"] == "yes"
    assert drive.frame(0).tags == first.tags
    no_split = SyntheticDrive(clear_cfg, 0, road=Road.from_profiles(900.0, cross_section.highway(2, 3.5)),
                              ego_lane=1, vehicles=[]).frame(0)
    assert no_split.tags["merge_split"] == "no"


def test_detections_follow_the_visible_near_lanes(clear_cfg, straight_road):
    drive = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[])
    T_lane_cam = extrinsic_base_to_lane(torch.from_numpy(drive.camera.T_base_cam))
    truth = []
    for frame in (drive.frame(i) for i in range(10)):
        for lane in frame.lanes:
            uv, _, _ = project_lane_points(torch.from_numpy(lane.points), torch.from_numpy(drive.camera.K), T_lane_cam)
            truth.append(uv.numpy()[(lane.visibility > 0) & (lane.points[:, 1] < 55.0)])
        for detection in frame.lanes2d:
            assert detection.uv.dtype == np.float32 and detection.uv.shape[1] == 2
            assert 0.0 < detection.score <= 1.0
            assert detection.category in LANE_CATEGORY_IDS
    detections = [d for i in range(10) for d in drive.frame(i).lanes2d]
    assert len(detections) >= 30
    truth_uv = np.concatenate(truth)
    errors = [np.median(np.linalg.norm(d.uv[:, None] - truth_uv[None], axis=2).min(axis=1)) for d in detections]
    assert np.mean(np.array(errors) < 6.0) > 0.85  # most are real lanes, a few are false fragments
    again = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[]).frame(3).lanes2d
    np.testing.assert_array_equal(np.concatenate([d.uv for d in again]),
                                  np.concatenate([d.uv for d in drive.frame(3).lanes2d]))


@pytest.mark.parametrize("radius, expected", [(None, "straight"), (600.0, "curve"), (150.0, "strong_curve")])
def test_curvature_tag(clear_cfg, radius, expected):
    curvature = 0.0 if radius is None else 1 / radius
    road = Road.from_profiles(800.0, cross_section.highway(2, 3.5), curvature=curvature)
    frame = SyntheticDrive(clear_cfg, 0, road=road, vehicles=[]).frame(0)
    assert frame.tags["curvature"] == expected
    assert {key: frame.tags[key] for key in ("environment", "daytime", "weather")} == \
        {"environment": "highway", "daytime": "day", "weather": "sun"}
