"""lanelab: an experiment platform for temporal monocular 3D lane detection."""

__version__ = "0.1.0"
