"""The rendered image agrees with the ground truth, and looks like its scenario."""

import itertools

import numpy as np
import pytest
import torch

from data_ingest.synth import cross_section
from data_ingest.synth.camera import NEAR_M, clip_near
from data_ingest.synth.config import DAYTIMES, ENVIRONMENTS, WEATHERS, load_synth_config
from data_ingest.synth.drive import EGO_START_M, SyntheticDrive
from data_ingest.synth.road import Road
from data_ingest.synth.traffic import Vehicle
from lanelab.geometry.camera import project_lane_points
from lanelab.geometry.frames import extrinsic_base_to_lane

SOLID_LINES = (2, 8)  # white and yellow solid: paint under every label point
SMALL = ("camera.width=160", "camera.height=120", "duration_s=0.5")


def pixels(drive: SyntheticDrive, lane, shift: float = 0.0) -> np.ndarray:
    """(P, 2) pixels of a label's points, moved ``shift`` m to the right, as a user of the labels projects them."""
    points = lane.points + np.array([shift, 0.0, 0.0])
    T_lane_cam = extrinsic_base_to_lane(torch.from_numpy(drive.camera.T_base_cam))
    uv, _, _ = project_lane_points(torch.from_numpy(points), torch.from_numpy(drive.camera.K), T_lane_cam)
    return uv.numpy()


