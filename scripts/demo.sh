#!/usr/bin/env bash
# The main job on the embedded default recording: installs what is needed, builds, and fits a vase (surface of
# revolution) jointly with the poses of the four views that recorded it (recordings/demo_vase).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install-deps.sh"
"$root/scripts/build.sh"
build="${S2M_BUILD_DIR:-$root/build}"
out="$build/demo"
mkdir -p "$out"
echo
"$build/apps/scan2model" fit --model revolution "$root/recordings/demo_vase/views.json" -o "$out/vase"
# The same result as a self-contained HTML report (docs/batch.md), and the vessel's profile drawing.
"$build/apps/scan2model" report "$out/vase.json" -o "$out/vase_report.html"
echo
echo "report: $out/vase_report.html (profile drawing: $out/vase_profile.svg)"
