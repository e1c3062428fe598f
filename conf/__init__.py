"""Hydra config tree, installed as the ``lanelab.conf`` package so entry points find it in a wheel too."""
