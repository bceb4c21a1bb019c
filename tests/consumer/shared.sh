#!/usr/bin/env bash
# tests/consumer/shared.sh SOURCE_DIR -- the package test against a shared libpendavg
# (BUILD_SHARED_LIBS=ON): a fresh library-only build in a temporary directory, then run.sh.
set -euo pipefail
source=$(realpath "$1")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake -S "$source" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DBUILD_SHARED_LIBS=ON \
  -DPENDAVG_BUILD_TESTS=OFF -DPENDAVG_BUILD_BENCHMARKS=OFF >"$work/configure.log"
cmake --build "$work/build" -j "$(nproc)" >"$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
ls "$work/build"/libpendavg.so.* >/dev/null || { echo "FAIL: no libpendavg.so" >&2; exit 1; }
bash "$source/tests/consumer/run.sh" "$work/build"
