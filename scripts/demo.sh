#!/usr/bin/env bash
# The main job on the embedded default recording: installs what is needed, builds, and fits a vase (surface of
# revolution) jointly with the poses of the four views that recorded it (recordings/demo_vase).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install-deps.sh"
"$root/scripts/build.sh"
build="${S2M_BUILD_DIR:-$root/build}"
echo
"$build/apps/scan2model" fit --model revolution "$root/recordings/demo_vase/views.json"
