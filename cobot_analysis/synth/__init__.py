"""Deterministic synthetic studies with their ground truth (``cobot-analysis synth ...``).

- ``paths``: smooth human-like base paths and speed profiles;
- ``body``: markers from a true pose (rigid pelvis, gait oscillation, feet, head, table corners),
  measurement noise and occlusion gaps;
- ``c3d``: C3D writing (ezc3d, mm, NaN + residual -1 for occluded samples);
- ``truth``: the TRUTH / TRUTH_TRIALS tables;
- ``walking``: the single-walking study; ``pairs``: the pair-carriage study.
"""

#: version of the generators: bump it when a change alters the generated data, so that a workspace
#: stage made by an older generator is regenerated instead of skipped as up to date.
GENERATOR_VERSION = 6
