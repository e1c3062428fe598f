"""Pictures of lanes: over the camera image and in a top view."""

from lanelab.viz.lanes import CATEGORY_COLORS, draw_lanes_on_image, draw_polylines, draw_top_view

__all__ = ["CATEGORY_COLORS", "draw_lanes_on_image", "draw_polylines", "draw_top_view"]
