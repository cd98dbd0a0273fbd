#!/usr/bin/env bash
# The main job on the embedded default input: installs what is needed, builds, and fits a cylinder to the
# NIST reference data set cyl1 (500 points), comparing the result with the certified reference fit.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install-deps.sh"
"$root/scripts/build.sh"
build="${S2M_BUILD_DIR:-$root/build}"
echo
"$build/apps/scan2model" fit --model cylinder "$root/tests/data/nist/cyl1.ds" \
  --reference "$root/tests/data/nist/cyl1.fit"
