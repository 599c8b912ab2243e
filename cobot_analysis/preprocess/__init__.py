"""Preprocessing of raw markers (docs/methods.md sec. 2): gaps, filtering, segmentation, normalisation.

- ``gaps``: gap report and cubic-spline filling of short gaps (flagged);
- ``filtering``: zero-phase Butterworth low-pass, design/effective order conventions;
- ``segmentation``: pair recordings by table height, walking trials by CoM speed;
- ``pairs``: a pair recording checked against the pair protocol (carriages, return, end orientation, who
  holds which end of the table);
- ``normalisation``: resampling to N samples over 0..100 % (endpoints included);
- ``stage``: the ``preprocess`` stage tying them with ``cobot_analysis.kinematics``.
"""
