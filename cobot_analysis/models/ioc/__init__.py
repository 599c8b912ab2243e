"""Inverse optimal control (docs/methods.md sec. 6): the measured targets (``targets``) and the
bi-level fit of the cost weights (``fit``)."""

from cobot_analysis.models.ioc.fit import (FAILED_D, LOG_BOUNDS, OPTIMIZERS, T_BOUNDS, Checkpoint, IOCResult, IOCSpec,
                                           distances, duration_terms, fit, fit_key, held_weights, solve_pair_target,
                                           solve_target)
from cobot_analysis.models.ioc.targets import PairTarget, Target, pair_targets_from_table, targets_from_table

__all__ = ["FAILED_D", "LOG_BOUNDS", "OPTIMIZERS", "T_BOUNDS", "Checkpoint", "IOCResult", "IOCSpec", "PairTarget", "Target",
           "distances", "duration_terms", "fit", "fit_key", "held_weights", "pair_targets_from_table", "solve_pair_target", "solve_target",
           "targets_from_table"]
