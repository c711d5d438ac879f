"""Direction vectors, angle conventions and poses (theory §2)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorgym.trackers.geometry import (
    R_YUP_FROM_ZUP,
    angles_from_unit,
    look_at_rotation,
    pixel_from_unit,
    relative_pose,
    unit_from_angles,
    unit_from_pixel,
    unit_from_zup_angles,
    wrap_angle,
    yup_from_zup,
    zup_angles_from_unit,
    zup_from_yup,
)

angles = st.floats(-3.0, 3.0, allow_nan=False)
elevations = st.floats(-1.5, 1.5, allow_nan=False)


def test_unit_from_angles_matches_paper_formula():
    phi, theta = np.deg2rad(30.0), np.deg2rad(10.0)
    a = unit_from_angles(phi, theta)
    # a = (cos θ sin φ, sin θ, cos θ cos φ)   (000 eq. 2)
    expected = [np.cos(theta) * np.sin(phi), np.sin(theta), np.cos(theta) * np.cos(phi)]
    np.testing.assert_allclose(a, expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(unit_from_angles(0.0, 0.0), [0.0, 0.0, 1.0])  # boresight is Z
    np.testing.assert_allclose(unit_from_angles(0.0, np.pi / 2), [0.0, 1.0, 0.0], atol=1e-16)


@settings(max_examples=200, deadline=None)
@given(angles, elevations)
def test_angles_round_trip(phi, theta):
    a = unit_from_angles(phi, theta)
    phi2, theta2 = angles_from_unit(a)
    assert abs(wrap_angle(phi2 - phi)) < 1e-9
    assert abs(theta2 - theta) < 1e-9


@pytest.mark.parametrize("inverted", [True, False])
def test_pixel_round_trip_and_sign(inverted):
    x, y, f = np.array([120.0, -40.0]), np.array([-15.0, 60.0]), 800.0
    a = unit_from_pixel(x, y, f, inverted=inverted)
    sign = -1.0 if inverted else 1.0
    v = np.stack([sign * x, sign * y, np.full(2, f)], -1)
    np.testing.assert_allclose(a, v / np.linalg.norm(v, axis=-1, keepdims=True), atol=1e-15)
    x2, y2 = pixel_from_unit(a, f, inverted=inverted)
    np.testing.assert_allclose(x2, x, rtol=1e-12)
    np.testing.assert_allclose(y2, y, rtol=1e-12)
    # azimuth from pixels: φ = atan(±x/f)   (000 eq. 3)
    np.testing.assert_allclose(angles_from_unit(a)[0], np.arctan(sign * x / f), rtol=1e-12)


def test_pixel_per_receiver_sign_flag_broadcasts():
    a = unit_from_pixel([10.0, 10.0], [5.0, 5.0], 100.0, inverted=[True, False])
    np.testing.assert_allclose(a[0, :2], -a[1, :2])


def test_zup_frame_adapter_is_a_proper_rotation_and_keeps_elevation():
    assert np.isclose(np.linalg.det(R_YUP_FROM_ZUP), 1.0)
    az, el = np.deg2rad(25.0), np.deg2rad(12.0)
    u = unit_from_zup_angles(az, el)
    np.testing.assert_allclose(zup_angles_from_unit(u), (az, el), atol=1e-15)
    a = yup_from_zup(u)
    phi, theta = angles_from_unit(a)
    # same elevation; azimuth changes sign because 000's +X points left (right-handed, Y up)
    np.testing.assert_allclose(theta, el, atol=1e-15)
    np.testing.assert_allclose(phi, -az, atol=1e-15)
    np.testing.assert_allclose(zup_from_yup(a), u, atol=1e-15)
    # forward and up axes agree between the frames
    np.testing.assert_allclose(yup_from_zup([0.0, 1.0, 0.0]), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(yup_from_zup([0.0, 0.0, 1.0]), [0.0, 1.0, 0.0])


def test_wrap_angle_range():
    x = np.linspace(-20, 20, 1001)
    w = wrap_angle(x)
    assert np.all((w >= -np.pi) & (w < np.pi))
    np.testing.assert_allclose(np.sin(w), np.sin(x), atol=1e-12)
    np.testing.assert_allclose(np.cos(w), np.cos(x), atol=1e-12)


def test_relative_pose_maps_points_into_frame_one(rng):
    o = rng.normal(size=(4, 3)) * 50
    R = look_at_rotation(o, rng.normal(size=(4, 3)))
    M_world = rng.normal(size=3) * 30
    # M_k = R_kᵀ (M − o_k)
    M_local = np.einsum("kji,kj->ki", R, M_world - o)
    P, b = relative_pose(R[:1], o[:1], R[1:], o[1:])
    # M_1 = P_k M_k + b_k   (theory §2.1)
    np.testing.assert_allclose(
        np.einsum("kij,kj->ki", P, M_local[1:]) + b, np.tile(M_local[0], (3, 1)), atol=1e-10
    )


def test_look_at_rotation_is_right_handed_with_boresight_on_target(rng):
    o = rng.normal(size=(10, 3))
    t = rng.normal(size=(10, 3)) + 5
    R = look_at_rotation(o, t)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    z = (t - o) / np.linalg.norm(t - o, axis=-1, keepdims=True)
    np.testing.assert_allclose(R[..., :, 2], z, atol=1e-12)
    assert np.all(R[..., 1, 1] >= 0)  # receiver Y has a non-negative world-up component


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="azimuth"):
        unit_from_angles(np.nan, 0.0)
    with pytest.raises(ValueError, match="a: contains a zero-length"):
        angles_from_unit([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="unit length"):
        angles_from_unit([1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="f: focal length"):
        unit_from_pixel(1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="up: parallel"):
        look_at_rotation([0, 0, 0], [0, 5, 0])
    with pytest.raises(ValueError, match=r"R1: expected shape \(\.\.\., 3, 3\)"):
        relative_pose(np.eye(2), [0, 0, 0], np.eye(3), [1, 0, 0])
    with pytest.raises(ValueError, match="not in front of the camera"):
        pixel_from_unit([0.0, 0.0, -1.0], 100.0)


def test_atan2_near_stays_within_its_bound():
    from sensorgym.trackers.geometry_kernels import ATAN2_NEAR_ERROR, atan2_near

    rng = np.random.default_rng(7)
    x = np.exp(rng.uniform(-25, 25, 200_000))
    ratio = np.concatenate([
        np.exp(rng.uniform(-30, 30, 100_000)),  # every scale of |y|/x
        rng.uniform(0.0, 2.0, 100_000),  # dense where the reduction switches at 1
    ])  # fmt: skip
    y = ratio * x * rng.choice([-1.0, 1.0], x.size)
    edges = np.array([0.0, -0.0, 1.0, -1.0, 1e-300, 1e300])  # y/x exactly 0, ±1, extremes
    x = np.concatenate([x, np.ones(edges.size)])
    y = np.concatenate([y, edges])
    near = np.array([atan2_near(a, b) for a, b in zip(y, x, strict=True)])
    err = np.abs(near - np.arctan2(y, x))
    # a tenth of the bound the scanning kernel's pixel test relies on
    assert err.max() < ATAN2_NEAR_ERROR / 10
    assert err.max() > 0.0  # an approximation, not libm
