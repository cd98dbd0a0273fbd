#!/usr/bin/env bash
# The sanitizer stage of CI (.ci/run runs it after the normal tests; its time on 2 cores: docs/reliability.md):
# one clang build with ASan + UBSan and libFuzzer's coverage instrumentation serves both
#   1. the tests of every reader, writer and fault path, and the fuzz corpus replays, under the sanitizers, and
#   2. a short coverage-guided pass over every fuzz target (S2M_CI_FUZZ_SECONDS each, default 20).
# The whole suite under the sanitizers is `scripts/sanitize.sh` (it does not fit CI's time limit beside the
# normal build and tests on 2 cores). Exit status: non-zero on any test failure, sanitizer report or fuzz finding.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${S2M_CI_SANITIZE_BUILD_DIR:-$root/build-ci-sanitize}"
seconds="${S2M_CI_FUZZ_SECONDS:-20}"
start=$(date +%s)

"$root/scripts/install-clang.sh"
"$root/scripts/install-deps.sh" >/dev/null

# The test programs of the readers, writers and fault paths (each a ctest group of its own test cases). The
# numerical core's own tests are the whole-suite run's (scripts/sanitize.sh): unoptimized, as built here,
# they would take most of CI's margin.
tests=(point_cloud_io_test scan_set_io_test part_file_test e57_io_test mesh_io_test depth_frame_test recording_test
  frame_source_test io_fault_test)
selected=()
for t in "${tests[@]}"; do
  [ -f "$root/tests/$t.cpp" ] && selected+=("$t")
done
fuzz_targets=$(sed -n 's/^ *s2m_add_fuzz_target(\([a-z0-9_]*\) .*/\1/p' "$root/fuzz/CMakeLists.txt")

# Unoptimized with line tables only (S2M_CI_SANITIZE_FLAGS; build type None adds no flags of its own): the
# build is most of this stage's time, and clang compiles the Eigen-heavy core much faster than optimized
# with full debug information (docs/reliability.md); the reports still name file and line.
flags="${S2M_CI_SANITIZE_FLAGS:--O0 -gline-tables-only}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=None -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DS2M_FUZZ=ON -DS2M_SANITIZE=address,undefined -DS2M_BUILD_TESTS=ON -DS2M_BUILD_BENCH=OFF >/dev/null
built_targets=()
known=$(cmake --build "$build" --target help)
for t in "${selected[@]}" $(for f in $fuzz_targets; do echo "${f}_fuzz"; done) scan2model io_fault_shim; do
  # Targets the configuration left out (an optional dependency missing) are skipped, not failed.
  if grep -qx "\.\.\. $t" <<<"$known"; then built_targets+=("$t"); fi
done
echo "[ci-sanitize] building ${#built_targets[@]} targets with clang, ASan + UBSan"
cmake --build "$build" -j"$(nproc)" --target "${built_targets[@]}" >/dev/null
echo "[ci-sanitize] built after $(($(date +%s) - start)) s"

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# Each test program's discovered cases carry its name as a label (tests/CMakeLists.txt); the corpus replays "fuzz".
labels="fuzz"
for t in "${built_targets[@]}"; do
  case "$t" in *_test) labels+="|$t" ;; esac
done
# The cases that run whole joint fits through the command take minutes each unoptimized (the E57 file's fit of
# the vase, a recording's fit): what they read is tested by the other cases, and their fits by the whole-suite run.
slow_fits="E57Io.CommandFitsAJointModelToTheScansOfAnE57File|Recording.CliInfoAndFitReadARecording"
status=0
(cd "$build" && ctest --output-on-failure -j"$(nproc)" -L "^($labels)\$" -E "^($slow_fits)\$") || status=1
echo "[ci-sanitize] sanitizer tests done after $(($(date +%s) - start)) s"

S2M_FUZZ_BUILD_DIR="$build" S2M_FUZZ_KEEP_CONFIG=1 "$root/scripts/fuzz.sh" all "$seconds" || status=1
echo "[ci-sanitize] total $(($(date +%s) - start)) s"
exit $status
