"""The OpenLane adapter: OpenLane's annotations and images -> a clip store (``lanelab-openlane``),
and predictions -> OpenLane prediction files.

- ``annotation``: one annotation file in lanelab's terms, and the lane frame of OpenLane stores;
- ``adapter``: segments -> clips, tags from the scenario lists and scene.json;
- ``predictions``: predicted lanes -> OpenLane prediction JSON;
- ``config`` / ``cli``: the options (``conf/openlane.yaml``) and the command.
"""
