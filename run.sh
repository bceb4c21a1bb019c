#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# pendavg's entry script (see README.md).
#   ./run.sh main   install what is missing, build in Release, regenerate tables/ (reports, figures)
#   ./run.sh test   install what is missing, build in Release, run the default test suite
#   ./run.sh slow   the slow validations (ctest -L slow)
set -euo pipefail
cd "$(dirname "$0")"

BUILD_DIR=${PENDAVG_BUILD_DIR:-build}
JOBS=$(nproc 2>/dev/null || echo 2)
PACKAGES_BUILD=(g++ cmake make pkg-config libgsl-dev libboost1.81-dev libmpfr-dev libgmp-dev libeigen3-dev catch2 libbenchmark-dev
                libflint-arb-dev
                pybind11-dev python3-dev python3-numpy python3-pytest python3-mpmath python3-matplotlib
                python3-pandas python3-xarray mypy locales
                libopenmpi-dev openmpi-bin python3-venv python3-pip groff-base man-db git)
PACKAGES_MAIN=(python3 python3-numpy python3-matplotlib)

log() { printf '[run.sh] %s\n' "$*" >&2; }

install_missing() {
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]})); then
    log "installing: ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
  fi
}

build() {
  install_missing "${PACKAGES_BUILD[@]}"
  log "configuring ($BUILD_DIR, Release)"
  # The Python module and its tests run with Debian's python3, which has numpy and pytest
  # (another python3 may come first on PATH); `pip install .` builds for the pip's interpreter.
  cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE:FILEPATH=/usr/bin/python3 >/dev/null
  log "building with $JOBS jobs"
  cmake --build "$BUILD_DIR" -j "$JOBS"
}

python_hint() {  # how to import the Python module of this build
  local python
  python=$(sed -n 's/^_\{0,1\}Python_EXECUTABLE:[A-Z]*=//p' "$BUILD_DIR/CMakeCache.txt" | head -1)
  log "Python module: PYTHONPATH=$PWD/$BUILD_DIR/python ${python:-python3} -c 'import pendavg'"
}

case "${1:-}" in
  test)
    build
    ctest --test-dir "$BUILD_DIR" -L default --output-on-failure -j "$JOBS"
    python_hint
    ;;
  slow)
    build
    ctest --test-dir "$BUILD_DIR" -L slow --output-on-failure
    ;;
  main)
    build
    install_missing "${PACKAGES_MAIN[@]}"
    PENDAVG="$BUILD_DIR/pendavg" bash tables/make_tables.sh
    python_hint
    ;;
  *)
    echo "usage: ./run.sh main|test|slow" >&2
    exit 2
    ;;
esac
