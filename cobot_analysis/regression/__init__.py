"""Metric regression: each stage's headline numbers in ``<stage>/metrics.json``, compared with a
committed baseline (``cobot-analysis metrics check``).

- ``extract``: each stage's ``metrics.json``, written by ``workspace.Stage`` when the stage succeeds: the
  run's API result's own numbers (``result.metrics()``, ``cobot_analysis.metrics``), else read from the
  stage's outputs (registry stage name -> reader); read back per workspace.
- ``baseline``: baselines, their tolerance rules, the comparison table and the update diff.
"""

from cobot_analysis.regression.extract import METRICS_FILE, Metric, stage_metrics, workspace_metrics, write_stage_metrics

__all__ = ["METRICS_FILE", "Metric", "stage_metrics", "workspace_metrics", "write_stage_metrics"]
