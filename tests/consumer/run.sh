#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/run.sh BUILD_DIR -- the package test of issue 10. Installs BUILD_DIR into a
# temporary prefix, builds tests/consumer (a separate project) against it with CMake's
# find_package(pendavg 0.3) and again with pkg-config, checks that a double-only program's
# #include <pendavg/pendavg.hpp> pulls in no Boost.Multiprecision, GSL or omp.h, compares the
# consumers' numbers with those the installed pendavg command prints, and imports the installed
# Python package from the prefix's site directory.
set -euo pipefail
build=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log" || fail "cmake --install"
cli="$prefix/bin/pendavg"
[ -x "$cli" ] || fail "the installed prefix has no bin/pendavg"

# The README's C++ example, verbatim: the ```cpp block after the marker line in README.md.
readme="$here/../../README.md"
awk '/<!-- readme-cpp-example/ { marked = 1; next }
     marked && /^```cpp$/ { inside = 1; next }
     inside && /^```$/ { exit }
     inside { print }' "$readme" >"$work/readme_example.cpp"
grep -q 'int main' "$work/readme_example.cpp" || fail "no marked C++ example (<!-- readme-cpp-example -->) in README.md"

# 1. find_package(pendavg 0.3) + target_link_libraries(... pendavg::pendavg), with the compiler's
# default language standard (the consumer project sets none)
cmake -S "$here" -B "$work/build" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release \
  -DPENDAVG_README_EXAMPLE="$work/readme_example.cpp" \
  >"$work/configure.log" 2>&1 || { cat "$work/configure.log" >&2; fail "configure against the prefix"; }
cmake --build "$work/build" -j 2 >"$work/build.log" 2>&1 || { tail -30 "$work/build.log" >&2; fail "build the consumer"; }
"$work/build/consumer_double" >"$work/double.txt" || fail "consumer_double"
"$work/build/consumer_mpfr" >"$work/mpfr.txt" || fail "consumer_mpfr"
# Against a shared libpendavg the consumers load it (from the prefix, by their run path).
if [ -n "$(find "$prefix" -name 'libpendavg.so*' | head -1)" ]; then
  for program in consumer_double consumer_mpfr readme_example; do
    # (ldd's output first: with pipefail, grep -q ending the pipe early would fail it)
    libraries=$(ldd "$work/build/$program")
    grep -q "libpendavg\.so.* => $prefix/" <<<"$libraries" ||
      fail "$program does not load libpendavg.so from the prefix"
  done
fi
# The example prints one "value +- error (method, kind)" line per particle of its double pendulum.
"$work/build/readme_example" >"$work/readme.txt" || fail "the README's C++ example runs"
[ "$(grep -cE '^0\.[0-9]+ \+- [0-9.e-]+ \([a-z_]+, (bound|estimate|statistical)\)$' "$work/readme.txt")" = 2 ] ||
  { cat "$work/readme.txt" >&2; fail "the README's C++ example printed something else"; }

# 2. pkg-config --cflags --libs pendavg
pc_dir=$(dirname "$(find "$prefix" -name pendavg.pc | head -1)")
flags=$(PKG_CONFIG_PATH="$pc_dir" pkg-config --cflags --libs pendavg) || fail "pkg-config pendavg"
c++ -std=c++20 -O1 "$here/consumer_double.cpp" $flags -o "$work/pc_double" 2>"$work/pc.log" ||
  { cat "$work/pc.log" >&2; fail "compile and link with pkg-config's flags: $flags"; }
# pkg-config gives no run path: a program linked against a shared libpendavg outside the loader's
# directories finds it through LD_LIBRARY_PATH (or its own -Wl,-rpath), as any such library.
libdir=$(PKG_CONFIG_PATH="$pc_dir" pkg-config --variable=libdir pendavg)
LD_LIBRARY_PATH="$libdir${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
  "$work/pc_double" >"$work/pc_double.txt" || fail "the pkg-config build runs"
cmp -s "$work/double.txt" "$work/pc_double.txt" || fail "pkg-config and CMake builds print different numbers"

