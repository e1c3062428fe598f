"""Auto-labeling (SparseLaneSTP §4, supplementary E): 3D lane labels from a drive log's 2D lane
detections and ego trajectory, an option of ``lanelab-ingest`` (``autolabel.enabled=true``).

One module per stage: :mod:`surface` (the road surface from the poses), :mod:`projection`
(detections met with it), :mod:`tracker` and :mod:`line_smoother` (lines tracked along the
drive), :mod:`frame_labels` (the lines in every frame, with visibility), :mod:`quality`
(scored against true lanes where a log has them); :mod:`pipeline` runs them on a drive,
:mod:`log` inside the ingest.
"""
