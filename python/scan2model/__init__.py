"""scan2model: fits of models to point clouds, in-process (docs/python.md).

Points are N x 3 float64 NumPy arrays; a C-contiguous float64 array is read in place (no copy), any other
array-like is converted with a ConversionWarning. An Open3D point cloud passes as ``np.asarray(pcd.points)``.
Results carry ``to_dict()`` with the members of the JSON Schemas in docs/schemas/ (the command's --json output).
Errors raise scan2model.Error subclasses (UsageError, InputError, FitError) with the command's messages.
"""

from ._scan2model import (  # noqa: F401
    ConversionWarning,
    DetectResult,
    BatchResult,
    Error,
    FitError,
    FitResult,
    InputError,
    PrimitiveFitResult,
    RegistrationResult,
    Result,
    Scan,
    ScanSet,
    UsageError,
    __version__,
    describe,
    detect,
    fit,
    fit_circle,
    fit_cone,
    fit_cylinder,
    fit_line,
    fit_option_keys,
    fit_plane,
    fit_sphere,
    fit_torus,
    points_view,
    read_e57,
    read_point_cloud,
    read_recording,
    read_views,
    register_scans,
    report_html,
    run_batch,
    write_e57,
    write_json,
    write_ply,
    write_recording,
    write_report,
    write_views,
)

__all__ = [name for name in dir() if not name.startswith("_")] + ["__version__"]