# 3. what a double-only consumer's include pulls in
echo '#include <pendavg/pendavg.hpp>' >"$work/include.cpp"
c++ -std=c++20 -H -fsyntax-only -I"$prefix/include" "$work/include.cpp" 2>"$work/includes.txt"
if grep -E "boost/multiprecision|gsl/|omp\.h|Eigen" "$work/includes.txt" >&2; then
  fail "#include <pendavg/pendavg.hpp> pulls in the files above"
fi

# 4. the same numbers as the installed CLI
python3 - "$work" "$cli" <<'PY'
import json, subprocess, sys
from decimal import Decimal
work, cli = sys.argv[1], sys.argv[2]
lines = {l.split()[0]: l.split() for l in open(f"{work}/double.txt").read().splitlines()}
lines.update({l.split()[0]: l.split() for l in open(f"{work}/mpfr.txt").read().splitlines()})
def cli_json(*args):
    return json.loads(subprocess.run([cli, "average", *args, "--format", "json"], capture_output=True, text=True,
                                     check=True).stdout)
cases = {
    "N2": ["--masses", "0.5,0.5", "--lengths", "1,1", "--beta", "1"],
    "N3": ["--masses", "1,2,0.5", "--lengths", "1,0.5,2", "--g", "9.81", "--beta", "0.3"],
    "N8": ["--masses", ",".join(["1"] * 8), "--lengths", ",".join(["1"] * 8), "--beta", "1", "--tol", "1e-8"],
}
# A double run's JSON numbers are its doubles exactly (shortest round trip): printed as the
# consumers print them (%.15e), the same text.
for label, args in cases.items():
    o = cli_json(*args)
    got = lines[label]
    assert got[1] == o["method"] and got[2] == o["beta_K_error_kind"], (label, got, o["method"], o["beta_K_error_kind"])
    assert got[3:] == [f"{v:.15e}" for v in o["beta_K"]], (label, got[3:], o["beta_K"])
o = cli_json(*cases["N2"], "--digits", "30")
got = lines["N2_30"]
assert got[1] == o["method"] and got[2] == o["beta_K_error_kind"], (got, o)
for mine, theirs, err in zip(got[3:], o["beta_K"], o["beta_K_error"]):
    assert abs(Decimal(mine) - Decimal(theirs)) <= Decimal(err), (mine, theirs, err)
    assert Decimal(err) < Decimal("1e-29"), err
assert lines["bad"][1:] and "beta" in " ".join(lines["bad"]), lines["bad"]
print("consumer: find_package, pkg-config, include hygiene and the CLI's numbers agree")
PY

# 5. the Python package (when built), installed into the prefix's site directory
init=$(find "$prefix" -path '*-packages/pendavg/__init__.py' | head -1)
if grep -q '^PENDAVG_BUILD_PYTHON:BOOL=ON' "$build/CMakeCache.txt"; then
  [ -n "$init" ] || fail "cmake --install put no Python package pendavg under $prefix"
  python=$(sed -n 's/^_\{0,1\}Python_EXECUTABLE:[A-Z]*=//p' "$build/CMakeCache.txt" | head -1)
  PYTHONPATH=$(dirname "$(dirname "$init")") "$python" - "$cli" "$prefix" <<'PY' || fail "the installed Python package"
import json, subprocess, sys
import pendavg
cli, prefix = sys.argv[1], sys.argv[2]
assert pendavg.__file__.startswith(prefix), pendavg.__file__
r = pendavg.average([0.5, 0.5], [1, 1], 1.0)
o = json.loads(subprocess.run([cli, "average", "--masses", "0.5,0.5", "--lengths", "1,1", "--beta", "1.0",
                               "--format", "json"], capture_output=True, text=True, check=True).stdout)
# (the CLI's JSON numbers are the doubles exactly: the module's, bit for bit)
assert list(r.beta_K) == o["beta_K"] and r.method == o["method"], (list(r.beta_K), o)
print("consumer: the installed Python package imports from", pendavg.__file__.replace(prefix, "PREFIX"))
PY
fi
