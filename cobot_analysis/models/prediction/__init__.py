"""Trajectory prediction (docs/methods.md sec. 7): the receding-horizon OC predictor and the
baselines (``predictor``, ``baselines``), their errors (``metrics``) and the sweep over
trajectories and settings (``sweep``)."""