def contrast_to_asphalt(drive: SyntheticDrive, image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(P,) largest mean |colour - asphalt| within one pixel of each uv: a sub-pixel stripe may be
    rasterised on either side of a pixel boundary."""
    asphalt = drive.renderer.look.palette["asphalt"]
    difference = np.abs(image.astype(float) - asphalt).mean(axis=2)
    padded = np.pad(difference, 1)
    col, row = np.floor(uv).astype(int).T + 1
    return np.max([padded[row + dv, col + du] for dv, du in itertools.product((-1, 0, 1), repeat=2)], axis=0)


def paint_hits(drive: SyntheticDrive, frame, shift: float = 0.0, max_y: float = 40.0) -> np.ndarray:
    """(P,) bool for the visible points of solid lines within max_y: is their pixel painted?"""
    hits = []
    for lane in frame.lanes:
        if lane.category in SOLID_LINES:
            uv = pixels(drive, lane, shift)
            near = (lane.visibility > 0) & (lane.points[:, 1] < max_y)
            inside = np.all((uv >= 0) & (uv < [drive.camera.width, drive.camera.height]), axis=1)
            hits.append(contrast_to_asphalt(drive, frame.image, uv[near & inside]) > 40)
    return np.concatenate(hits)


def test_labels_project_onto_the_painted_lines(clear_cfg, straight_road):
    hilly_curve = Road.from_profiles(800.0, cross_section.two_way("rural", 1, 1, 3.5, double_centre=False),
                                     curvature=1 / 150, grade=lambda s: 0.04 * np.sin(s / 60))
    for road in (straight_road, hilly_curve):
        drive = SyntheticDrive(clear_cfg, 0, road=road, vehicles=[], sensor_noise=False)
        for frame in (drive.frame(0), drive.frame(7)):
            on_paint = paint_hits(drive, frame)
            assert len(on_paint) > 40
            assert on_paint.mean() >= 0.9
            # Half a metre off, the same check fails: it tests the geometry, not just "inside the image".
            assert paint_hits(drive, frame, shift=0.5).mean() < 0.5


def test_a_crest_hides_the_road_behind_it(clear_cfg, crest_road):
    drive = SyntheticDrive(clear_cfg, 0, road=crest_road, ego_lane=1, vehicles=[], sensor_noise=False)
    frame = drive.frame(0)
    hidden = []
    for lane in frame.lanes:
        if lane.category in SOLID_LINES:
            uv = pixels(drive, lane)
            inside = np.all((uv >= 0) & (uv < [drive.camera.width, drive.camera.height]), axis=1)
            behind = inside & (lane.visibility == 0) & (lane.points[:, 1] > 20)
            hidden.append(contrast_to_asphalt(drive, frame.image, uv[behind]) > 40)
    hidden = np.concatenate(hidden)
    assert len(hidden) > 30
    assert hidden.mean() < 0.1  # the near road was drawn over the lines beyond the crest


def test_a_vehicle_ahead_is_drawn_where_it_stands(clear_cfg, straight_road):
    blue = (200.0, 60.0, 20.0)
    car = Vehicle.in_lane(straight_road, 1, EGO_START_M + 25.0, speed=0.0, color=blue)
    drive = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[car], sensor_noise=False)
    image = drive.frame(0).image
    body = straight_road.surface(car.s - car.length / 2, car.lane_offset, 0.6)  # middle of its rear
    T_base_world = np.linalg.inv(drive.pose_at(0))
    T_cam_world = np.linalg.inv(drive.camera.T_base_cam) @ T_base_world
    p = T_cam_world[:3, :3] @ body + T_cam_world[:3, 3]
    u, v = (drive.camera.K @ p)[:2] / p[2]
    assert np.abs(image[int(v), int(u)].astype(float) - np.array(blue) * 0.88).max() < 25


def test_a_vehicle_beside_the_camera_is_clipped_not_mirrored(clear_cfg, straight_road):
    red = (20.0, 20.0, 230.0)
    truck = Vehicle.in_lane(straight_road, 2, EGO_START_M + 1.0, speed=0.0, kind="truck", color=red, cargo=red)
    drive = SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[truck], sensor_noise=False)
    image = drive.frame(0).image.astype(float)
    reddish = (image[..., 2] > 120) & (image[..., 0] < 80) & (image[..., 1] < 80)
    assert reddish[:, drive.camera.width // 2:].sum() > 1000  # it fills the right side ...
    assert reddish[:, : drive.camera.width // 3].sum() == 0  # ... and nothing flips over to the left


def test_clip_near_keeps_what_is_in_front():
    quad = np.array([[[-1.0, 1.0, -2.0], [1.0, 1.0, -2.0], [1.0, 1.0, 8.0], [-1.0, 1.0, 8.0]]])
    behind, ahead = quad - [0, 0, 20.0], quad + [0, 0, 20.0]
    clipped, keep = clip_near(np.concatenate([quad, behind, ahead]), NEAR_M)
    assert keep.tolist() == [True, False, True]
    assert clipped[0, :, 2].min() == pytest.approx(NEAR_M)
    assert {tuple(p) for p in clipped[0].round(9)} == {(-1.0, 1.0, NEAR_M), (1.0, 1.0, NEAR_M), (1.0, 1.0, 8.0),
                                                      (-1.0, 1.0, 8.0)}
    np.testing.assert_array_equal(clipped[2, :4], ahead[0])


def render(environment: str, daytime: str, weather: str) -> np.ndarray:
    cfg = load_synth_config([*SMALL, f"world.environment={environment}", f"world.daytime={daytime}",
                             f"world.weather={weather}", "world.num_lanes=2"])
    return SyntheticDrive(cfg, 3).frame(0).image.astype(float)


@pytest.fixture(scope="module")
def looks() -> dict[tuple[str, str, str], np.ndarray]:
    return {combo: render(*combo) for combo in itertools.product(ENVIRONMENTS, DAYTIMES, WEATHERS)}


def test_every_scenario_renders(looks):
    for combo, image in looks.items():
        assert image.shape == (120, 160, 3), combo
        assert 5 < image.mean() < 250, combo


def test_scenarios_change_the_image(looks):
    for environment in ENVIRONMENTS:
        sunny_day = looks[(environment, "day", "sun")]
        night = looks[(environment, "night", "sun")]
        assert night.mean() < 0.5 * sunny_day.mean()
        for weather in ("rain", "fog", "snow"):
            assert np.abs(looks[(environment, "day", weather)] - sunny_day).mean() > 8, (environment, weather)
        # Fog washes out the far field: the band around the horizon loses its contrast.
        band = slice(40, 70)
        assert looks[(environment, "day", "fog")][band].std() < 0.5 * sunny_day[band].std()
    assert np.abs(looks[("urban", "day", "sun")] - looks[("highway", "day", "sun")]).mean() > 8
