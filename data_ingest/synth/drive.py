"""A synthetic drive: one log's world (road, scenery, traffic), its ego, camera and frames.

Whatever the config leaves "random" is drawn from (cfg.seed, log_index) alone: equal inputs
give equal drives, bit for bit. Environment, daytime and weather are dealt like cards, so
that a set of logs is balanced: every aligned block of 3 logs has each environment once, of
2 logs each daytime, of 4 logs each weather, in an order shuffled per block and seed. Lane
count, lane width, ego speed and the world itself come from independent streams of a
``numpy.random.SeedSequence``. Tests build exact situations by passing the road, the vehicles
or the ego's lane themselves::

    xs = cross_section.highway(num_lanes=3, lane_width=3.5)
    road = Road.from_profiles(800.0, xs, grade=lambda s: ...)
    drive = SyntheticDrive(cfg, 0, road=road, ego_lane=1,
                           vehicles=[Vehicle.in_lane(road, 1, s=EGO_START_M + 30.0)])
"""

from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np

from data_ingest.synth.appearance import Look, make_look, without_noise
from data_ingest.synth.boxes import Boxes
from data_ingest.synth.camera import View, make_camera
from data_ingest.synth.config import DAYTIMES, ENVIRONMENTS, WEATHERS, SynthConfig
from data_ingest.synth.cross_section import random_cross_section
from data_ingest.synth.ego import Ego, LaneChange, Wander, plan_lane_change
from data_ingest.synth.frame import SynthFrame
from data_ingest.synth.labels import ARC_MARGIN, Labeler
from data_ingest.synth.render import DRAW_RANGE_M, Renderer
from data_ingest.synth.road import Road, random_road
from data_ingest.synth.roadside import scenery as make_scenery
from data_ingest.synth.traffic import TYPICAL_SPEED_MPS, Traffic, Vehicle, random_vehicles

EGO_START_M = 30.0  # arc length where the ego starts
ROAD_MARGIN_M = 50.0  # road beyond the farthest point ever drawn
BEHIND_EGO_M = 20.0  # vehicles this far behind the ego may still reach into the camera's view
LANE_COUNTS = {"highway": (2, 5), "urban": (1, 3), "rural": (1, 2)}  # lanes per direction when random
_STREAMS = ("scenario", "road", "scenery", "traffic", "ego", "look", "render")


