"""Kinematics on analytic cases: straight walk, circle, sideways step, pure rotation, table pose."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_analysis import kinematics as kin
from cobot_analysis.angles import angle_diff

RATE = 200.0
# pelvis geometry in the pelvis frame (x forward, y left, z up), barycentre at the origin
PELVIS = {"LASI": (0.08, 0.12, 0.0), "RASI": (0.08, -0.12, 0.0), "LPSI": (-0.08, 0.045, 0.02),
          "RPSI": (-0.08, -0.045, 0.02)}


def pelvis_markers(x, y, theta, z=0.95):
    """Marker positions (T, 3) of a rigid pelvis whose barycentre is (x, y, z) and heading theta."""
    x, y, theta = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, theta)))
    c, s = np.cos(theta), np.sin(theta)
    out = {}
    for name, (a, b, h) in PELVIS.items():
        out[name] = np.column_stack([x + c * a - s * b, y + s * a + c * b, np.full_like(x, z + h - 0.01)])
    return out


def kinematics_of(m):
    xy, rigid = kin.pelvis_com(m["LASI"], m["RASI"], m["LPSI"], m["RPSI"])
    theta = kin.pelvis_theta(m["LASI"], m["RASI"])
    v = kin.velocity(xy, RATE)
    return xy, rigid, theta, v, kin.gamma(theta, v)


def test_straight_walk_theta_constant_gamma_zero():
    t = np.arange(0, 3, 1 / RATE)
    x = 1.2 * t + 0.5
    xy, rigid, theta, v, g = kinematics_of(pelvis_markers(x, -1.0, 0.0))
    np.testing.assert_allclose(xy[:, 0], x, atol=1e-12)
    np.testing.assert_allclose(xy[:, 1], -1.0, atol=1e-12)
    np.testing.assert_allclose(theta, 0.0, atol=1e-12)
    np.testing.assert_allclose(v, np.column_stack([np.full_like(t, 1.2), np.zeros_like(t)]), atol=1e-9)
    np.testing.assert_allclose(g, 0.0, atol=1e-9)
    assert not rigid.any()


def test_straight_walk_along_any_heading():
    t = np.arange(0, 2, 1 / RATE)
    heading = 2.5
    m = pelvis_markers(np.cos(heading) * t, np.sin(heading) * t, heading)
    _, _, theta, _, g = kinematics_of(m)
    np.testing.assert_allclose(theta, heading, atol=1e-12)
    np.testing.assert_allclose(g, 0.0, atol=1e-9)


def test_circle_com_on_circle_gamma_zero_when_facing_tangent():
    t = np.arange(0, 6, 1 / RATE)
    r, w = 2.0, 0.8  # m, rad/s: counter-clockwise, more than half a turn past pi
    phi = w * t
    m = pelvis_markers(r * np.cos(phi), r * np.sin(phi), phi + np.pi / 2)
    xy, _, theta, v, g = kinematics_of(m)
    np.testing.assert_allclose(np.hypot(xy[:, 0], xy[:, 1]), r, atol=1e-12)
    np.testing.assert_allclose(theta, phi + np.pi / 2, atol=1e-12)  # unwrapped: grows past pi
    assert theta[-1] > np.pi
    np.testing.assert_allclose(np.hypot(*v.T)[1:-1], r * w, rtol=1e-4)
    np.testing.assert_allclose(g[1:-1], 0.0, atol=1e-4)


def test_sideways_step_gamma_is_minus_or_plus_half_pi():
    t = np.arange(0, 1, 1 / RATE)
    _, _, theta, _, g_left = kinematics_of(pelvis_markers(0.0, 0.4 * t, 0.0))  # moves to its left
    _, _, _, _, g_right = kinematics_of(pelvis_markers(0.0, -0.4 * t, 0.0))
    np.testing.assert_allclose(theta, 0.0, atol=1e-12)
    np.testing.assert_allclose(g_left, -np.pi / 2, atol=1e-9)  # gamma = theta - tangent = 0 - pi/2
    np.testing.assert_allclose(g_right, np.pi / 2, atol=1e-9)


def test_pure_rotation_com_fixed_theta_follows_gamma_undefined():
    t = np.arange(0, 5, 1 / RATE)
    heading = -np.pi + 1.5 * t  # more than a full turn
    xy, _, theta, v, g = kinematics_of(pelvis_markers(1.0, 2.0, heading))
    np.testing.assert_allclose(xy, np.tile([1.0, 2.0], (len(t), 1)), atol=1e-12)
    np.testing.assert_allclose(theta - theta[0], heading - heading[0], atol=1e-12)
    np.testing.assert_allclose(angle_diff(theta[0], heading[0]), 0.0, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-9)
    assert np.isnan(g).all()  # no tangent anywhere


def test_gamma_holds_ends_below_min_speed():
    t = np.arange(0, 4, 1 / RATE)
    tau = np.clip((t - 1) / 2, 0, 1)
    s = 2.0 * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)  # rest 1 s, walk 2 m in 2 s, rest 1 s
    theta = np.full_like(t, 0.3)
    v = kin.velocity(np.column_stack([s, np.zeros_like(s)]), RATE)
    g = kin.gamma(theta, v, min_speed=0.1)
    moving = np.hypot(*v.T) >= 0.1
    first, last = np.flatnonzero(moving)[[0, -1]]
    np.testing.assert_allclose(g, 0.3, atol=1e-12)  # tangent is +x throughout the walk
    assert g[0] == g[first] and g[-1] == g[last]
    # a heading change while standing: gamma keeps the value of the last moving instant
    theta2 = np.where(t > 3.5, 1.0, 0.3)
    g2 = kin.gamma(theta2, v, min_speed=0.1)
    assert g2[-1] == pytest.approx(0.3)


def test_rigid_fill_recovers_barycentre_with_one_marker_missing():
    t = np.arange(0, 2, 1 / RATE)
    m = pelvis_markers(0.7 * t, 0.2 * np.sin(t), 0.4 * t)
    truth, _ = kin.pelvis_com(*(m[k] for k in ("LASI", "RASI", "LPSI", "RPSI")))
    for k, gap in (("LPSI", slice(50, 150)), ("LASI", slice(200, 260))):
        m[k] = m[k].copy()
        m[k][gap] = np.nan
    xy, rigid = kin.pelvis_com(m["LASI"], m["RASI"], m["LPSI"], m["RPSI"])
    np.testing.assert_allclose(xy, truth, atol=1e-9)
    assert rigid[50:150].all() and rigid[200:260].all() and rigid.sum() == 160
    # two markers missing at once: no position there
    m["RASI"] = m["RASI"].copy()
    m["RASI"][100:110] = np.nan
    xy, _ = kin.pelvis_com(m["LASI"], m["RASI"], m["LPSI"], m["RPSI"])
    assert np.isnan(xy[100:110]).all() and not np.isnan(xy[110:150]).any()


def test_theta_is_nan_where_an_asis_marker_is_missing_and_unwraps_across():
    t = np.arange(0, 4, 1 / RATE)
    heading = 2.0 * t
    m = pelvis_markers(0.0, 0.0, heading)
    m["LASI"][300:320] = np.nan
    theta = kin.pelvis_theta(m["LASI"], m["RASI"])
    assert np.isnan(theta[300:320]).all()
    ok = ~np.isnan(theta)
    np.testing.assert_allclose(theta[ok], heading[ok], atol=1e-12)


def test_unwrap_nan_matches_numpy_without_nan():
    a = np.angle(np.exp(1j * np.linspace(0, 20, 300)))
    np.testing.assert_allclose(kin.unwrap_nan(a), np.unwrap(a))


LENGTH, WIDTH = 1.22, 0.80


def table_corners(x, y, theta, z, mirrored=False):
    """TAB1 at a corner, TAB2 along the long side, TAB3 along the short side (either side)."""
    side = -1.0 if mirrored else 1.0
    local = {"TAB1": (-LENGTH / 2, -side * WIDTH / 2), "TAB2": (LENGTH / 2, -side * WIDTH / 2),
             "TAB3": (-LENGTH / 2, side * WIDTH / 2)}
    c, s = np.cos(theta), np.sin(theta)
    return [np.array([[x + c * a - s * b, y + s * a + c * b, z]]) for a, b in local.values()]


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-10, 10), y=st.floats(-10, 10), theta=st.floats(-np.pi, np.pi), z=st.floats(0.5, 1.2),
       mirrored=st.booleans())
def test_table_pose_from_corners_any_rigid_motion(x, y, theta, z, mirrored):
    corners = table_corners(x, y, theta, z, mirrored)
    xy, th = kin.table_pose(*corners)
    np.testing.assert_allclose(xy[0], [x, y], atol=1e-9)
    assert abs(angle_diff(th[0], theta)) < 1e-9
    assert kin.table_height(*corners)[0] == pytest.approx(z)


def test_table_theta_unwrapped_over_a_turn_and_height_through_a_gap():
    t = np.arange(0, 3, 1 / RATE)
    theta = 3.0 * t
    frames = [table_corners(np.cos(k), np.sin(k), th, 0.9) for k, th in zip(t, theta)]
    tab = [np.concatenate([f[i] for f in frames]) for i in range(3)]
    _, th = kin.table_pose(*tab)
    np.testing.assert_allclose(th - th[0], theta - theta[0], atol=1e-9)
    tab[1][10:20] = np.nan
    h = kin.table_height(*tab)
    np.testing.assert_allclose(h, 0.9)
