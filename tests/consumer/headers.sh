#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/headers.sh CXX SOURCE_DIR BUILD_DIR -- every public header compiles alone (a user
# may include any one of them first): a translation unit holding only `#include <pendavg/H>`, for
# each header of include/pendavg/ and the generated ones (version.hpp, export.hpp), with -Wall
# -Wextra -Werror, with C++20 as pendavg::pendavg asks for.
set -euo pipefail
cxx=$1 source=$(realpath "$2") build=$(realpath "$3")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mpfr_flags=$(pkg-config --cflags mpfr gmp)
failed=0 count=0
for header in "$source"/include/pendavg/*.hpp "$build"/include/pendavg/*.hpp; do
  name=$(basename "$header")
  printf '#include <pendavg/%s>\n' "$name" >"$work/$name.cpp"
  if ! "$cxx" -std=c++20 -fsyntax-only -Wall -Wextra -Werror -I"$source/include" \
       -I"$build/include" $mpfr_flags "$work/$name.cpp" 2>"$work/$name.log"; then
    echo "FAIL: pendavg/$name does not compile alone:" >&2
    head -5 "$work/$name.log" >&2
    failed=1
  fi
  count=$((count + 1))
done
[ "$count" -ge 11 ] || { echo "FAIL: only $count headers found" >&2; exit 1; }
[ "$failed" = 0 ] || exit 1
echo "$count public headers compile alone"
