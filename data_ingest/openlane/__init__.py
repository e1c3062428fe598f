"""The OpenLane adapter: OpenLane's annotations and images -> a clip store (``lanelab-openlane``).

- ``annotation``: one annotation file in lanelab's terms, and the lane frame of OpenLane stores;
- ``adapter``: segments -> clips, tags from the scenario lists and scene.json;
- ``config`` / ``cli``: the options (``conf/openlane.yaml``) and the command.

OpenLane's JSON format and lists themselves are :mod:`lanelab.openlane`'s: predictions for an
OpenLane store's frames are written there (:func:`lanelab.openlane.write.write_prediction`
under :func:`lanelab.openlane.file_paths.file_path_of`).
"""
