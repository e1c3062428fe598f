"""The preview pictures of lanelab-synth (and the top view both previews share): every lane
inside the top view, its title in a strip of its own, and a legend of the colours drawn."""

from __future__ import annotations

import numpy as np

from data_ingest.synth.frame import CameraModel, SynthFrame
from data_ingest.synth.preview import CAPTION_HEIGHT, PreviewRow, contact_sheet
from lanelab.lanes import Lane
from lanelab.viz import CATEGORY_COLORS, draw_top_view
from lanelab.viz.lanes import HIDDEN_COLOR, TITLE_HEIGHT, fit_x_range

WHITE_DASH, CURB = 1, 21


def lane(x: float, category: int, hidden_from: float = 200.0) -> Lane:
    """A straight lane at x (metres) from 0 to 150 m ahead, hidden beyond hidden_from."""
    y = np.linspace(0.0, 150.0, 40)
    return Lane(np.stack([np.full_like(y, x), y, np.zeros_like(y)], -1), (y < hidden_from).astype(np.float64), category)


def has(picture: np.ndarray, color: tuple[int, int, int]) -> bool:
    return bool(np.all(picture == color, axis=-1).any())


def test_the_x_range_holds_every_lane_within_the_y_range_and_at_least_20_m() -> None:
    assert fit_x_range([lane(-3.0, 1), lane(3.0, 1)], (0.0, 100.0)) == (-20.0, 20.0)
    low, high = fit_x_range([lane(-3.0, 1), lane(31.5, 1)], (0.0, 100.0))
    assert (low, high) == (-35.0, 35.0)  # symmetric about the ego, a metre to spare, 5 m steps
    beyond = Lane(np.array([[0.0, 50.0, 0.0], [60.0, 180.0, 0.0]]), np.ones(2), 1)
    assert fit_x_range([beyond], (0.0, 100.0)) == (-20.0, 20.0)  # a point past the view's far end does not count


def test_the_top_view_title_has_a_strip_nothing_is_drawn_over() -> None:
    view = draw_top_view([lane(x, CURB) for x in (-8.0, -4.0, 0.0, 4.0)], size=(240, 120), y_range=(0.0, 100.0),
                         title="3D panel")  # fmt: skip
    assert view.shape == (240, 120, 3)
    strip, plot = view[:TITLE_HEIGHT], view[TITLE_HEIGHT:]
    assert (strip.max(-1) > 200).any()  # the title's letters
    assert not has(strip, CATEGORY_COLORS[CURB]) and has(plot, CATEGORY_COLORS[CURB])


def synth_row(name: str, lanes: list[Lane]) -> PreviewRow:
    # A forward-looking camera 1.5 m up: optical (x right, y down, z ahead) -> base_link (x ahead, y left, z up).
    T_base_cam = np.eye(4)
    T_base_cam[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]
    T_base_cam[2, 3] = 1.5
    camera = CameraModel(np.array([[100.0, 0, 80], [0, 100.0, 60], [0, 0, 1]]), 160, 120, T_base_cam)
    frames = [SynthFrame(i, i * 10**9, np.full((120, 160, 3), 60, np.uint8), np.eye(4), lanes, []) for i in range(2)]
    return PreviewRow(name, camera, {"num_lanes": "6"}, frames)


def test_the_synth_preview_shows_the_outer_lanes_and_a_legend_of_its_colours() -> None:
    lanes = [lane(-31.0, CURB), lane(-3.5, WHITE_DASH, hidden_from=60.0), lane(3.5, WHITE_DASH), lane(31.0, CURB)]
    sheet = contact_sheet([synth_row("log_000", lanes)], tile_width=160)
    # The row: a caption, then 160-pixel tiles (the image, each kept frame), then the top view.
    top = sheet[CAPTION_HEIGHT : CAPTION_HEIGHT + 120, 3 * 160 :]
    middle = top.shape[1] // 2
    assert has(top[:, :middle], CATEGORY_COLORS[CURB]) and has(top[:, middle:], CATEGORY_COLORS[CURB])
    legend = sheet[CAPTION_HEIGHT + 120 :]
    assert legend.shape[0] > 10
    for color in (CATEGORY_COLORS[CURB], CATEGORY_COLORS[WHITE_DASH], HIDDEN_COLOR):
        assert has(legend, color), color
