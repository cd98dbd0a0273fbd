// Scans, sets of views and their files in Python: point clouds (PLY, PCD, XYZ, NIST .ds, E57), views
// manifests, recordings (.s2mrec) and E57 files with several posed scans (docs/python.md).
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <filesystem>

#include "acquisition/e57_io.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "acquisition/scan_set_io.h"
#include "pipeline/output.h"
#include "pipeline/views.h"
#include "python/bindings.h"
#include "python/json_object.h"
#include "python/points.h"

namespace s2m::python {

ScanSet Views::ToScanSet() const {
  ScanSet set;
  set.name = name;
  set.scans.reserve(scans.size());
  for (const auto& scan : scans) set.scans.push_back(*scan);
  return set;
}

Views Views::FromScanSet(ScanSet&& set) {
  Views views;
  views.name = std::move(set.name);
  for (Scan& scan : set.scans) views.scans.push_back(std::make_shared<Scan>(std::move(scan)));
  return views;
}

bool IsPathLike(py::handle object) {
  return py::isinstance<py::str>(object) || py::hasattr(object, "__fspath__");
}

std::string PathArg(py::handle object, const char* what) {
  if (!IsPathLike(object)) {
    throw py::type_error(std::string(what) + ": expected a path (str or os.PathLike), got " +
                         std::string(py::str(py::type::handle_of(object).attr("__name__"))));
  }
  return py::str(py::module_::import("os").attr("fspath")(object)).cast<std::string>();
}

namespace {

RigidMotion PoseArg(const Eigen::Matrix4d& m) {
  if (!m.allFinite()) throw py::value_error("world_T_scan: the 4 x 4 pose has a NaN or inf");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const double orthogonality = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality > 1e-9 || r.determinant() < 0 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 0) {
    throw py::value_error(
        "world_T_scan: not a rigid motion (the rotation must be orthonormal with determinant +1 within 1e-9, "
        "the last row 0 0 0 1)");
  }
  return RigidMotion::FromMatrix(m);
}

std::shared_ptr<Scan> NewScan(py::handle points, py::handle normals, const std::string& units,
                              const std::optional<Eigen::Matrix4d>& world_T_scan) {
  auto scan = std::make_shared<Scan>();
  scan->points = CopyPoints(points, "points");
  if (!normals.is_none()) {
    scan->normals = CopyPoints(normals, "normals");
    if (scan->normals.cols() != scan->points.cols()) {
      throw py::value_error("normals: " + std::to_string(scan->normals.cols()) + " normals for " +
                            std::to_string(scan->points.cols()) + " points");
    }
  }
  scan->units = units;
  if (world_T_scan) scan->world_T_scan = PoseArg(*world_T_scan);
  return scan;
}

Views ViewsArg(py::handle object) {
  if (py::isinstance<Views>(object)) return object.cast<Views>();
  Views views;
  for (const py::handle item : object) {
    if (!py::isinstance<Scan>(item)) throw py::type_error("views: expected a ScanSet or a list of Scan");
    views.scans.push_back(item.cast<std::shared_ptr<Scan>>());
  }
  return views;
}

E57CoordinateEncoding CoordinateEncoding(const std::string& name) {
  if (name == "float64") return E57CoordinateEncoding::kFloat64;
  if (name == "float32") return E57CoordinateEncoding::kFloat32;
  if (name == "scaled-integer") return E57CoordinateEncoding::kScaledInteger;
  throw std::invalid_argument("coordinates: '" + name + "' is not one of float64, float32, scaled-integer");
}

}  // namespace

