"""Camera/laser offsets against synthetic truth, exact and with noise."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError
from kinid.vision.laser_offsets import (
    axial_offset,
    focus_height,
    focus_measure,
    radial_offset_from_hole,
)
from kinid.vision.laser_shapes import radial_offset_from_edges, radial_offset_from_sphere

# the laser sits 12.4 mm in +x and 3.1 mm in -y of the camera's optical axis, 4.75 mm higher
OFFSET = np.array([12.4, -3.1, 4.75])
N_TRIALS = 200


def _coverage(errors, sigmas):
    """Fraction of trials whose error lies within 3 standard deviations."""
    return np.mean(np.abs(np.asarray(errors)) <= 3 * np.asarray(sigmas))


# --- hole ---------------------------------------------------------------------------------------

def test_hole_exact():
    hole_cam = np.array([40.0, 25.0])
    r = radial_offset_from_hole(hole_cam + OFFSET[:2], hole_cam)
    assert (r.dx_mm, r.dy_mm) == pytest.approx(tuple(OFFSET[:2]), abs=1e-12)
    assert math.isnan(r.dz_mm) and r.method == "hole"
    assert all(math.isnan(s) for s in r.sigma)  # one reading each, no repeatability given


def test_hole_noise_covered_at_3_sigma():
    rng = np.random.default_rng(1)
    hole_cam = np.array([40.0, 25.0])
    err, sig = [], []
    for _ in range(N_TRIALS):
        laser = hole_cam + OFFSET[:2] + rng.normal(0, 0.004, (5, 2))
        camera = hole_cam + rng.normal(0, 0.002, (4, 2))
        r = radial_offset_from_hole(laser, camera)
        err.append([r.dx_mm - OFFSET[0], r.dy_mm - OFFSET[1]])
        sig.append(r.sigma[:2])
    assert _coverage(err, sig) > 0.97
    # the reported sigma is the spread of the estimate: sqrt(0.004^2/5 + 0.002^2/4)
    assert np.median(np.asarray(sig)) == pytest.approx(math.sqrt(0.004 ** 2 / 5 + 0.002 ** 2 / 4), rel=0.2)


def test_hole_sigma_from_given_repeatability():
    r = radial_offset_from_hole([52.4, 21.9], [40.0, 25.0], sigma_mm=0.003)
    assert r.sigma[0] == pytest.approx(0.003 * math.sqrt(2)) and r.sigma[1] == pytest.approx(0.003 * math.sqrt(2))


# --- sphere -------------------------------------------------------------------------------------

def _sphere_points(rng, centre, radius, standoff, n=40, max_polar_deg=60.0, noise=0.0):
    polar = np.radians(rng.uniform(0, max_polar_deg, n))
    azim = rng.uniform(0, 2 * np.pi, n)
    normal = np.column_stack([np.sin(polar) * np.cos(azim), np.sin(polar) * np.sin(azim), np.cos(polar)])
    surface = centre + radius * normal
    machine = surface + np.array([0.0, 0.0, standoff])  # the laser reads `standoff` above the surface
    return machine + rng.normal(0, noise, machine.shape) if noise else machine


def test_sphere_exact():
    rng = np.random.default_rng(2)
    centre = np.array([110.0, -35.0, -12.0])  # ball centre as found by the laser (machine frame)
    pts = _sphere_points(rng, centre, 6.35, 30.0)
    camera = centre[:2] - OFFSET[:2]
    r = radial_offset_from_sphere(pts, 30.0, camera)
    assert (r.dx_mm, r.dy_mm) == pytest.approx(tuple(OFFSET[:2]), abs=1e-9)
    assert r.feature_mm == pytest.approx(tuple(centre), abs=1e-9)
    assert r.radius_mm == pytest.approx(6.35, abs=1e-9)
    assert r.residual_rms_mm < 1e-9


@pytest.mark.parametrize("known_radius", [False, True])
def test_sphere_noise_covered_at_3_sigma(known_radius):
    rng = np.random.default_rng(3)
    centre = np.array([110.0, -35.0, -12.0])
    err, sig = [], []
    for _ in range(N_TRIALS):
        pts = _sphere_points(rng, centre, 6.35, 30.0, n=25, noise=0.003)
        r = radial_offset_from_sphere(pts, 30.0, centre[:2] - OFFSET[:2],
                                      radius_mm=6.35 if known_radius else None)
        err.append([r.dx_mm - OFFSET[0], r.dy_mm - OFFSET[1]])
        sig.append(r.sigma[:2])
    assert _coverage(err, sig) > 0.97
    assert np.sqrt(np.mean(np.square(err))) < 0.003  # the fit averages the laser noise down


def test_sphere_camera_repeats_add_to_sigma():
    rng = np.random.default_rng(4)
    centre = np.array([0.0, 0.0, 0.0])
    pts = _sphere_points(rng, centre, 5.0, 20.0, noise=0.002)
    one = radial_offset_from_sphere(pts, 20.0, [-12.4, 3.1])
    many = radial_offset_from_sphere(pts, 20.0, [[-12.401, 3.1], [-12.399, 3.102], [-12.4, 3.098]])
    assert many.sigma[0] > one.sigma[0] > 0


def test_sphere_rejects_degenerate_points():
    ring = np.column_stack([np.cos(np.linspace(0, 6, 12)), np.sin(np.linspace(0, 6, 12)), np.zeros(12)])
    with pytest.raises(DataError, match="do not fix a sphere"):
        radial_offset_from_sphere(ring, 0.0, [0.0, 0.0])
    with pytest.raises(DataError, match="at least 5 points"):
        radial_offset_from_sphere(ring[:4] + [0, 0, 1], 0.0, [0.0, 0.0])
    with pytest.raises(DataError, match=r"must have shape \(3,\) or \(N, 3\) in mm, got shape \(6, 2\)"):
        radial_offset_from_sphere(np.zeros((6, 2)), 0.0, [0.0, 0.0])
    with pytest.raises(DataError, match="radius_mm must be positive"):
        radial_offset_from_sphere(ring + [0, 0, 1], 0.0, [0.0, 0.0], radius_mm=-1)


# --- two edges ----------------------------------------------------------------------------------

def _edge_points(rng, corner, angle_deg, n, noise=0.0, start=1.0, length=15.0):
    d = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    t = np.sort(rng.uniform(start, length, n))
    pts = corner + t[:, None] * d
    return pts + rng.normal(0, noise, pts.shape) if noise else pts


def test_edges_exact():
    rng = np.random.default_rng(5)
    corner = np.array([80.0, 60.0])  # where the laser sees the corner
    e1 = _edge_points(rng, corner, 10.0, 12)
    e2 = _edge_points(rng, corner, 95.0, 9)
    r = radial_offset_from_edges(e1, e2, corner - OFFSET[:2])
    assert (r.dx_mm, r.dy_mm) == pytest.approx(tuple(OFFSET[:2]), abs=1e-9)
    assert r.feature_mm == pytest.approx(tuple(corner), abs=1e-9)
    assert r.method == "edges" and r.n_points == 21


def test_edges_noise_covered_at_3_sigma():
    rng = np.random.default_rng(6)
    corner = np.array([80.0, 60.0])
    err, sig = [], []
    for _ in range(N_TRIALS):
        e1 = _edge_points(rng, corner, -20.0, 10, noise=0.005)
        e2 = _edge_points(rng, corner, 60.0, 10, noise=0.005)
        r = radial_offset_from_edges(e1, e2, corner - OFFSET[:2])
        err.append([r.dx_mm - OFFSET[0], r.dy_mm - OFFSET[1]])
        sig.append(r.sigma[:2])
    assert _coverage(err, sig) > 0.97
    assert np.median(np.asarray(sig)) < 0.01


@settings(max_examples=25, deadline=None)
@given(turn_deg=st.floats(-180, 180), shift=st.tuples(st.floats(-200, 200), st.floats(-200, 200)))
def test_property_edges_rotate_and_translate_with_the_layout(turn_deg, shift):
    rng = np.random.default_rng(7)
    corner = np.array([5.0, 5.0])
    e1 = _edge_points(rng, corner, 30.0, 8, noise=0.01)
    e2 = _edge_points(rng, corner, 140.0, 8, noise=0.01)
    camera = np.array([1.0, 2.0])
    base = radial_offset_from_edges(e1, e2, camera)
    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    rot = np.array([[c, -s], [s, c]])
    moved = radial_offset_from_edges(e1 @ rot.T + shift, e2[::-1] @ rot.T + shift, camera @ rot.T + shift)
    expected = rot @ [base.dx_mm, base.dy_mm]
    assert (moved.dx_mm, moved.dy_mm) == pytest.approx(tuple(expected), abs=1e-8)
    assert moved.residual_rms_mm == pytest.approx(base.residual_rms_mm, rel=1e-6)


def test_edges_reject_parallel_and_short():
    rng = np.random.default_rng(8)
    e1 = _edge_points(rng, np.zeros(2), 0.0, 6)
    with pytest.raises(DataError, match="edges meet at 5.0 deg; need at least 10"):
        radial_offset_from_edges(e1, _edge_points(rng, np.zeros(2), 5.0, 6), [0.0, 0.0])
    with pytest.raises(DataError, match="edge2_points_xy_mm needs at least 3 points"):
        radial_offset_from_edges(e1, e1[:2] @ [[0, 1], [1, 0]], [0.0, 0.0])


# --- axial --------------------------------------------------------------------------------------

def test_axial_exact_with_reading_correction():
    focus_z = 50.0
    height = 30.0
    # laser at its preset height sits at focus_z + 4.75; readings taken slightly off the preset
    laser_z = np.array([54.70, 54.80, 54.75])
    reading = height + (laser_z - (focus_z + OFFSET[2]))
    r = axial_offset(focus_z, reading, laser_z_mm=laser_z, laser_height_mm=height)
    assert r.dz_mm == pytest.approx(OFFSET[2], abs=1e-12)
    assert math.isnan(r.dx_mm) and math.isnan(r.dy_mm) and r.method == "axial"
    assert r.sigma[2] == pytest.approx(0.0, abs=1e-12)


def test_axial_noise_covered_at_3_sigma():
    rng = np.random.default_rng(9)
    err, sig = [], []
    for _ in range(N_TRIALS):
        # sigma comes from the scatter of the readings: with n readings the error over sigma is
        # Student-t distributed, so take enough (n = 12: P(|t| < 3) = 0.99) for a 97 % check
        focus = 50.0 + rng.normal(0, 0.01, 12)  # focus judgement is the weak part
        laser_z = 54.75 + rng.normal(0, 0.05, 12)
        reading = 30.0 + (laser_z - 54.75) + rng.normal(0, 0.001, 12)
        r = axial_offset(focus, reading, laser_z_mm=laser_z, laser_height_mm=30.0)
        err.append(r.dz_mm - OFFSET[2])
        sig.append(r.sigma[2])
    assert _coverage(err, sig) > 0.97


def test_axial_rejects_mismatched_lengths():
    with pytest.raises(DataError, match="laser_z_mm has 2 values but laser_reading_mm has 3"):
        axial_offset(50.0, [30.0, 30.1, 29.9], laser_z_mm=[54.7, 54.8], laser_height_mm=30.0)
    with pytest.raises(DataError, match="camera_focus_z_mm must be one or more finite numbers"):
        axial_offset([], [30.0], laser_z_mm=[54.7], laser_height_mm=30.0)


def test_focus_height_from_rendered_sweep():
    import cv2

    rng = np.random.default_rng(10)
    base = rng.integers(0, 256, (64, 64)).astype(np.float64)
    base = cv2.GaussianBlur(base, (0, 0), 1.0)
    z0, depth = 12.34, 0.5  # best focus and the defocus blur growth (px per mm)
    z = np.linspace(11.0, 14.0, 31)
    sharp = [focus_measure(cv2.GaussianBlur(base, (0, 0), 0.3 + abs(zz - z0) / depth)) for zz in z]
    f = focus_height(z, sharp, n_fit=5)
    assert f.found and f.z_mm == pytest.approx(z0, abs=0.05) and f.sigma_mm < 0.05
    edge = focus_height(z[:12], sharp[:12])
    assert not edge.found and "sweep" in edge.reason and math.isnan(edge.z_mm)


def test_focus_height_rejects_bad_input():
    with pytest.raises(DataError, match="sharpness must be positive"):
        focus_height([1, 2, 3, 4, 5], [1, 2, 0, 2, 1])
    with pytest.raises(DataError, match="z_mm has 3 values but sharpness has 2"):
        focus_height([1, 2, 3], [1, 2])


def test_bad_shapes_name_the_argument():
    with pytest.raises(DataError, match=r"laser_xy_mm must have shape \(2,\) or \(N, 2\)"):
        radial_offset_from_hole([1.0, 2.0, 3.0], [0.0, 0.0])
    with pytest.raises(DataError, match="camera_xy_mm holds a non-finite value"):
        radial_offset_from_hole([1.0, 2.0], [np.nan, 0.0])
    with pytest.raises(DataError, match="sigma_mm must be a non-negative number"):
        radial_offset_from_hole([1.0, 2.0], [0.0, 0.0], sigma_mm=-1)
