#!/usr/bin/env bash
# `cmake --install` into a fresh prefix, then a project outside the tree (tests/consumer) find_package()s the
# installed scan2model, builds against it and fits a sphere (docs/install.md). Also checks that the prefix holds
# the command, the headers, the Python package and the config with its version file.
#   install_consumer_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build="$1"
source="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" >/dev/null
for f in bin/scan2model include/scan2model/fitting/primitive_fit.h; do
  [ -e "$prefix/$f" ] || { echo "missing after install: $f" >&2; exit 1; }
done
config="$(find "$prefix" -name scan2modelConfig.cmake)"
[ -n "$config" ] && [ -e "$(dirname "$config")/scan2modelConfigVersion.cmake" ] &&
  [ -e "$(dirname "$config")/scan2modelTargets.cmake" ] || { echo "missing: the CMake package files" >&2; exit 1; }
"$prefix/bin/scan2model" --version
if [ -d "$build/python/scan2model" ]; then
  module="$(find "$prefix" -path '*/dist-packages/scan2model/_scan2model*.so')"
  [ -n "$module" ] || { echo "missing after install: the Python module" >&2; exit 1; }
  python="${S2M_TEST_PYTHON:-/usr/bin/python3}"
  PYTHONPATH="$(dirname "$(dirname "$module")")" "$python" -c \
    'import scan2model, numpy as np
p = np.random.default_rng(1).normal(size=(50, 3))
r = scan2model.fit_sphere(p / np.linalg.norm(p, axis=1, keepdims=True))
assert abs(r.parameters["radius"] - 1) < 1e-9, r.parameters
print("python", scan2model.__version__, "sphere radius", r.parameters["radius"])'
fi
launcher=()
[ -n "${S2M_TEST_LAUNCHER:-}" ] && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER="$S2M_TEST_LAUNCHER")
cmake -S "$source/tests/consumer" -B "$work/consumer" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
  "${launcher[@]}" >/dev/null
cmake --build "$work/consumer" >/dev/null
"$work/consumer/fit_sphere"
