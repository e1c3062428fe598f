"""OpenLane's JSON format and lists: the one place that reads and writes them.

- ``read``: ground-truth and prediction JSON files, read and validated;
- ``write``: lanes of the lane frame as prediction and ground-truth JSON files;
- ``ground_frame``: OpenLane's camera axes and the official evaluator's ground frame;
- ``file_paths``: a frame's ``file_path`` and where its JSON files lie;
- ``lane_order``: lanes listed far to near in OpenLane files, near to far in a store;
- ``lists``: test lists and the scenario lists of OpenLane's six test cases.

Metrics (:mod:`lanelab.metrics`) read through this package; the OpenLane adapter
(``data_ingest.openlane``) and lanelab's prediction writers write through it.
"""
