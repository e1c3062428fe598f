"""lanelab: an experiment platform for temporal monocular 3D lane detection."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("lanelab")  # set at install from git (setuptools-scm, pyproject.toml)
except PackageNotFoundError:  # sources on the path, never installed
    __version__ = "0.0.0+unknown"
