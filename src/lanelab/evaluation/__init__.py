"""Evaluation runs: the OpenLane metric over predictions, reported as the papers' tables.

- ``cli``: ``lanelab-eval`` (options: ``config``, ``conf/eval.yaml``);
- ``report``: the tables (overall, scenario F1, per scenario) as text, Markdown and JSON;
- ``pictures``: a few frames with ground truth and prediction over the image and in a top view.
"""
