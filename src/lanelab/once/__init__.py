"""ONCE-3DLanes' JSON format: the one place that reads and writes it (no torch).

- ``camera``: the fixed camera of ONCE stores (LATR's height and pitch) and camera <-> lane frame;
- ``labels``: label and prediction JSON files, read and validated, and their content;
- ``file_paths``: where a frame's ONCE files lie (``<sequence>/cam01/<stamp>.json``).

The ONCE adapter (``data_ingest.once``) reads through it, lanelab-eval's ``format=once`` writes
through it, and the ONCE metric (:mod:`lanelab.metrics.once`) reads lanes with it.
"""
