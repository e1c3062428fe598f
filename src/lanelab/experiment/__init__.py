"""Experiments: the ``lanelab-train`` and ``lanelab-eval`` entry points over the ``conf/`` tree, its config checks,
the evaluation report after training, and ``lanelab-sweep-report`` over multiruns.

- ``config``: the root schema and the start-up checks; ``targets``: ``_target_`` nodes
  checked against the signatures of what they build;
- ``build``: a run (datamodule, LightningModule, Trainer, ...) built from its config, and the
  config every checkpoint carries;
- ``train``: ``lanelab-train``; ``evaluate``: predictions, report and pictures of a split;
- ``eval_cli``: ``lanelab-eval``, over prediction files or a checkpoint on a store;
- ``sweep_report``: ``lanelab-sweep-report``.
"""

METRICS_JSON = "metrics.json"  # every run folder's final metrics, written by train, read by sweep_report
BLIND_PRIOR_PREFIX = "blind_prior/"  # metrics.json keys of the blind prior's scores (lanelab.evaluation.blind_prior)
