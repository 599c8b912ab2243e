"""The API as a notebook meets it: options given as the command line's text or as Python lists, bad options
and misplaced tables refused with one ``InputError`` naming the option (never a ``TypeError`` from deep
inside pandas or numpy, never a silent empty or wrong result), and the published pair study's relative pose
taken as ``import_published`` gives it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import cobot_analysis.api as ca
from cobot_analysis.errors import InputError
from cobot_analysis.synth.tables import pair_table, walking_table


def test_localise_takes_one_bag_and_names_unknown_options(tmp_path):
    """A single path was iterated ('r: no such file', or "'PosixPath' object is not iterable"); an unknown
    option was a TypeError, a tuple ``delay_window`` an AttributeError."""
    from cobot_analysis.localisation import synth

    bag = synth.write_ros1(synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)), tmp_path / "run.bag")
    one = ca.localise(str(bag), delay=0.55, delay_window=(0.0, 1.5))
    listed = ca.localise([bag], delay=0.55)
    pd.testing.assert_frame_equal(one.runs, listed.runs, check_exact=True)
    with pytest.raises(InputError, match=r"^unknown localise option\(s\) \['tol'\]"):
        ca.localise(bag, tol=0.1)
    with pytest.raises(InputError, match=r"^--min-samples must be >= 3, got 0"):
        ca.localise(bag, min_samples=0)
