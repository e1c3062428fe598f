"""The ONCE-3DLanes adapter: ONCE-3DLanes labels and images -> a clip store (``lanelab-once``).

- ``labeled_frame``: one label file as a store frame's calibration, extrinsic and lanes;
- ``poses``: ego poses from ONCE's per-sequence annotations (``poses=``);
- ``adapter``: sequences -> clips;
- ``config`` / ``cli``: the options (``conf/once.yaml``) and the command.

ONCE's JSON format itself is :mod:`lanelab.once`'s: lanelab-eval ``format=once`` writes
predictions for a ONCE store's frames there.
"""
