"""Points between NumPy and the core: read in place (the buffer's address), converted with a warning otherwise."""

import gc
import warnings

import numpy as np
import pytest
import scan2model

from conftest import sphere_points


def address(a):
    return a.__array_interface__["data"][0]


def test_float64_c_contiguous_is_read_in_place():
    a = sphere_points(100)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ConversionWarning
        view = scan2model.points_view(a)
        scan2model.fit_sphere(a)
    assert address(view) == address(a)
    assert view.base is a or view is a


@pytest.mark.parametrize(
    "make, what",
    [
        (lambda a: a.astype(np.float32), "float32"),
        (lambda a: np.asfortranarray(a), "not C-contiguous"),
        (lambda a: np.repeat(a, 2, axis=0)[::2], "not C-contiguous"),
        (lambda a: np.round(a * 1000).astype(np.int64), "int64"),
    ],
)
def test_other_arrays_are_converted_with_a_note(make, what):
    a = make(sphere_points(100))
    with pytest.warns(scan2model.ConversionWarning, match=what):
        view = scan2model.points_view(a)
    assert address(view) != address(a)
    assert view.dtype == np.float64 and view.flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(view, np.asarray(a, dtype=np.float64))
    with pytest.warns(scan2model.ConversionWarning):
        r = scan2model.fit_sphere(a)
    expected = scan2model.fit_sphere(np.ascontiguousarray(a, dtype=np.float64))
    assert r.parameters["radius"] == expected.parameters["radius"]


def test_lists_are_converted_without_warning():
    points = sphere_points(20).tolist()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        view = scan2model.points_view(points)
    np.testing.assert_array_equal(view, np.array(points))


@pytest.mark.parametrize("shape", [(10, 2), (3,), (2, 3, 3)])
def test_wrong_shapes_raise(shape):
    with pytest.raises(ValueError, match=r"points: expected an N x 3 array"):
        scan2model.fit_sphere(np.zeros(shape))


def test_scan_points_are_views_of_the_scan(nist_dir):
    scan = scan2model.read_point_cloud(nist_dir / "sph1.ds")
    p1, p2 = scan.points, scan.points
    assert p1.shape == (len(scan), 3) and p1.dtype == np.float64
    assert address(p1) == address(p2)
    assert address(scan2model.points_view(scan)) == address(p1)  # the fits read the scan's own memory
    original = p1[0, 0]
    p1[0, 0] = 12345.0  # writes go through
    assert scan.points[0, 0] == 12345.0
    p1[0, 0] = original


def test_arrays_keep_their_scan_alive(nist_dir):
    points = scan2model.read_point_cloud(nist_dir / "sph1.ds").points
    gc.collect()
    expected = np.loadtxt(nist_dir / "sph1.ds", skiprows=1)
    np.testing.assert_array_equal(points, expected)


def test_scan_from_numpy_copies_into_the_scan():
    a = sphere_points(50)
    scan = scan2model.Scan(a, units="mm")
    assert address(scan.points) != address(a)  # a Scan owns its points (documented)
    np.testing.assert_array_equal(scan.points, a)
    assert scan.units == "mm" and scan.normals.shape == (0, 3)
    np.testing.assert_array_equal(scan.world_T_scan, np.eye(4))


def test_scan_rejects_a_pose_that_is_not_rigid():
    scan = scan2model.Scan(sphere_points(10))
    with pytest.raises(ValueError, match="not a rigid motion"):
        scan.world_T_scan = np.diag([2.0, 1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="normals for"):
        scan2model.Scan(sphere_points(10), normals=np.zeros((9, 3)))


def test_open3d_point_cloud_through_asarray():
    o3d = pytest.importorskip("open3d")
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(sphere_points(200))
    r = scan2model.fit_sphere(np.asarray(pcd.points))
    assert r.parameters["radius"] == pytest.approx(3.0, abs=1e-9)
