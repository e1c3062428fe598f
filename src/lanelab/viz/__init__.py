"""Pictures of lanes: over the camera image and in a top view (``lanes``), and rows that compare
ground truth with predictions under a legend (``panels``)."""

from lanelab.viz.lanes import CATEGORY_COLORS, GT_COLOR, PREDICTION_COLOR, draw_lanes_on_image, draw_polylines, draw_top_view

__all__ = ["CATEGORY_COLORS", "GT_COLOR", "PREDICTION_COLOR", "draw_lanes_on_image", "draw_polylines", "draw_top_view"]
