"""Recordings and E57 files through Python, the round trip E57 -> Python -> fit -> JSON, and errors as exceptions
with the command's messages."""

import json
import os
import subprocess

import numpy as np
import pytest
import scan2model

from conftest import sphere_points


def test_recording_round_trip(tmp_path, source_dir):
    # The pot's depth frames replayed into posed views (the frame path of `fit`), written as a points recording.
    pot = scan2model.read_views(source_dir / "recordings" / "pot.s2mrec")
    assert len(pot) == 8 and all(len(v) > 0 for v in pot)
    scan2model.write_recording(tmp_path / "copy.s2mrec", pot)
    back = scan2model.read_recording(tmp_path / "copy.s2mrec")
    assert len(back) == len(pot)
    for a, b in zip(pot, back):
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.world_T_scan, b.world_T_scan)
    with pytest.raises(scan2model.InputError, match="copy.s2mrec"):  # a recording is never overwritten
        scan2model.write_recording(tmp_path / "copy.s2mrec", pot)
    with pytest.raises(scan2model.InputError, match="pot.s2mrec"):  # depth frames only: no points stream
        scan2model.read_recording(source_dir / "recordings" / "pot.s2mrec")


def test_e57_files(tmp_path, source_dir):
    e57 = source_dir / "tests" / "data" / "e57"
    mixed = scan2model.read_e57(e57 / "cartesian_mixed.e57")
    assert len(mixed) >= 1 and all(v.units == "m" for v in mixed)
    with pytest.raises(scan2model.InputError, match="unknown_codec.e57") as error:
        scan2model.read_e57(e57 / "unknown_codec.e57")
    assert error.value.exit_code == 3


def test_round_trip_e57_python_fit_json(tmp_path):
    """Two posed scans of a sphere (mm) -> E57 (metres) -> Python -> fit -> JSON, and the command on the same file."""
    points = sphere_points(600, centre=(100.0, 50.0, 20.0), radius=30.0, noise=0.01)
    pose = np.eye(4)
    pose[:3, 3] = [5.0, -2.0, 1.0]
    first = scan2model.Scan(points[:300], units="mm")
    second = scan2model.Scan(points[300:] - pose[:3, 3], units="mm", world_T_scan=pose)  # in its own frame
    scan2model.write_e57(tmp_path / "sphere.e57", scan2model.ScanSet([first, second], "sphere"))

    views = scan2model.read_e57(tmp_path / "sphere.e57")
    assert len(views) == 2 and views[0].units == "m"
    np.testing.assert_allclose(views[1].world_T_scan[:3, 3], pose[:3, 3] / 1000, atol=1e-15)
    np.testing.assert_allclose(views[1].world_points(), points[300:] / 1000, atol=1e-15)

    result = scan2model.fit(views, "sphere", name=str(tmp_path / "sphere.e57"))
    assert result.parameters["radius"] == pytest.approx(0.030, abs=1e-5)
    assert result.to_dict()["input"]["units"] == "m"
    scan2model.write_json(result, tmp_path / "sphere.json")
    document = json.loads((tmp_path / "sphere.json").read_text())
    assert document == json.loads(result.to_json())
    assert document["parameters"]["center"] == pytest.approx([0.1, 0.05, 0.02], abs=1e-5)

    cli = os.environ.get("S2M_CLI")
    if cli:  # the command reads the same file into the same fit
        out = subprocess.run([cli, "fit", "--model", "sphere", "--json", str(tmp_path / "sphere.e57")],
                             capture_output=True, text=True, check=True)
        command = json.loads(out.stdout)
        assert command["parameters"]["radius"] == pytest.approx(document["parameters"]["radius"], rel=1e-12)
        assert command["parameters"]["center"] == pytest.approx(document["parameters"]["center"], rel=1e-12)


def test_errors_carry_the_commands_messages(tmp_path):
    missing = tmp_path / "nowhere.ply"
    with pytest.raises(scan2model.InputError) as error:
        scan2model.fit(missing, "sphere")
    assert error.value.exit_code == 3 and str(missing) in str(error.value)
    assert isinstance(error.value, OSError) and isinstance(error.value, scan2model.Error)
    cli = os.environ.get("S2M_CLI")
    if cli:
        out = subprocess.run([cli, "fit", "--model", "sphere", str(missing)], capture_output=True, text=True)
        assert out.returncode == error.value.exit_code
        assert str(error.value) in out.stderr

    with pytest.raises(scan2model.UsageError, match="cube"):
        scan2model.fit(sphere_points(10), "cube")
    with pytest.raises(scan2model.UsageError, match="unknown option 'frobnicate'"):
        scan2model.fit(sphere_points(10), "sphere", frobnicate=1)
    with pytest.raises(scan2model.UsageError, match="max_iterations"):
        scan2model.fit(sphere_points(10), "sphere", max_iterations="many")
    with pytest.raises(ValueError):  # a UsageError is a ValueError
        scan2model.fit_sphere(sphere_points(10), method="xyz")
    with pytest.raises(scan2model.FitError, match="at least 4 points") as error:
        scan2model.fit_sphere(sphere_points(3))
    assert error.value.exit_code == 4
    with pytest.raises(scan2model.FitError, match="coincide"):
        scan2model.fit_sphere(np.ones((10, 3)))
    nan = sphere_points(10)
    nan[3, 1] = np.nan
    with pytest.raises(scan2model.Error):
        scan2model.fit(nan, "sphere")
    with pytest.raises(TypeError):
        scan2model.read_point_cloud(42)

    corrupt = tmp_path / "corrupt.ply"
    corrupt.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty double x\n")
    with pytest.raises(scan2model.InputError, match="corrupt.ply"):
        scan2model.read_point_cloud(corrupt)
    with pytest.raises(scan2model.UsageError, match="not a result of scan2model fit"):
        scan2model.report_html({"schema": "something/1"})
