"""The road's geometry and cross-section: the surface, the profiles, lanes and lines."""

import numpy as np
import pytest

from data_ingest.synth import cross_section
from data_ingest.synth.cross_section import ExtraLane
from data_ingest.synth.road import ROAD_STYLES, Road, random_road
from lanelab.lanes import LANE_CATEGORY_IDS


def test_straight_road_runs_east_with_d_to_the_right(straight_road):
    points = straight_road.surface(np.array([0.0, 10.0, 100.0]), np.array([0.0, 2.0, -3.0]))
    # odom: x east, y north; the road starts heading east, so "right" is south (-y).
    np.testing.assert_allclose(points, [[0.0, 0.0, 0.0], [10.0, -2.0, 0.0], [100.0, 3.0, 0.0]], atol=1e-9)


def test_constant_curvature_is_a_circle():
    radius = 200.0
    road = Road.from_profiles(400.0, cross_section.highway(2, 3.5), curvature=1 / radius, bank=0.0)
    quarter = np.pi / 2 * radius
    np.testing.assert_allclose(road.heading(quarter), np.pi / 2, atol=1e-6)
    np.testing.assert_allclose(road.surface(quarter, 0.0), [radius, radius, 0.0], atol=1e-3)
    # A line 5 m right of a left curve runs on the outside: 2.5 % longer per metre.
    np.testing.assert_allclose(road.travelled(quarter, 5.0), quarter * (1 + 5.0 / radius), rtol=1e-6)
    np.testing.assert_allclose(road.s_after(road.travelled(123.0, 5.0), 5.0), 123.0, atol=1e-6)


def test_grade_integrates_to_elevation_and_bank_lowers_the_right_side():
    road = Road.from_profiles(300.0, cross_section.highway(2, 3.5), grade=0.05, bank=0.04)
    assert road.surface(200.0, 0.0)[2] == pytest.approx(10.0)
    assert road.height(200.0, 3.0) == pytest.approx(10.0 - 3.0 * np.sin(0.04))
    assert road.height(200.0, -3.0) > road.height(200.0, 3.0)


def test_curves_bank_inwards():
    left = Road.from_profiles(300.0, cross_section.highway(2, 3.5), curvature=1 / 150)
    assert left.bank(100.0) < 0  # left side lower: into the curve
    assert left.height(100.0, -5.0) < left.height(100.0, 5.0)


def test_layouts_have_valid_categories_unique_track_ids_and_curbsides():
    layouts = [cross_section.highway(4, 3.5),
               cross_section.two_way("urban", 2, 2, 3.2),
               cross_section.two_way("rural", 1, 1, 3.6, double_centre=False)]
    for layout in layouts:
        categories = [line.category for line in layout.lines]
        assert set(categories) <= set(LANE_CATEGORY_IDS)
        assert len({line.track_id for line in layout.lines}) == len(layout.lines)
        assert categories[0] == 20 and categories[-1] == 21  # curbsides at the edges, left to right
        offsets = [line.offset for line in layout.lines]
        assert offsets == sorted(offsets)
    highway, urban, rural = layouts
    assert [line.category for line in highway.lines] == [20, 8, 1, 1, 1, 2, 21]
    assert 10 in [line.category for line in urban.lines]  # double yellow between the directions
    assert 7 in [line.category for line in rural.lines]  # dashed yellow centre line
    assert [lane.direction for lane in urban.lanes] == [-1, -1, 1, 1]


def test_extra_lane_opens_and_closes_with_a_separator_that_starts_and_ends():
    extra = ExtraLane(start=100.0, end=400.0, taper=60.0, width=3.5)
    layout = cross_section.highway(2, 3.5, extra_lanes=(extra,))
    edge = next(line for line in layout.lines if line.category == 2)
    separator = next(line for line in layout.lines if np.isfinite(line.start))
    s = np.array([50.0, 130.0, 250.0, 370.0, 450.0])
    offsets = layout.line_offset(edge, s)
    assert offsets[0] == offsets[-1] == 7.0  # the edge line converges back ...
    assert offsets[2] == pytest.approx(10.5)  # ... from a full lane further out
    assert 7.0 < offsets[1] < 10.5 and 7.0 < offsets[3] < 10.5  # over the tapers
    assert 100.0 < separator.start < 160.0 and 340.0 < separator.end < 400.0
    assert separator.offset == 7.0 and separator.category == 1


@pytest.mark.parametrize("environment", ["highway", "rural", "urban"])
def test_random_roads_respect_the_radius_and_grade_limits(environment):
    layout = cross_section.random_cross_section(np.random.default_rng(1), environment, 2, 3.5, 30.0, 3000.0, 120.0)
    road = random_road(np.random.default_rng(2), 3000.0, layout, min_radius=120.0)
    s = np.linspace(0.0, road.length, 5000)
    assert np.abs(road.curvature(s)).max() <= 1 / 120.0 + 1e-9
    assert np.abs(road.curvature(s)).max() > 0  # it does bend
    assert np.abs(road.grade(s)).max() <= ROAD_STYLES[environment].max_grade + 1e-9
    again = random_road(np.random.default_rng(2), 3000.0, layout, min_radius=120.0)
    np.testing.assert_array_equal(again.surface(s, 1.0), road.surface(s, 1.0))


def _longest_straight(road: Road, step: float = 1.0) -> float:
    s = np.arange(0.0, road.length, step)
    straight = np.abs(road.curvature(s)) < 1e-9
    longest = run = 0
    for flat in straight:
        run = run + 1 if flat else 0
        longest = max(longest, run)
    return longest * step


def test_max_straight_caps_the_straights_and_keeps_the_style_otherwise():
    # A highway's straights run to 500 m, so a 4 s drive rarely sees a curve; the cap makes short
    # drives bend (the demo's training drives), without touching the radii.
    layout = cross_section.random_cross_section(np.random.default_rng(1), "highway", 2, 3.5, 30.0, 3000.0, 120.0)
    free = random_road(np.random.default_rng(2), 3000.0, layout, min_radius=120.0)
    capped = random_road(np.random.default_rng(2), 3000.0, layout, min_radius=120.0, max_straight=60.0)
    assert _longest_straight(free) > 100.0
    assert _longest_straight(capped) <= 61.0
    s = np.linspace(0.0, capped.length, 5000)
    radii = 1 / np.abs(capped.curvature(s))[np.abs(capped.curvature(s)) > 0]
    assert radii.min() >= ROAD_STYLES["highway"].radius_m[0] - 1e-6
