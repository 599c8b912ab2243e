"""Localisation accuracy of an on-board LiDAR/ICP pose against motion capture (docs/methods.md sec. 9).

Data flow: ``bags`` (read pose streams) -> ``compare`` (time base, delay, offset, errors, drift) ->
``goals`` (stops and goal accuracy) -> ``report`` (tables, figures, results fragment); ``synth``
writes a synthetic run with known answers.
"""
