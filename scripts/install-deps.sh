#!/usr/bin/env bash
# Installs the Debian 12 packages scan2model needs. Idempotent, non-interactive; run as root (or with sudo available).
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev          # maths core
  libcgal-dev            # maths core, header-only: the FE surface's parameter-domain triangulation (CGAL's
                         # constrained Delaunay mesher, fitting/domain_triangulation.cpp, docs/fe-surfaces.md)
  nlohmann-json3-dev     # --json output, manifests
  libcli11-dev           # command line
  zlib1g-dev             # .ply.gz
  libsqlite3-dev         # recordings (.s2mrec, docs/recordings.md)
  libpugixml-dev         # E57 files' XML section (acquisition/e57_io.cpp, docs/e57.md)
  libgtest-dev libgmock-dev
  libbenchmark-dev
  libpcl-dev             # optional edge (s2m_pcl): PCL's reference ICP, coarse alignment (FPFH + RANSAC)
  pybind11-dev python3-dev python3-numpy  # the Python module (python/, docs/python.md)
  python3-pytest         # tests only: the Python module's tests (tests/python)
  python3-scipy          # bench only: SciPy's Clough-Tocher interpolant, a baseline of bench/fe_surfaces.cpp
  dpkg-dev               # the .deb (cpack -G DEB): dpkg-shlibdeps names the Debian packages it depends on
  python3-jsonschema     # tests only: docs/schemas/ validated against real outputs (tests/json_schemas_test.py)
  libtiff-dev            # tests only: libtiff decodes the Kinect depth TIFFs independently of our reader
  libopen3d-dev          # optional edge (s2m_virtual_scanner): the virtual scanner's ray casting (RaycastingScene) and the
                         # benchmark's Open3D point-to-plane ICP baseline (bench/open3d_baselines.cpp)
  libopenmpi-dev openmpi-bin  # optional: `scan2model batch` under mpirun (docs/batch.md)
  libopencv-dev          # optional edge (s2m_horus): the Horus laser scanner's camera (V4L2), laser-line triangulation
                         # and chessboard calibration (devices/opencv_camera.cpp, laser_line.cpp, horus_calibration.cpp)
  chromium               # tests only: the HTML report opens in headless Chromium (tests/report_test.cpp)
  libusb-1.0-0-dev       # optional edge (s2m_usb): USB transport and the Horus turntable board (docs/devices.md)
  umockdev libumockdev-dev  # tests only: the emulated USB board (tests/emulated_horus_board.h, umockdev-wrapper)
  libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev
                         # bench only (optional): OpenCASCADE's variational curve smoothing, the fair-curve
                         # benchmark's baseline (bench/occt_curve_baseline.cpp, docs/fair-curves.md)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "[install-deps] all ${#packages[@]} packages present"
  exit 0
fi

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "[install-deps] not root and no sudo: install ${missing[*]} by hand" >&2; exit 1; }
  sudo_cmd=(sudo)
fi
echo "[install-deps] installing: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
