#!/usr/bin/env bash
# Builds the .deb (CPack) from the build folder and runs the packaged `scan2model --version`: installed with dpkg
# when running as root and no scan2model package is installed already (then removed again), else extracted with
# dpkg-deb -x into a temporary folder. Also checks the package's dependencies are Debian package names.
#   deb_package_test.sh BUILD_DIR
# Exit 77 (skipped) without dpkg-deb. ctest label "deb": `ctest -LE deb` leaves it out.
set -euo pipefail
build="$1"
command -v dpkg-deb >/dev/null || { echo "dpkg-deb not found: skipped"; exit 77; }
work="$(mktemp -d)"
installed_here=0
cleanup() {
  if [ "$installed_here" = 1 ]; then dpkg -r scan2model >/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
(cd "$build" && cpack -G DEB -B "$work" >/dev/null)
deb="$(ls "$work"/scan2model_*.deb)"
echo "package: $(basename "$deb") ($(du -h "$deb" | cut -f1))"
depends="$(dpkg-deb -f "$deb" Depends)"
echo "Depends: $depends"
# Debian names: every alternative is a known package (dpkg-shlibdeps resolved the libraries to them).
for name in $(echo "$depends" | tr ',|' '\n\n' | sed 's/(.*)//; s/:any//' | tr -d ' ' | sort -u); do
  dpkg-query -W "$name" >/dev/null 2>&1 || apt-cache show "$name" >/dev/null 2>&1 ||
    { echo "not a Debian package: $name" >&2; exit 1; }
done
if [ "$(id -u)" = 0 ] && command -v dpkg >/dev/null && ! dpkg-query -W scan2model >/dev/null 2>&1; then
  installed_here=1
  dpkg -i "$deb" >/dev/null
  version="$(/usr/bin/scan2model --version)"
  python3_version="$(/usr/bin/python3 -c 'import scan2model; print(scan2model.__version__)')"
  echo "installed: $version; python module $python3_version"
else
  dpkg-deb -x "$deb" "$work/root"
  version="$("$work/root/usr/bin/scan2model" --version)"
  echo "extracted: $version"
fi
[[ "$version" == "scan2model "* ]] || { echo "unexpected --version output: $version" >&2; exit 1; }
