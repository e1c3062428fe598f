"""SyntheticDrive: scenario, camera, ego motion, frames and determinism."""

import numpy as np
import pytest

from data_ingest.synth.config import DAYTIMES, ENVIRONMENTS, WEATHERS, load_synth_config
from data_ingest.synth.drive import EGO_START_M, SyntheticDrive
from data_ingest.synth.ego import LaneChange

SMALL = ("camera.width=160", "camera.height=120", "duration_s=1.0", "fps=10")


def angle_between(R0: np.ndarray, R1: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(R0.T @ R1) - 1) / 2, -1.0, 1.0)))


def test_camera_model_follows_the_config(clean_drive, clear_cfg):
    camera, cam_cfg = clean_drive.camera, clear_cfg.camera
    assert (camera.width, camera.height, camera.frame_id) == (cam_cfg.width, cam_cfg.height, cam_cfg.frame_id)
    assert camera.K[0, 0] == pytest.approx(cam_cfg.width / 2 / np.tan(np.deg2rad(cam_cfg.hfov_deg / 2)))
    np.testing.assert_allclose(camera.K[:2, 2], [cam_cfg.width / 2, cam_cfg.height / 2])
    pitch = np.deg2rad(cam_cfg.pitch_deg)
    np.testing.assert_allclose(camera.T_base_cam[:3, 2], [np.cos(pitch), 0.0, -np.sin(pitch)], atol=1e-12)
    np.testing.assert_allclose(camera.T_base_cam[:3, 0], [0.0, -1.0, 0.0], atol=1e-12)  # optical x = right
    np.testing.assert_allclose(camera.T_base_cam[:3, 3], [cam_cfg.mount_forward_m, 0.0, cam_cfg.mount_height_m])


def test_frames_count_from_zero_at_the_camera_rate(clean_drive, clear_cfg):
    frames = list(clean_drive.frames())
    assert len(frames) == round(clear_cfg.duration_s * clear_cfg.fps)
    assert [f.index for f in frames] == list(range(len(frames)))
    assert [f.timestamp_ns for f in frames] == [round(i * 1e9 / clear_cfg.fps) for i in range(len(frames))]
    assert clean_drive.duration_ns == round(clear_cfg.duration_s * 1e9)
    for frame in frames[:3]:
        assert frame.image.shape == (clear_cfg.camera.height, clear_cfg.camera.width, 3)
        assert frame.image.dtype == np.uint8
        np.testing.assert_array_equal(frame.T_world_base, clean_drive.pose_at(frame.timestamp_ns))


def test_ego_drives_smoothly_on_the_surface_at_the_configured_speed(crest_road):
    cfg = load_synth_config([*SMALL, "world.ego_speed_mps=20.0", "duration_s=6.0"])
    drive = SyntheticDrive(cfg, 0, road=crest_road, ego_lane=1, vehicles=[])
    stamps = np.arange(0, drive.duration_ns + 1, 20_000_000)  # the /tf rate, 50 Hz
    poses = np.stack([drive.pose_at(int(t)) for t in stamps])
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1) / 0.02
    np.testing.assert_allclose(steps, 20.0, rtol=0.01)  # speed as configured, no jumps
    turns = [angle_between(a[:3, :3], b[:3, :3]) for a, b in zip(poses[:-1], poses[1:])]
    assert max(turns) < 0.01  # < 0.5 degree per 20 ms, even over the crest
    for t, pose in zip(stamps[::25], poses[::25]):
        s, d = drive.ego.place(t * 1e-9)
        np.testing.assert_allclose(pose[:3, 3], crest_road.surface(s, d), atol=1e-9)  # on the road surface
        grade = crest_road.grade(s)
        assert pose[2, 0] == pytest.approx(grade / np.hypot(1.0, grade), abs=0.005)  # the nose follows the grade
    assert drive.pose_at(0)[2, 0] > 0.05 and drive.pose_at(drive.duration_ns)[2, 0] < -0.05  # up, then down
    assert drive.ego.place(0.0)[0] == pytest.approx(EGO_START_M)


def test_the_ego_wanders_within_its_lane(clean_drive):
    t = np.linspace(0.0, 60.0, 601)
    _, d = clean_drive.ego.place(t)
    lane = clean_drive.road.cross_section.lanes[1]
    assert 0.05 < np.abs(d - lane.offset).max() < 0.35


