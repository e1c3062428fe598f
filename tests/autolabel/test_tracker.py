"""The line tracker: one line, one track and one id; lanes that end; false detections; gaps."""

from __future__ import annotations

import numpy as np

from data_ingest.autolabel.projection import Observation
from data_ingest.autolabel.tracker import LineTracker, different_kinds, line_kind

STEP = 2  # nodes (metres) the ego advances per frame
NEAR, FAR = 5, 35  # nodes ahead of the ego that a frame's detections cover


def tracker(category_penalty_m: float = 1.0) -> LineTracker:
    return LineTracker(node_spacing_m=1.0, gate_m=1.5, confirm_hits=3, max_misses=5, merge_m=0.4,
                       process_noise_m=0.01, category_penalty_m=category_penalty_m)


def seen(frame: int, offset: float, rng: np.random.Generator, end: int | None = None, category: int = 1,
         sigma: float = 0.05) -> Observation | None:
    """Frame ``frame``'s detection of the line at lateral ``offset`` (ending at node ``end``)."""
    first, last = frame * STEP + NEAR, frame * STEP + FAR
    if end is not None:
        last = min(last, end)
    if last - first < 3:
        return None
    nodes = np.arange(first, last + 1)
    return Observation(frame, nodes, offset + rng.normal(0, sigma, len(nodes)), np.full(len(nodes), sigma),
                       category, 0.9)


def advance(tracked: LineTracker, t: int, observations: list[Observation]) -> None:
    """Frame t: the ego has passed node t * STEP, and a track is in view where it has nodes
    within the detections' reach."""
    window = (t * STEP + NEAR, t * STEP + FAR)
    tracked.step(t, observations, lambda track: bool(np.any((track.nodes >= window[0]) & (track.nodes <= window[1]))),
                 passed_node=t * STEP)


def run(lines: list[dict], frames: int, seed: int = 0) -> LineTracker:
    """Track ``lines`` (keyword arguments of :func:`seen`) over ``frames`` frames."""
    rng = np.random.default_rng(seed)
    tracked = tracker()
    for t in range(frames):
        observations = [o for line in lines if (o := seen(t, rng=rng, **line)) is not None]
        advance(tracked, t, observations)
    return tracked


def test_a_straight_lane_seen_for_100_frames_is_one_track_with_one_id():
    lines = run([{"offset": 1.75}], 100).lines(curvature_noise=0.003, min_length_m=10, max_std_m=0.5, max_gap_m=60)
    assert len(lines) == 1
    (line,) = lines
    assert line.track_id == 0 and not line.ended
    assert line.nodes[0] == NEAR and line.nodes[-1] == 99 * STEP + FAR  # all of it, from the first view on
    assert np.abs(line.d - 1.75).max() < 0.05  # 30 noisy views of each node, fused


def test_a_lane_that_ends_yields_a_track_that_ends_there_while_its_neighbour_goes_on():
    lines = run([{"offset": 1.75}, {"offset": -1.75, "end": 120, "category": 2}], 100)
    by_offset = {round(float(np.median(line.d))): line for line in lines.lines(0.003, 10, 0.5, 60)}
    assert sorted(by_offset) == [-2, 2]
    ending, going = by_offset[-2], by_offset[2]
    assert ending.ended and ending.nodes[-1] == 120 and ending.category == 2
    assert not going.ended and going.nodes[-1] == 99 * STEP + FAR
    assert {ending.track_id, going.track_id} == {0, 1}


def test_ids_stay_with_their_lines_and_a_one_off_false_detection_is_no_line():
    rng = np.random.default_rng(3)
    tracked = tracker()
    ids_over_time = []
    for t in range(60):
        observations = [seen(t, 1.75, rng), seen(t, -1.75, rng), seen(t, 5.25, rng)]
        if t == 30:  # a false detection between two lines, once
            observations.append(Observation(t, np.arange(t * STEP + 8, t * STEP + 16), np.full(8, 3.5),
                                            np.full(8, 0.05), 1, 0.4))
        advance(tracked, t, observations)
        ids_over_time.append({round(float(np.nanmedian(track.d))): track.track_id for track in tracked.tracks
                              if track.confirmed})
    lines = tracked.lines(0.003, 10, 0.5, 60)
    np.testing.assert_allclose(sorted(np.median(line.d) for line in lines), [-1.75, 1.75, 5.25], atol=0.05)
    assert all(ids == ids_over_time[-1] for ids in ids_over_time[3:])  # confirmed on the third frame, never renamed


