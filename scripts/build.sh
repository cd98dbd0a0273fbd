#!/usr/bin/env bash
# Configures and builds scan2model (Release) into build/: every target, or only those given with --target
# (e.g. `scripts/build.sh --target scan2model`, what scripts/demo.sh runs). Other arguments go to CMake's
# configure step.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${S2M_BUILD_DIR:-$root/build}"
configure=()
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --target) targets+=(--target "$2"); shift 2 ;;
    *) configure+=("$1"); shift ;;
  esac
done
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release "${configure[@]}" >/dev/null
cmake --build "$build" -j"$(nproc)" "${targets[@]}"
