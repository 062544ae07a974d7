"""UVW stage kinematics: exact inverse, numerical forward, the patent's decomposition of a move."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError, StageError
from kinid.stages.uvw import UVWGeometry, decompose_move, forward_kinematics, inverse_kinematics
from kinid.stages.uvw.kinematics import Pose, Strokes

GEOMETRIES = [UVWGeometry(a_mm=50.0, b_mm=50.0),
              UVWGeometry(a_mm=40.0, b_mm=-65.0, x1_offset_mm=12.0, x2_offset_mm=-7.5, y_offset_mm=9.0)]


@pytest.mark.parametrize("geometry", GEOMETRIES)
@settings(max_examples=200, deadline=None)
@given(x=st.floats(-5000, 5000), y=st.floats(-5000, 5000), theta=st.floats(-3.0, 3.0))
def test_round_trip_ik_fk(geometry, x, y, theta):
    s = inverse_kinematics(geometry, x, y, theta)
    p = forward_kinematics(geometry, s)
    assert p.x_um == pytest.approx(x, abs=1e-9)
    assert p.y_um == pytest.approx(y, abs=1e-9)
    assert p.theta_deg == pytest.approx(theta, abs=1e-12)
    # and back: the strokes of the recovered pose are the strokes we started from
    s2 = inverse_kinematics(geometry, p.x_um, p.y_um, p.theta_deg)
    assert (s2.x1_um, s2.x2_um, s2.y_um) == pytest.approx((s.x1_um, s.x2_um, s.y_um), abs=1e-9)


def test_inverse_kinematics_closed_form_values():
    g = UVWGeometry(a_mm=50.0, b_mm=60.0)
    s = inverse_kinematics(g, 100.0, -30.0, 0.0)
    assert (s.x1_um, s.x2_um, s.y_um) == (100.0, 100.0, -30.0)
    th = 0.5
    s = inverse_kinematics(g, 0.0, 0.0, th)
    expected = 50e3 * math.sin(math.radians(th))
    assert s.x1_um == pytest.approx(-expected, abs=1e-12)
    assert s.x2_um == pytest.approx(expected, abs=1e-12)
    assert s.y_um == pytest.approx(60e3 * math.sin(math.radians(th)), abs=1e-12)


def test_exact_not_small_angle():
    # at 2 degrees the pivot offsets make the cosine term matter (c (cos θ - 1) = -6 µm for c = 10 mm)
    g = UVWGeometry(a_mm=50.0, b_mm=50.0, x1_offset_mm=10.0, x2_offset_mm=10.0)
    s = inverse_kinematics(g, 0.0, 0.0, 2.0)
    assert s.x1_um + s.x2_um == pytest.approx(2 * 10e3 * (math.cos(math.radians(2.0)) - 1), abs=1e-9)
    assert s.x1_um + s.x2_um < -12.0


def test_rotation_decomposes_into_two_x_moves_and_one_y_move():
    g = UVWGeometry(a_mm=50.0, b_mm=50.0)
    m = decompose_move(g, Pose(200.0, 100.0, 0.0), Pose(200.0, 100.0, 0.05))
    assert m.x1_um < 0 < m.x2_um
    assert m.x1_um == pytest.approx(-m.x2_um, abs=1e-12)
    assert m.y_um == pytest.approx(m.x2_um, abs=1e-12)   # b = a
    t = decompose_move(g, Pose(0.0, 0.0, 0.0), Pose(1234.5, 0.0, 0.0))
    assert (t.x1_um, t.x2_um, t.y_um) == (1234.5, 1234.5, 0.0)
    assert Strokes(1.0, 2.0, 3.0).as_dict() == {"X1": 1.0, "X2": 2.0, "Y": 3.0}


def test_unreachable_strokes_and_bad_geometry():
    g = UVWGeometry(a_mm=1.0, b_mm=1.0)
    with pytest.raises(StageError, match="differ by 3000 µm, more than the pivot distance"):
        forward_kinematics(g, Strokes(-1500.0, 1500.0, 0.0))
    with pytest.raises(DataError, match="a_mm must be positive"):
        UVWGeometry(a_mm=0.0, b_mm=50.0)
    with pytest.raises(DataError, match="b_mm must be non-zero"):
        UVWGeometry(a_mm=50.0, b_mm=0.0)
    with pytest.raises(DataError, match="x1_offset_mm must be a finite number"):
        UVWGeometry(x1_offset_mm=float("nan"))