def test_a_line_missed_for_a_few_frames_keeps_its_id_and_its_gap_is_filled():
    rng = np.random.default_rng(4)
    tracked = tracker()
    for t in range(80):
        observations = [] if 30 <= t < 34 else [seen(t, -1.75, rng)]  # the detector misses it 4 frames running
        advance(tracked, t, observations)
    (line,) = tracked.lines(0.003, 10, 0.5, 60)
    assert line.track_id == 0 and np.array_equal(line.nodes, np.arange(NEAR, 79 * STEP + FAR + 1))


def test_a_detection_joins_the_track_of_its_category_over_a_nearer_one_of_another():
    # A curb a metre beyond a yellow line, both tracked; then the curb seen from afar, its
    # detection biased 0.6 m towards the line: nearer the line's track, but a curb.
    def curb_track_after(category_penalty_m: float) -> list[float]:
        rng, tracked = np.random.default_rng(0), tracker(category_penalty_m)
        for t in range(10):
            tracked.step(t, [seen(t, -6.9, rng, category=8), seen(t, -7.9, rng, category=20)], lambda track: True,
                         passed_node=t * STEP)
        nodes = np.arange(10 * STEP + NEAR, 10 * STEP + FAR + 1)
        tracked.step(10, [Observation(10, nodes, np.full(len(nodes), -7.3), np.full(len(nodes), 0.05), 20, 0.9)],
                     lambda track: True, passed_node=10 * STEP)
        (curb,) = [track for track in tracked.tracks if track.category == 20]
        return [curb.hits, curb.misses]

    assert curb_track_after(category_penalty_m=1.0) == [11, 0]
    assert curb_track_after(category_penalty_m=0.0) == [10, 1]  # without: the yellow line's track took it


def test_dashed_and_solid_of_one_colour_are_one_kind_of_line_and_curbs_another():
    # A no-passing zone turns a dashed centre line solid: still the same line.
    assert line_kind(1) == line_kind(2) == line_kind(4) == "white"  # white dash, solid, double solid
    assert line_kind(7) == line_kind(8) == line_kind(10) == "yellow"
    assert line_kind(20) == line_kind(21) == "curb"
    assert different_kinds(20, 2) and different_kinds(8, 2) and not different_kinds(1, 2)
    assert not different_kinds(0, 20) and not different_kinds(8, 0)  # a detector that does not classify


def test_a_line_hidden_for_a_stretch_is_one_line_with_the_gap_filled_unless_joining_is_off():
    rng = np.random.default_rng(5)
    tracked = tracker()
    for t in range(90):  # hidden (by traffic, say) for 30 frames: 32 m unseen, its track ends, another begins
        observations = [] if 30 <= t < 60 else [seen(t, -1.75, rng), seen(t, 1.75, rng, category=20)]
        advance(tracked, t, observations)
    assert len([track for track in tracked.tracks if track.confirmed]) == 4
    joined = tracked.lines(0.003, 10, 0.5, max_gap_m=60)
    assert [line.track_id for line in joined] == [0, 1]
    for line in joined:
        assert np.array_equal(line.nodes, np.arange(NEAR, 89 * STEP + FAR + 1))
        assert np.abs(line.d - np.median(line.d)).max() < 0.05  # the gap filled along the line
    assert len(tracked.lines(0.003, 10, 0.5, max_gap_m=0)) == 4
    assert len(tracked.lines(0.003, 10, 0.5, max_gap_m=60)) == 2  # lines() leaves the tracks as they were


def test_lines_of_another_kind_or_offset_beyond_a_gap_are_not_joined():
    rng = np.random.default_rng(6)
    tracked = tracker()
    for t in range(70):  # a white line ends; 28 m on a curb goes on where it was, and a line 3 m away
        if t < 20:
            observations = [seen(t, -1.75, rng)]
        elif t < 48:
            observations = []
        else:
            observations = [seen(t, -1.75, rng, category=20), seen(t, 1.25, rng)]
        advance(tracked, t, observations)
    assert len(tracked.lines(0.003, 10, 0.5, max_gap_m=60)) == 3


def test_a_detection_that_overlaps_the_end_of_a_track_by_a_node_or_two_continues_it():
    tracked = tracker()
    for t, (first, last) in enumerate([(0, 20), (0, 22), (0, 24), (23, 45)]):  # the last shares two nodes
        nodes = np.arange(first, last + 1)
        tracked.step(t, [Observation(t, nodes, np.full(len(nodes), 1.75), np.full(len(nodes), 0.05), 1, 0.9)],
                     lambda track: True, passed_node=0)
    (track,) = tracked.tracks
    assert track.hits == 4 and track.nodes[-1] == 45
