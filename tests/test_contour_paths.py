"""Contour error against circles, lines and polylines; ISO 230-4 G, F, H on tracks with known deviations."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError
from kinid.stages.contour.paths import (CirclePath, LinePath, PolylinePath, circular_test, contour_error, fit_circle,
                                  fit_line, load_polyline, travel_direction)


def circle_track(radius_mm, dev_um, phi, centre=(0.0, 0.0)):
    r = radius_mm + np.asarray(dev_um) * 1e-3
    return np.column_stack([centre[0] + r * np.cos(phi), centre[1] + r * np.sin(phi)])


@settings(max_examples=40, deadline=None)
@given(cx=st.floats(-100, 100), cy=st.floats(-100, 100), r=st.floats(0.5, 200), start=st.floats(0, 6.28),
       arc=st.floats(1.0, 6.28))
def test_fit_circle_exact_on_any_arc(cx, cy, r, start, arc):
    phi = start + np.linspace(0, arc, 25)
    (fx, fy), fr = fit_circle(circle_track(r, 0.0, phi, (cx, cy)))
    assert fx == pytest.approx(cx, abs=1e-7 * max(r, 1))
    assert fy == pytest.approx(cy, abs=1e-7 * max(r, 1))
    assert fr == pytest.approx(r, rel=1e-9)


def test_radial_deviation_positive_outward_and_nan_rows_kept():
    phi = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    dev = 3.0 * np.cos(2 * phi)  # orthogonal to a centre shift: the LSQ circle is the nominal one
    xy = circle_track(25.0, dev, phi, (-25.0, 0.0))
    xy[7] = np.nan
    ce = contour_error(xy, CirclePath())
    assert np.isnan(ce.error_um[7])
    keep = np.arange(40) != 7
    # one missing point moves the LSQ circle a little: compare with the given-circle error
    exact = contour_error(xy, CirclePath((-25.0, 0.0), 25.0))
    np.testing.assert_allclose(exact.error_um[keep], dev[keep], atol=1e-9)
    np.testing.assert_allclose(ce.error_um[keep], dev[keep], atol=0.3)
    assert ce.path.radius_mm == pytest.approx(25.0, abs=1e-3)
    assert exact.rms_um == pytest.approx(np.sqrt(np.mean(dev[keep] ** 2)))
    assert exact.max_um == pytest.approx(np.max(np.abs(dev[keep])))


def test_circle_with_given_radius_fits_only_the_centre():
    phi = np.linspace(0, 2 * np.pi, 36, endpoint=False)
    xy = circle_track(10.0, 0.0, phi, (3.0, -2.0))
    ce = contour_error(xy, CirclePath(None, 10.002))
    assert ce.path.centre_mm == pytest.approx((3.0, -2.0), abs=1e-9)
    np.testing.assert_allclose(ce.error_um, -2.0, atol=1e-7)


def test_line_error_sign_is_right_of_travel_in_image_axes():
    x = np.linspace(0, 50, 11)
    off_um = np.array([0, 1, -1, 2, 0, 0, 3, -2, 0, 1, 0], float)
    xy = np.column_stack([x, off_um * 1e-3])  # +y is down in the image: right of travel towards +x
    ce = contour_error(xy, LinePath((0.0, 0.0), (50.0, 0.0)))
    np.testing.assert_allclose(ce.error_um, off_um, atol=1e-9)
    back = contour_error(xy[::-1], LinePath((50.0, 0.0), (0.0, 0.0)))
    np.testing.assert_allclose(back.error_um, -off_um[::-1], atol=1e-9)
    start, end = fit_line(np.column_stack([x, 0.5 * x]))
    assert start == pytest.approx((0.0, 0.0), abs=1e-9) and end == pytest.approx((50.0, 25.0))


def test_polyline_error_uses_nearest_segment():
    square = ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 0.0))
    pts = np.array([[5.0, 0.002], [10.003, 5.0], [5.0, 9.999], [-0.004, 5.0]])
    ce = contour_error(pts, PolylinePath(square))
    # travelling clockwise as seen in the image (x right, y down): the inside is to the right
    np.testing.assert_allclose(ce.error_um, [2.0, -3.0, 1.0, -4.0], atol=1e-9)


def test_iso_230_4_g_f_h_on_known_deviations():
    n = 180
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    a_um, h_um, R = 4.0, 2.5, 50.0
    fwd = circle_track(R, a_um * np.cos(2 * phi) + h_um / 2, phi)
    back = circle_track(R, a_um * np.cos(2 * phi[::-1]) - h_um / 2, phi[::-1])
    xy = np.vstack([fwd, back])
    dirs = travel_direction(xy, (0.0, 0.0))
    assert set(dirs[:n - 1]) == {1} and set(dirs[n:]) == {-1}
    test = circular_test(xy, nominal_radius_mm=R - 0.001)
    assert test.centre_mm == pytest.approx((0.0, 0.0), abs=1e-9)
    assert test.radius_mm == pytest.approx(R, abs=1e-9)
    assert test.G_by_direction_um["+"] == pytest.approx(2 * a_um, abs=1e-3)
    assert test.G_by_direction_um["-"] == pytest.approx(2 * a_um, abs=1e-3)
    assert test.G_um == pytest.approx(2 * a_um, abs=1e-3)
    assert test.F_max_um == pytest.approx(a_um + h_um / 2 + 1.0, abs=1e-3)
    assert test.F_min_um == pytest.approx(-a_um - h_um / 2 + 1.0, abs=1e-3)
    assert test.H_um == pytest.approx(h_um, abs=0.05)
    one_way = circular_test(fwd)
    assert np.isnan(one_way.H_um) and list(one_way.G_by_direction_um) == ["+"]


def test_fit_circle_rejects_degenerate_input():
    with pytest.raises(DataError, match="at least 3 located points, got 2"):
        fit_circle([[0, 0], [1, 1], [np.nan, 0]])
    with pytest.raises(DataError, match="lie on a line"):
        fit_circle(np.column_stack([np.arange(5.0), 2 * np.arange(5.0)]))


def test_load_polyline(tmp_path):
    f = tmp_path / "path.csv"
    f.write_text("# square\nx_mm,y_mm\n0,0\n10,0\n10,10\n")
    assert load_polyline(f) == ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0))
    f.write_text("x_mm,y\n0,0\n1,1\n")
    with pytest.raises(DataError, match="missing column y_mm"):
        load_polyline(f)
    f.write_text("x_mm,y_mm\n0,0\n1,abc\n")
    with pytest.raises(DataError, match=r"path.csv:3, column 'y_mm': 'abc' is not a number"):
        load_polyline(f)
    f.write_text("x_mm,y_mm\n0,0\n")
    with pytest.raises(DataError, match="at least 2 vertices, got 1"):
        load_polyline(f)
