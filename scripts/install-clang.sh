#!/usr/bin/env bash
# Installs clang and its sanitizer/libFuzzer runtimes (Debian 12) when missing: the fuzz and sanitizer stages
# (scripts/fuzz.sh, scripts/ci-sanitize.sh) build with them.
set -euo pipefail
need=()
for p in clang libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  sudo_cmd=()
  [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
  echo "[install-clang] installing: ${need[*]}"
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${need[@]}"
fi