class SyntheticDrive:
    """One synthetic drive log: ``camera``, ``duration_ns``, ``scenario``, ``pose_at`` and ``frames``.

    Timestamps run from 0 to ``duration_ns``; frame k is at round(k * 1e9 / cfg.fps).
    Keyword arguments replace parts of the random world (for tests): ``road``, ``vehicles``
    (an empty list for no traffic), ``ego_lane`` (index into ``road.cross_section.lanes``),
    ``lane_changes`` (() for none), ``scenery`` (False: none) and ``sensor_noise`` (False: clean images).
    """

    def __init__(self, cfg: SynthConfig, log_index: int, *, road: Road | None = None,
                 vehicles: Sequence[Vehicle] | None = None, ego_lane: int | None = None,
                 lane_changes: tuple[LaneChange, ...] | None = None, scenery: bool = True,
                 sensor_noise: bool = True) -> None:
        self.cfg = cfg
        self.log_index = log_index
        seeds = np.random.SeedSequence([cfg.seed, log_index]).spawn(len(_STREAMS))
        rng = {name: np.random.default_rng(seed) for name, seed in zip(_STREAMS, seeds)}
        world = cfg.world

        deal = {name: _dealt(choices, cfg.seed, log_index, salt)
                for salt, (name, choices) in enumerate((("environment", ENVIRONMENTS), ("daytime", DAYTIMES),
                                                        ("weather", WEATHERS)))}
        environment = road.cross_section.environment if road is not None else _configured(
            _random_as_none(world.environment), deal["environment"])
        daytime = _configured(_random_as_none(world.daytime), deal["daytime"])
        weather = _configured(_random_as_none(world.weather), deal["weather"])
        pick = rng["scenario"]  # every choice is drawn even when configured, so the draws stay aligned
        low, high = LANE_COUNTS[environment]
        num_lanes = _configured(world.num_lanes, int(pick.integers(low, high + 1)))
        lane_width = float(pick.uniform(*world.lane_width_m))
        speed = _configured(world.ego_speed_mps, float(pick.uniform(*TYPICAL_SPEED_MPS[environment])))

        self.duration_ns = int(round(cfg.duration_s * 1e9))
        self.draw_range = max(DRAW_RANGE_M, ARC_MARGIN * world.max_range_m)
        self.num_frames = max(int(round(cfg.duration_s * cfg.fps)), 1)
        if road is None:
            length = EGO_START_M + speed * cfg.duration_s + self.draw_range + ROAD_MARGIN_M
            xs = random_cross_section(rng["road"], environment, num_lanes, lane_width, EGO_START_M, length,
                                      world.min_curve_radius_m)
            road = random_road(rng["road"], length, xs, world.min_curve_radius_m, world.max_straight_m)
        self.road = road
        ego_lanes = road.cross_section.ego_lanes()
        lane = ego_lanes[int(rng["ego"].integers(len(ego_lanes)))] if ego_lane is None else ego_lane
        wander = Wander.random(rng["ego"])
        if lane_changes is None:
            lane_changes = plan_lane_change(rng["ego"], Ego(road, lane, EGO_START_M, speed), cfg.duration_s)
        self.ego = Ego(road, lane, EGO_START_M, speed, wander, lane_changes)
        if vehicles is None:
            vehicles = random_vehicles(rng["traffic"], road, environment, world.traffic_density, lane,
                                       EGO_START_M, speed, cfg.duration_s)
            times = np.arange(0.0, cfg.duration_s + 0.05, 0.05)
            self.traffic = Traffic(road, vehicles).clear_of(times, *self.ego.place(times))
        else:
            self.traffic = Traffic(road, vehicles)
        self.scenery = make_scenery(rng["scenery"], road) if scenery else Boxes.empty()

        self.scenario = {"environment": environment, "daytime": daytime, "weather": weather,
                         "num_lanes": str(len(ego_lanes)),
                         "lane_width_m": f"{road.cross_section.lanes[lane].width:.2f}",
                         "ego_speed_mps": f"{speed:.1f}"}
        self.camera = make_camera(cfg.camera)
        look: Look = make_look(environment, daytime, weather, rng["look"])
        self.renderer = Renderer(road, self.scenery, self.camera, look if sensor_noise else without_noise(look),
                                 rng["render"], self.draw_range)
        self.labeler = Labeler(road, self.camera, world.max_range_m, self.scenario, (cfg.seed, log_index),
                               cfg.detector_noise)

    def pose_at(self, t_ns: int) -> np.ndarray:
        """Ego pose T_odom_base (4, 4) at time ``t_ns`` (ns since the start; any time, smooth)."""
        return self.ego.pose(t_ns * 1e-9)

    def timestamp(self, index: int) -> int:
        return int(round(index * 1e9 / self.cfg.fps))

    def frame(self, index: int) -> SynthFrame:
        """Frame ``index`` (0-based): image, pose and ground truth."""
        return self._frame(index, render=True)

    def unrendered_frame(self, index: int) -> SynthFrame:
        """Frame ``index`` without its image (``image`` is empty): pose, ground truth and detections,
        as :meth:`frame` gives them, for work that needs no pixels."""
        return self._frame(index, render=False)

    def _frame(self, index: int, render: bool) -> SynthFrame:
        t_ns = self.timestamp(index)
        t = t_ns * 1e-9
        T_world_base = self.ego.pose(t)
        s, d = (float(x) for x in self.ego.place(t))
        view = View(self.camera, T_world_base)
        vehicles = self.traffic.boxes(t, s - BEHIND_EGO_M, s + self.draw_range)
        image = self.renderer.render(view, s, vehicles, index) if render else np.zeros((0, 0, 3), np.uint8)
        occluders = Boxes.concat([self.scenery.overlapping(s, s + ARC_MARGIN * self.cfg.world.max_range_m), vehicles])
        truth = self.labeler.label(index, view, s, d, occluders)
        return SynthFrame(index, t_ns, image, T_world_base, truth.lanes, truth.lanes2d, truth.tags, truth.occluders)

    def frames(self) -> Iterator[SynthFrame]:
        """All frames in time order."""
        for index in range(self.num_frames):
            yield self.frame(index)


def _dealt(choices: tuple[str, ...], seed: int, log_index: int, salt: int) -> str:
    """The choice of log ``log_index``: each aligned block of len(choices) logs gets every choice once."""
    block, slot = divmod(log_index, len(choices))
    order = np.random.default_rng([seed, block, salt]).permutation(len(choices))
    return choices[int(order[slot])]


def _random_as_none(value: str) -> str | None:
    return None if value == "random" else value


def _configured(value, drawn):
    return drawn if value is None else value
