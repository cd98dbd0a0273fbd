#!/usr/bin/env bash
# The main job on the embedded default recordings: installs what is needed, builds, fits a vase (surface of
# revolution) jointly with the poses of the four views that recorded it (recordings/demo_vase), and runs the full
# pipeline on the pot recording (recordings/pot.s2mrec: a virtual Kinect-class camera around a pot on a turntable):
# replay, outlier removal and normals (PCL), then the joint fit. Builds only the command it runs (the tests and
# benchmarks are built by scripts/test.sh and scripts/bench.sh; README "Two commands" has the times).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install-deps.sh"
"$root/scripts/build.sh" --target scan2model
build="${S2M_BUILD_DIR:-$root/build}"
out="$build/demo"
mkdir -p "$out"
echo
"$build/apps/scan2model" fit --model revolution "$root/recordings/demo_vase/views.json" -o "$out/vase"
# The same result as a self-contained HTML report (docs/batch.md), and the vessel's profile drawing.
"$build/apps/scan2model" report "$out/vase.json" -o "$out/vase_report.html"
echo
"$build/apps/scan2model" export "$root/recordings/pot.s2mrec" -o "$out/pot_views" --remove-outliers \
  --outlier-stddev 3 --normals -q
"$build/apps/scan2model" fit --model revolution "$out/pot_views/views.json" -o "$out/pot"
echo
echo "report: $out/vase_report.html (profile drawing: $out/vase_profile.svg)"
