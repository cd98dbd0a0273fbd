#!/usr/bin/env bash
# Coverage-guided fuzzing of every reader and parser (docs/reliability.md), under ASan + UBSan with libFuzzer.
#   scripts/fuzz.sh [TARGET|all] [SECONDS per target]      e.g. scripts/fuzz.sh point_cloud 600
# Builds the fuzz targets with clang into build-fuzz/ (S2M_FUZZ_BUILD_DIR), grows a working corpus per target in
# build-fuzz/corpus/<target>/ from the seeds (fuzz/corpus/<target>/ and the shipped files), and copies every crash,
# leak or timeout into tests/data/fuzz/<target>/, where ctest replays it in every build from then on.
# Exit status: 0 when no target found anything, 1 otherwise.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
target="${1:-all}"
seconds="${2:-60}"
build="${S2M_FUZZ_BUILD_DIR:-$root/build-fuzz}"

"$root/scripts/install-clang.sh"
"$root/scripts/install-deps.sh" >/dev/null

# S2M_FUZZ_KEEP_CONFIG=1: a build folder configured for fuzzing already (scripts/ci-sanitize.sh's, with tests).
if [ "${S2M_FUZZ_KEEP_CONFIG:-0}" != 1 ] || [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang \
    -DCMAKE_CXX_COMPILER=clang++ -DS2M_FUZZ=ON -DS2M_SANITIZE=address,undefined -DS2M_BUILD_TESTS=OFF \
    -DS2M_BUILD_BENCH=OFF >/dev/null
fi
all_targets=$(sed -n 's/^ *s2m_add_fuzz_target(\([a-z0-9_]*\) .*/\1/p' "$root/fuzz/CMakeLists.txt")
if [ "$target" = all ]; then targets=$all_targets; else targets=$target; fi
for t in $targets; do
  grep -qx "$t" <<<"$all_targets" || { echo "[fuzz] unknown target '$t' (targets: $(echo $all_targets))" >&2; exit 2; }
done
cmake --build "$build" -j"$(nproc)" --target $(for t in $targets; do printf '%s_fuzz ' "$t"; done) >/dev/null

found=0
# The targets write every input to a scratch file (fuzz/fuzz_input.h): in memory where the system has it, since
# rewriting a file on a disk mounted with `discard` costs milliseconds each (measured 3.6 ms against 0.03 ms).
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then export TMPDIR=/dev/shm; fi
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
for t in $targets; do
  corpus="$build/corpus/$t"
  findings="$build/findings/$t"
  mkdir -p "$corpus" "$findings"
  # An earlier run's artifacts were copied to tests/data/fuzz/<target>/ when it found them; left here they would
  # be reported again as this run's findings.
  rm -f "$findings"/crash-* "$findings"/leak-* "$findings"/timeout-* "$findings"/oom-*
  # libFuzzer takes only folders that exist: a target may have no seed folder (recordings are seeded with the
  # shipped recordings, copied into the working corpus) and no findings yet.
  seeds=()
  [ -d "$root/fuzz/corpus/$t" ] && seeds+=("$root/fuzz/corpus/$t")
  [ -d "$root/tests/data/fuzz/$t" ] && seeds+=("$root/tests/data/fuzz/$t")
  if [ "$t" = recording ]; then
    for r in "$root"/recordings/*.s2mrec; do [ -f "$r" ] && cp -n "$r" "$corpus/"; done
  fi
  dict=()
  [ -f "$root/fuzz/dict/$t.dict" ] && dict=(-dict="$root/fuzz/dict/$t.dict")
  echo "[fuzz] $t for ${seconds} s"
  # -malloc_limit_mb: an input that claims a huge size must be refused before allocating (docs/reliability.md).
  set +e
  "$build/fuzz/${t}_fuzz" "${dict[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -malloc_limit_mb=1024 -max_len=65536 -artifact_prefix="$findings/" -print_final_stats=1 \
    "$corpus" "${seeds[@]}" 2>"$findings/log.txt"
  status=$?
  set -e
  grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb" "$findings/log.txt" | sed "s/^/[fuzz] $t /" || true
  shopt -s nullglob
  artifacts=("$findings"/crash-* "$findings"/leak-* "$findings"/timeout-* "$findings"/oom-*)
  shopt -u nullglob
  if [ $status -ne 0 ] || [ ${#artifacts[@]} -gt 0 ]; then
    found=1
    mkdir -p "$root/tests/data/fuzz/$t"
    for a in "${artifacts[@]}"; do cp "$a" "$root/tests/data/fuzz/$t/"; done
    echo "[fuzz] $t: FINDING (exit $status); inputs copied to tests/data/fuzz/$t/, log in $findings/log.txt" >&2
  fi
done
exit $found
