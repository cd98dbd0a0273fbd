#!/usr/bin/env bash
# Builds the benchmarks (Release) and runs them: the side-by-side comparisons (build/bench/compare: markdown
# tables on standard output, CSV in build/bench/compare.csv) and the micro-benchmarks (foot points per second
# per core, assembly throughput: build/bench/micro_benchmarks.csv). Arguments go to compare, e.g.
# `scripts/bench.sh --quick` for a smoke test in seconds. The full run takes about 6 minutes on 2 idle cores (12 under load).
# docs/benchmarks.md holds one run's tables and the machine it ran on.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${S2M_BUILD_DIR:-$root/build}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target compare micro_benchmarks
# OpenMP threads wait passively: a spinning wait steals the core another library's thread needs.
export OMP_WAIT_POLICY=PASSIVE
"$build/bench/compare" --csv "$build/bench/compare.csv" "$@"
echo
echo "## Micro-benchmarks (one thread; items_per_second = foot points or assembled points per second per core)"
echo
min_time=1
for a in "$@"; do [ "$a" = "--quick" ] && min_time=0.05; done
"$build/bench/micro_benchmarks" --benchmark_min_time="$min_time" --benchmark_out="$build/bench/micro_benchmarks.csv" \
  --benchmark_out_format=csv
