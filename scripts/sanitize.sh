#!/usr/bin/env bash
# The whole test suite under sanitizers (docs/reliability.md).
#   scripts/sanitize.sh [address,undefined|thread] [ctest arguments...]
# Builds into build-<sanitizers>/ (S2M_SANITIZE_BUILD_DIR) without the benchmarks and runs ctest there; any
# sanitizer report fails the test that triggered it (no recovery). S2M_SANITIZE_TARGETS="a_test b_test": build
# only those programs (and the command) and run only their cases (ctest -L, each program's label).
# ThreadSanitizer: Debian's libgomp is not built with it, so OpenMP's own synchronization would be reported;
# the thread runs set OMP_THREAD_LIMIT=1 (no OpenMP team is started, whatever omp_set_num_threads asks) and
# check the threads of our own: the batch pool, the recording writer and readers, the USB event thread.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
sanitizers="${1:-address,undefined}"
shift || true
build="${S2M_SANITIZE_BUILD_DIR:-$root/build-${sanitizers//,/-}}"
"$root/scripts/install-deps.sh" >/dev/null
# RelWithDebInfo: optimized as the product is, with line numbers in the reports.
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DS2M_SANITIZE="$sanitizers" \
  -DS2M_BUILD_BENCH=OFF >/dev/null
labels=()
if [ -n "${S2M_SANITIZE_TARGETS:-}" ]; then
  read -r -a targets <<<"$S2M_SANITIZE_TARGETS"
  cmake --build "$build" -j"$(nproc)" --target "${targets[@]}" scan2model
  labels=(-L "^($(IFS='|'; echo "${targets[*]}"))\$")
else
  cmake --build "$build" -j"$(nproc)"
fi
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$root/scripts/lsan-suppressions.txt}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export TSAN_OPTIONS="${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=$root/scripts/tsan-suppressions.txt}"
case "$sanitizers" in *thread*) export OMP_NUM_THREADS=1 OMP_THREAD_LIMIT=1 ;; esac
cd "$build"
ctest --output-on-failure -j"$(nproc)" "${labels[@]}" "$@"
