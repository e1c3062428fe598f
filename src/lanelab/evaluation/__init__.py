"""Evaluation runs: the OpenLane metric over predictions, reported as the papers' tables.

- ``config``: the schema of ``conf/eval.yaml``, the options of ``lanelab-eval``
  (:mod:`lanelab.experiment.eval_cli`, which also runs checkpoints);
- ``report``: the tables (overall, scenario F1, per scenario) as text, Markdown and JSON;
- ``pictures``: a few frames with ground truth and prediction over the image and in a top view.
"""
