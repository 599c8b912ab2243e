"""Angles: ``wrap`` takes the mod only where it changes a value, and gives the mod's bits everywhere (NaN payloads too)."""

from __future__ import annotations

import numpy as np
import pytest

from cobot_analysis.angles import angle_diff, wrap


def mod_wrap(a):
    """``wrap``'s formula with the mod taken everywhere."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2 * np.pi)


def test_wrap_is_the_mod_formula_bit_for_bit():
    rng = np.random.default_rng(0)
    nans = list(np.array([0x7FF8000000000000, 0xFFF8000000000000, 0x7FF8000000000123, 0xFFF8000000000123], dtype=np.uint64).view(float))
    edges = [0.0, -0.0, np.pi, -np.pi, 2 * np.pi, -2 * np.pi, 3 * np.pi, 1e300, -1e300, 5e-324, -5e-324,
             np.nextafter(np.pi, 0), np.nextafter(np.pi, 4), np.nextafter(-np.pi, 0), np.nextafter(-np.pi, -4), *nans]
    for a in (np.array(edges), rng.normal(0, 0.3, 5000), rng.uniform(-20, 20, (50, 40)), rng.uniform(-20, 20, (50, 40))[:, ::3],
              np.pi + rng.normal(0, 1e-13, 1000), -np.pi + rng.normal(0, 1e-13, 1000), np.arange(-20, 20)):
        w = wrap(a)
        assert w.dtype == np.float64 and w.shape == np.shape(a)
        np.testing.assert_array_equal(w.view(np.int64), mod_wrap(a).view(np.int64))
        assert ((w >= -np.pi) & (w <= np.pi) | np.isnan(w)).all()  # -pi: a = pi + 1 ulp, the mod rounds to 2 pi
    for x in edges:  # scalars stay scalars
        assert np.float64(wrap(x)).view(np.int64) == np.float64(mod_wrap(x)).view(np.int64)
        assert np.ndim(wrap(x)) == 0


def test_wrap_values():
    np.testing.assert_array_equal(wrap([np.pi, -np.pi, 3 * np.pi / 2, -3 * np.pi / 2, 0.0]),
                                  [np.pi, np.pi, -np.pi / 2, np.pi / 2, 0.0])
    assert angle_diff(np.pi - 0.01, -np.pi + 0.01) == pytest.approx(-0.02, abs=1e-14)  # across the cut
