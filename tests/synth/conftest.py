"""Drives and configs for the synthetic-log tests.

The MCAP writer's tests call ``synth_config(*overrides)`` and ``make_drive(cfg)``; the
latter is parametrised over an analytic :class:`FakeDrive` (exact, with awkward poses)
and the real :class:`SyntheticDrive`, so every writer test runs on both. The world,
renderer and ground-truth tests build exact small worlds (``clean_drive``, ``crest_road``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Iterator

import cv2
import numpy as np
import pytest

from data_ingest.synth import cross_section
from data_ingest.synth.config import SynthConfig, load_synth_config
from data_ingest.synth.drive import SyntheticDrive
from data_ingest.synth.frame import CameraModel, Lane2D, SynthFrame
from data_ingest.synth.road import Road
from lanelab.lanes import Lane

# Small and quick; label_every=3 so that not every frame is labelled.
SMALL = ["duration_s=2.0", "fps=10", "tf_rate_hz=50", "label_every=3",
         "camera.width=160", "camera.height=120"]


def _camera(cfg: SynthConfig) -> CameraModel:
    """A pinhole camera mounted as cfg.camera says: forward, up, pitched down."""
    cam = cfg.camera
    f = cam.width / 2 / math.tan(math.radians(cam.hfov_deg) / 2)
    K = np.array([[f, 0, cam.width / 2], [0, f, cam.height / 2], [0, 0, 1]])
    p = math.radians(cam.pitch_deg)
    # Columns: optical x, y, z in base_link; z forward and tilted down by the pitch.
    R = np.array([[0, -math.sin(p), math.cos(p)], [-1, 0, 0], [0, -math.cos(p), -math.sin(p)]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, (cam.mount_forward_m, 0.0, cam.mount_height_m)
    return CameraModel(K=K, width=cam.width, height=cam.height, T_base_cam=T, frame_id=cam.frame_id)


@dataclass
class FakeDrive:
    """Drives along a gentle left curve over a slightly rolling road; everything is analytic.

    The pose has non-zero roll, pitch and yaw and large coordinates, so that axis mix-ups
    and precision losses show.
    """

    camera: CameraModel
    duration_ns: int
    fps: float
    scenario: dict[str, str] = field(
        default_factory=lambda: {"environment": "rural", "daytime": "day", "weather": "fog"})

    def pose_at(self, t_ns: int) -> np.ndarray:
        t = t_ns / 1e9
        yaw, pitch, roll = 0.3 + 0.05 * t, 0.02 * math.sin(t), 0.01 * math.cos(2 * t)
        cy, sy, cp, sp, cr, sr = (math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch),
                                  math.cos(roll), math.sin(roll))
        T = np.eye(4)
        T[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]]
        T[:3, 3] = (1234.5 + 15 * t, -678.25 + 2 * t * t, 3.0 + 0.1 * t)
        return T

    def frames(self) -> Iterator[SynthFrame]:
        count = int(self.duration_ns * self.fps // 1e9)
        for index in range(count):
            t_ns = round(index * 1e9 / self.fps)
            yield SynthFrame(
                index=index,
                timestamp_ns=t_ns,
                image=self._image(index),
                T_world_base=self.pose_at(t_ns),
                lanes=self._lanes(index),
                lanes2d=self._lanes2d(index),
                tags={"weather": "fog", "daytime": "day", "environment": "rural",
                      "curvature": "straight" if index < count // 2 else "curve"},
                occluders=self._occluders(index),
            )

    def _image(self, index: int) -> np.ndarray:
        h, w = self.camera.height, self.camera.width
        rows = np.linspace(0, 255, h, dtype=np.float64)[:, None]
        cols = np.linspace(0, 255, w, dtype=np.float64)[None, :]
        image = np.stack([np.broadcast_to(rows, (h, w)), np.broadcast_to(cols, (h, w)),
                          np.full((h, w), 7.0 * index % 256)], axis=-1).astype(np.uint8)
        for k in range(3):
            cv2.line(image, (w // 2 + (k - 1) * w // 3, h), (w // 2 + (k - 1) * 8 + index, h // 2), (255, 255, 255), 2)
        return image

    def _occluders(self, index: int) -> np.ndarray:
        mask = np.zeros((self.camera.height, self.camera.width), bool)
        mask[self.camera.height // 2: self.camera.height // 2 + 10, index: index + 20] = True
        return mask

    def _lanes(self, index: int) -> list[Lane]:
        y = np.linspace(3.0, 80.0, 25)
        lanes = []
        for k, offset in enumerate((-5.25, -1.75, 1.75, 5.25)):
            x = offset + 1e-3 * y**2 + 0.01 * index
            z = 0.02 * y + 0.001 * k
            visibility = (y < 60 + 5 * k).astype(np.float32) * np.float32(0.9)
            lanes.append(Lane(track_id=10 + k, category=(2, 1, 1, 21)[k],
                              points=np.stack([x, y, z], axis=-1), visibility=visibility))
        return lanes

    def _lanes2d(self, index: int) -> list[Lane2D]:
        v = np.linspace(self.camera.height - 1, self.camera.height / 2, 12, dtype=np.float32)
        return [Lane2D(uv=np.stack([u0 + (v - v[0]) * slope + 0.5 * index, v], axis=-1).astype(np.float32),
                       score=0.8 - 0.1 * k, category=1)
                for k, (u0, slope) in enumerate(((20.0, -0.9), (140.0, 0.9)))]


def fake_drive(cfg: SynthConfig) -> FakeDrive:
    return FakeDrive(_camera(cfg), duration_ns=round(cfg.duration_s * 1e9), fps=cfg.fps)


@pytest.fixture
def synth_config() -> Callable[..., SynthConfig]:
    """``synth_config(*overrides)``: conf/synth.yaml with :data:`SMALL`, then ``overrides``."""
    return lambda *overrides: load_synth_config([*SMALL, *overrides])


@pytest.fixture
def fake_drive_factory() -> Callable[[SynthConfig], FakeDrive]:
    return fake_drive


@pytest.fixture(params=["fake", "synthetic"])
def make_drive(request, fake_drive_factory):
    """The drive the MCAP writer tests write, a function of the config: the fake or the real one."""
    if request.param == "fake":
        return fake_drive_factory
    return lambda cfg: SyntheticDrive(cfg, 0)


# --- exact small worlds for the tests of the world, renderer and ground truth ------------------

CLEAR = ("world.environment=highway", "world.daytime=day", "world.weather=sun", "world.traffic_density=0",
         "duration_s=2.0", "fps=10")


@pytest.fixture(scope="session")
def clear_cfg() -> SynthConfig:
    """Clear day on a highway, no random traffic, 2 s at 10 fps, the default 480 x 360 camera."""
    return load_synth_config(CLEAR)


@pytest.fixture(scope="session")
def straight_road() -> Road:
    """800 m of straight, flat three-lane highway, 3.5 m lanes."""
    return Road.from_profiles(800.0, cross_section.highway(3, 3.5))


@pytest.fixture(scope="session")
def crest_road() -> Road:
    """A highway climbing at 6 % that turns over a sharp crest into a 6 % descent, 100-140 m in."""
    return Road.from_profiles(800.0, cross_section.highway(3, 3.5),
                              grade=lambda s: np.interp(s, [0.0, 100.0, 140.0], [0.06, 0.06, -0.06]))


@pytest.fixture(scope="session")
def clean_drive(clear_cfg, straight_road) -> SyntheticDrive:
    """The ego in the middle lane of the straight road: nothing but the road, no sensor noise."""
    return SyntheticDrive(clear_cfg, 0, road=straight_road, ego_lane=1, vehicles=[], sensor_noise=False)