void BindIo(py::module_& m) {
  py::class_<Scan, std::shared_ptr<Scan>>(
      m, "Scan",
      "One view: points (and optional normals) in the scanner's own coordinates, the pose world_T_scan that "
      "places them in the world, the units, and what the source said about them. `points` and `normals` are "
      "N x 3 float64 arrays over the scan's own memory (no copy; writes go through).")
      .def(py::init(&NewScan), py::arg("points"), py::arg("normals") = py::none(),
           py::arg("units") = "unknown", py::arg("world_T_scan") = py::none(),
           "A scan of the given points (copied into the scan; any N x 3 array-like), unit normals, units "
           "('mm', 'm', ...) and 4 x 4 pose (identity when omitted).")
      .def_property(
          "points", [](py::object self) { return MatrixView(self.cast<Scan&>().points, self); },
          [](Scan& s, py::handle points) {
            Eigen::Matrix3Xd copy = CopyPoints(points, "points");
            if (s.normals.cols() != 0 && s.normals.cols() != copy.cols()) s.normals.resize(3, 0);
            s.points = std::move(copy);
          },
          "N x 3 float64 view of the points (scan coordinates); assigning copies (and drops normals of "
          "another "
          "count).")
      .def_property(
          "normals", [](py::object self) { return MatrixView(self.cast<Scan&>().normals, self); },
          [](Scan& s, py::handle normals) {
            if (normals.is_none()) {
              s.normals.resize(3, 0);
              return;
            }
            Eigen::Matrix3Xd copy = CopyPoints(normals, "normals");
            if (copy.cols() != s.points.cols())
              throw py::value_error("normals: " + std::to_string(copy.cols()) + " normals for " +
                                    std::to_string(s.points.cols()) + " points");
            s.normals = std::move(copy);
          },
          "N x 3 float64 view of the unit normals, or a 0 x 3 array when the scan has none.")
      .def_property(
          "world_T_scan", [](const Scan& s) { return Eigen::Matrix4d(s.world_T_scan.matrix()); },
          [](Scan& s, const Eigen::Matrix4d& pose) { s.world_T_scan = PoseArg(pose); },
          "The 4 x 4 pose mapping scan coordinates to world coordinates (a copy; assign to change it).")
      .def_readwrite("units", &Scan::units, "'mm', 'm', ... as the source declared them, or 'unknown'.")
      .def_property_readonly(
          "source", [](const Scan& s) { return s.metadata.source; }, "Where the scan came from.")
      .def_property_readonly(
          "device", [](const Scan& s) { return s.metadata.device; },
          "The device that recorded it, or 'file'.")
      .def_property_readonly(
          "notes", [](const Scan& s) { return s.metadata.notes; }, "What the reader did to the data.")
      .def(
          "world_points", [](const Scan& s) { return MatrixArray(s.WorldPoints()); },
          "The points mapped into the world frame (a new N x 3 array).")
      .def("__len__", [](const Scan& s) { return s.size(); })
      .def("__repr__", [](const Scan& s) {
        return "<scan2model.Scan " + std::to_string(s.size()) + " points, units " + s.units +
               (s.has_normals() ? ", normals" : "") + ">";
      });

  py::class_<Views>(
      m, "ScanSet",
      "Several views of one part, each a Scan with its pose (a views manifest, a recording, an E57 "
      "file). Indexing gives the Scan itself (its arrays are views of its memory).")
      .def(py::init([](const std::vector<std::shared_ptr<Scan>>& scans, const std::string& name) {
             Views v;
             v.name = name;
             for (const auto& s : scans) {
               if (!s) throw py::type_error("ScanSet: None is not a Scan");
               v.scans.push_back(s);
             }
             return v;
           }),
           py::arg("scans") = std::vector<std::shared_ptr<Scan>>{}, py::arg("name") = "")
      .def_readwrite("name", &Views::name)
      .def("__len__", [](const Views& v) { return v.scans.size(); })
      .def("__getitem__",
           [](const Views& v, py::ssize_t k) {
             const auto n = static_cast<py::ssize_t>(v.scans.size());
             if (k < 0) k += n;
             if (k < 0 || k >= n) throw py::index_error("ScanSet index out of range");
             return v.scans[static_cast<std::size_t>(k)];
           })
      .def(
          "__iter__", [](const Views& v) { return py::make_iterator(v.scans.begin(), v.scans.end()); },
          py::keep_alive<0, 1>())
      .def(
          "append",
          [](Views& v, const std::shared_ptr<Scan>& s) {
            if (!s) throw py::type_error("ScanSet.append: None is not a Scan");
            v.scans.push_back(s);
          },
          py::arg("scan"))
      .def(
          "total_points", [](const Views& v) { return v.ToScanSet().TotalPoints(); },
          "Points over all views.")
      .def(
          "merged_points", [](const Views& v) { return MatrixArray(v.ToScanSet().MergedWorldPoints()); },
          "All views' points in the world frame, as one new N x 3 array.")
      .def("__repr__", [](const Views& v) {
        std::size_t points = 0;
        for (const auto& s : v.scans) points += static_cast<std::size_t>(s->size());
        return "<scan2model.ScanSet '" + v.name + "' " + std::to_string(v.scans.size()) + " views, " +
               std::to_string(points) + " points>";
      });

  m.def(
      "read_point_cloud",
      [](py::handle path) {
        const std::string file = PathArg(path, "path");
        py::gil_scoped_release release;
        return std::make_shared<Scan>(ReadPointCloud(file));
      },
      py::arg("path"),
      "Reads a point cloud: PLY (ASCII/binary, .ply.gz), PCD, XYZ/CSV text, NIST .ds, or E57 (every scan "
      "placed "
      "by its pose, as one cloud). Raises InputError naming the file, the line or byte, and the problem.");
  m.def(
      "read_views",
      [](py::handle path) {
        const std::string file = PathArg(path, "path");
        ScanSet set;
        {
          py::gil_scoped_release release;
          set = pipeline::ReadViews(file);
        }
        return Views::FromScanSet(std::move(set));
      },
      py::arg("path"),
      "Reads the views of a multi-view input as `scan2model fit` does: a views manifest (.json), Stanford "
      ".conf, recording (.s2mrec) replayed through the frame path, E57 file (each scan a view with its "
      "pose), "
      "or one point cloud (one view).");
  m.def(
      "read_e57",
      [](py::handle path) {
        const std::string file = PathArg(path, "path");
        ScanSet set;
        {
          py::gil_scoped_release release;
          set = ReadE57ScanSet(file);
        }
        return Views::FromScanSet(std::move(set));
      },
      py::arg("path"), "Reads an E57 file (ASTM E2807): every data3D scan a view with its pose (metres).");
  m.def(
      "write_e57",
      [](py::handle path, py::handle views, const std::string& coordinates, double coordinate_scale) {
        const std::string file = PathArg(path, "path");
        const ScanSet set = ViewsArg(views).ToScanSet();
        E57WriteOptions options;
        options.coordinates = CoordinateEncoding(coordinates);
        options.coordinate_scale = coordinate_scale;
        py::gil_scoped_release release;
        WriteE57(file, set, options);
      },
      py::arg("path"), py::arg("views"), py::arg("coordinates") = "float64",
      py::arg("coordinate_scale") = 1e-5,
      "Writes the views as an E57 file, each a scan with its pose; units must be a length (m, cm, mm, um). "
      "coordinates: float64 (exact), float32, or scaled-integer (steps of coordinate_scale metres).");
  m.def(
      "read_recording",
      [](py::handle path, const std::string& stream) {
        const std::string file = PathArg(path, "path");
        ScanSet set;
        {
          py::gil_scoped_release release;
          set = ReadRecording(file, stream);
        }
        return Views::FromScanSet(std::move(set));
      },
      py::arg("path"), py::arg("stream") = "",
      "Reads a recording's points stream (docs/recordings.md): one view per frame with its pose. stream: the "
      "stream's name (empty: the only points stream). Depth and profile streams: read_views replays them.");
  m.def(
      "write_recording",
      [](py::handle path, py::handle views, const std::string& stream) {
        const std::string file = PathArg(path, "path");
        const ScanSet set = ViewsArg(views).ToScanSet();
        py::gil_scoped_release release;
        WriteRecording(file, set, stream);
      },
      py::arg("path"), py::arg("views"), py::arg("stream") = "points",
      "Writes the views as a recording (.s2mrec): one points frame per view with its pose; never "
      "overwrites.");
  m.def(
      "write_views",
      [](py::handle path, py::handle views) {
        const std::string file = PathArg(path, "path");
        const ScanSet set = ViewsArg(views).ToScanSet();
        py::gil_scoped_release release;
        WriteScanSet(file, set);
      },
      py::arg("path"), py::arg("views"),
      "Writes a views manifest (scan2model.views/1) and one PLY per view beside it.");
  m.def(
      "write_ply",
      [](py::handle path, const Scan& scan) {
        const std::string file = PathArg(path, "path");
        py::gil_scoped_release release;
        WritePly(file, scan);
      },
      py::arg("path"), py::arg("scan"), "Writes a scan as binary PLY (points, normals when present).");
  m.def(
      "describe",
      [](const Scan& scan, const std::string& name, const std::string& format) {
        return ToPython(pipeline::DescribeScan(scan, name, format));
      },
      py::arg("scan"), py::arg("name") = "", py::arg("format") = "memory",
      "The `input` member of fit/1 and detect/1 for a scan: points, normals, units, bounds, centroid, pose.");
  m.def(
      "points_view", [](py::handle points) { return PointsArg(points, "points").array(); }, py::arg("points"),
      "The N x 3 float64 array the fits read for `points`: the array itself when it is N x 3 float64 "
      "C-contiguous (no copy), a Scan's points in place, else a converted copy (with a ConversionWarning). "
      "Convert once with it to fit the same points many times without copies.");
}

}  // namespace s2m::python
