"""The headline numbers of each stage ("metrics"): the numbers ``docs/results.md`` reports (distances mean
and sd, test statistics and p, fitted D and weights, prediction errors, localisation delay, offsets,
errors, goals) and the counts behind them, as functions of the stage's own tables.

The results of ``cobot_analysis.api`` give theirs with ``.metrics()``; the workspace writes the same
records into ``<stage>/metrics.json`` (``cobot_analysis.regression``), which the metric regression
compares with its baselines. One module per concept: ``records`` (a metric and how records are
named), ``data`` (synthetic studies, import, preprocess), ``analysis`` (average, compare, stats,
reconstruct), ``models`` (fit-ioc, generate, velocity-commands), ``prediction``, ``localisation``.

    >>> import cobot_analysis.api as ca
    >>> from cobot_analysis.synth.tables import walking_table
    >>> numbers = ca.average(walking_table(n_subjects=3, n_conditions=2, n_trials=2)).metrics().as_dict()
    >>> numbers["average.means"], numbers["average.walker.trials"]
    (2, 12)
"""

from cobot_analysis.metrics.records import Collector, Metric, Metrics

__all__ = ["Collector", "Metric", "Metrics"]