def test_same_seed_same_drive():
    cfg = load_synth_config([*SMALL, "world.traffic_density=2.0"])
    first, second = SyntheticDrive(cfg, 5), SyntheticDrive(cfg, 5)
    assert first.scenario == second.scenario
    for a, b in zip(first.frames(), second.frames()):
        np.testing.assert_array_equal(a.image, b.image)
        np.testing.assert_array_equal(a.T_world_base, b.T_world_base)
        assert a.tags == b.tags
        assert [(la.track_id, la.category) for la in a.lanes] == [(lb.track_id, lb.category) for lb in b.lanes]
        for la, lb in zip(a.lanes, b.lanes):
            np.testing.assert_array_equal(la.points, lb.points)
            np.testing.assert_array_equal(la.visibility, lb.visibility)
        assert [(d.score, d.category) for d in a.lanes2d] == [(d.score, d.category) for d in b.lanes2d]


def test_logs_differ_and_cover_the_scenarios():
    cfg = load_synth_config(SMALL)
    drives = [SyntheticDrive(cfg, i) for i in range(12)]
    for a, b in zip(drives[:-1], drives[1:]):
        assert a.scenario != b.scenario or not np.allclose(a.pose_at(10**9), b.pose_at(10**9))
    for drive in drives:
        assert drive.scenario["environment"] in ENVIRONMENTS
        assert drive.scenario["daytime"] in DAYTIMES
        assert drive.scenario["weather"] in WEATHERS
        low, high = {"highway": (25, 33), "rural": (15, 25), "urban": (8, 14)}[drive.scenario["environment"]]
        assert low <= float(drive.scenario["ego_speed_mps"]) <= high
    # Dealt, not drawn: any 12 aligned logs are balanced, whatever the seed.
    for key, choices in (("environment", ENVIRONMENTS), ("daytime", DAYTIMES), ("weather", WEATHERS)):
        values = [d.scenario[key] for d in drives]
        assert sorted(values) == sorted(choices * (12 // len(choices))), key


def test_configured_choices_are_kept():
    cfg = load_synth_config([*SMALL, "world.environment=urban", "world.daytime=night", "world.weather=fog",
                             "world.num_lanes=2", "world.ego_speed_mps=11.0", "world.lane_width_m=[3.2,3.2]"])
    drive = SyntheticDrive(cfg, 7)
    assert drive.scenario == {"environment": "urban", "daytime": "night", "weather": "fog", "num_lanes": "2",
                              "lane_width_m": "3.20", "ego_speed_mps": "11.0"}
    assert [lane.direction for lane in drive.road.cross_section.lanes].count(1) == 2


def test_a_lane_change_moves_the_ego_smoothly_by_a_lane(clear_cfg, straight_road):
    cfg = load_synth_config([*SMALL, "world.ego_speed_mps=25.0", "duration_s=5.0"])
    drive = SyntheticDrive(cfg, 0, road=straight_road, ego_lane=1, vehicles=[],
                           lane_changes=(LaneChange(start=1.0, duration=3.0, shift=3.5),))
    before, after = drive.frame(0), drive.frame(45)
    lanes = straight_road.cross_section.lanes
    assert drive.ego.place(0.0)[1] == pytest.approx(lanes[1].offset, abs=0.35)
    assert drive.ego.place(4.5)[1] == pytest.approx(lanes[2].offset, abs=0.35)
    yaw = [np.arctan2(drive.pose_at(t)[1, 0], drive.pose_at(t)[0, 0]) for t in (0, 2_500_000_000, 4_500_000_000)]
    assert yaw[1] < -0.05 and abs(yaw[0]) < 0.03 and abs(yaw[2]) < 0.03  # turned right, then straight again
    # The same lines keep their ids; seen from the ego, they all moved a lane to the left.
    x_before = {lane.track_id: np.interp(20.0, lane.points[:, 1], lane.points[:, 0]) for lane in before.lanes}
    x_after = {lane.track_id: np.interp(20.0, lane.points[:, 1], lane.points[:, 0]) for lane in after.lanes}
    assert x_before.keys() == x_after.keys()
    for track_id in x_before:
        assert x_after[track_id] - x_before[track_id] == pytest.approx(-3.5, abs=0.7)


def test_random_traffic_never_overlaps_the_ego():
    cfg = load_synth_config([*SMALL, "duration_s=20.0", "world.traffic_density=3.0", "world.environment=highway"])
    for log_index in range(6):
        drive = SyntheticDrive(cfg, log_index)
        times = np.arange(0.0, 20.0, 0.1)
        s, d = drive.ego.place(times)
        centres = drive.traffic.centres(times)
        for k, vehicle in enumerate(drive.traffic.vehicles):
            # base_link is at the rear axle: the ego reaches ~1 m behind it and ~3.8 m ahead, 0.95 m aside.
            overlap_s = (centres[:, k] - vehicle.length / 2 < s + 3.8) & (centres[:, k] + vehicle.length / 2 > s - 1.0)
            overlap_d = np.abs(vehicle.lane_offset - d) < vehicle.width / 2 + 0.95
            assert not (overlap_s & overlap_d).any(), (log_index, vehicle)
