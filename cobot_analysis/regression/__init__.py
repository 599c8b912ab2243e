"""Metric regression: each stage's headline numbers in ``<stage>/metrics.json``, compared with a
committed baseline (``cobot-analysis metrics check``).

- ``extract``: what each stage reports (registry stage name -> function of the stage directory),
  written by ``workspace.Stage`` when the stage succeeds; read back per workspace.
- ``baseline``: baselines, their tolerance rules, the comparison table and the update diff.
"""

from cobot_analysis.regression.extract import METRICS_FILE, Metric, stage_metrics, workspace_metrics, write_stage_metrics

__all__ = ["METRICS_FILE", "Metric", "stage_metrics", "workspace_metrics", "write_stage_metrics"]
