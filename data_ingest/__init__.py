"""Producers of clip datasets: synthetic drive logs, MCAP ingestion, adapters, auto-labelling.

- ``contract``: the drive-log contract (topics, frames, roles) that ``synth`` writes and
  ``ingest`` reads;
- ``synth``: synthetic drive logs (``lanelab-synth``); ``ingest``: drive logs -> a clip store
  (``lanelab-ingest``); ``openlane``: OpenLane -> a clip store (``lanelab-openlane``);
  ``autolabel``: 3D lane labels from 2D detections and the trajectory (``lanelab-ingest
  autolabel.enabled=true``).

Imports :mod:`lanelab`; :mod:`lanelab` never imports this package.
"""
