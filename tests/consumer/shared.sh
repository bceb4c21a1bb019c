#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/shared.sh SOURCE_DIR [PYTHON] -- the package test against a shared libpendavg
# (BUILD_SHARED_LIBS=ON): a fresh library-only build in a temporary directory, then run.sh. The
# library exports its API only (hidden visibility, pendavg/export.hpp): every exported name of
# namespace pendavg is declared in a public header, and the consumers run against the library.
set -euo pipefail
source=$(realpath "$1")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The Python module for PYTHON (the calling build's interpreter, which has numpy), when given.
cmake -S "$source" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DBUILD_SHARED_LIBS=ON \
  -DPENDAVG_BUILD_TESTS=OFF -DPENDAVG_BUILD_BENCHMARKS=OFF \
  ${2:+-DPython_EXECUTABLE:FILEPATH=$2} >"$work/configure.log"
cmake --build "$work/build" -j "$(nproc)" >"$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
ls "$work/build"/libpendavg.so.* >/dev/null || { echo "FAIL: no libpendavg.so" >&2; exit 1; }

library=$(realpath "$work/build/libpendavg.so")
nm -D --defined-only -C "$library" >"$work/exported.txt"
# The names after "pendavg::" in the exported symbols (functions, classes, namespaces) must all be
# declared in include/pendavg/ or generated public headers: an engine's name is not.
grep -o 'pendavg::[A-Za-z_][A-Za-z0-9_]*' "$work/exported.txt" | sort -u | sed 's/^pendavg:://' |
  while read -r name; do
    grep -qw -- "$name" "$source"/include/pendavg/*.hpp "$work/build/include/pendavg/"*.hpp ||
      echo "$name"
  done >"$work/internal.txt"
if [ -s "$work/internal.txt" ]; then
  echo "FAIL: libpendavg.so exports names of no public header:" >&2
  head -20 "$work/internal.txt" >&2
  exit 1
fi
echo "libpendavg.so exports $(wc -l <"$work/exported.txt") symbols ($(grep -c 'pendavg::' "$work/exported.txt") of namespace pendavg), all of the public API"

bash "$source/tests/consumer/run.sh" "$work/build"
