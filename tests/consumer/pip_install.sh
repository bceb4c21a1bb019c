#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/pip_install.sh SOURCE_DIR VERSION -- `pip install .` as the README documents it,
# offline on Debian 12: a clean copy of the committed tree (git archive HEAD), a fresh venv of
# Debian's python3 (which has numpy) with the system site packages, pip install
# --no-build-isolation .; then the package imports without PYTHONPATH, from the venv,
# with CMake's project version as importlib.metadata.version and `pip show`; it computes; the
# venv holds the Python package only (no headers, library or CLI); pip uninstall removes it.
# PENDAVG_PIP_PYTHON picks another interpreter. Rebuilds the module: label slow.
set -euo pipefail
source=$(realpath "$1") version=$2
python=${PENDAVG_PIP_PYTHON:-/usr/bin/python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

mkdir "$work/src"
git -C "$source" archive HEAD | tar -x -C "$work/src"
cd "$work"
"$python" -m venv --system-site-packages v
# The build directory is src/build, laid out as a normal build beside its sources, so that a
# compiler cache (CMAKE_CXX_COMPILER_LAUNCHER=ccache, base_dir above both trees) serves the
# objects of an earlier build of the same sources.
export CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-2}
export PENDAVG_PIP_BUILD_DIR="$work/src/build"
# Exactly the README's command; pip need not ask an index (numpy comes from the system).
export PIP_DISABLE_PIP_VERSION_CHECK=1
(cd src && ../v/bin/pip install --no-build-isolation .) >"$work/pip.log" 2>&1 ||
  { tail -40 "$work/pip.log" >&2; fail "pip install --no-build-isolation ."; }

unset PYTHONPATH
cd /  # not the source tree: the import must come from the venv
v="$work/v"
"$v/bin/python" - "$v" "$version" <<'PY' || fail "the installed package"
import importlib.metadata, os, sys
import pendavg
venv, version = sys.argv[1], sys.argv[2]
assert os.path.realpath(pendavg.__file__).startswith(os.path.realpath(venv)), pendavg.__file__
assert importlib.metadata.version("pendavg") == version, importlib.metadata.version("pendavg")
assert pendavg.__version__ == version, pendavg.__version__
r = pendavg.average([0.5, 0.5], [1, 1], 1.0)
assert abs(sum(r.beta_K) - 1.0) < 1e-12, r.beta_K  # sum_i beta<K_i> = N/2
files = [str(f) for f in importlib.metadata.files("pendavg")]
assert any(f.startswith("pendavg/_pendavg") for f in files), files
outside = [f for f in files if not f.startswith(("pendavg/", "pendavg-"))]
assert not outside, outside
print("pip install .: pendavg", version, "imports from the venv:", len(files), "files")
PY
"$v/bin/pip" show pendavg >"$work/show.txt" || fail "pip show pendavg"
grep -qx "Name: pendavg" "$work/show.txt" && grep -qx "Version: $version" "$work/show.txt" &&
  grep -qx "License: GPL-3.0-or-later" "$work/show.txt" || { cat "$work/show.txt" >&2; fail "pip show"; }
# The venv received no C++ headers, library, CMake package files or CLI.
if find "$v" \( -path '*/include/pendavg*' -o -name 'libpendavg*' -o -name pendavgConfig.cmake \
     -o -name pendavg.pc -o -path "$v/bin/pendavg" \) | grep .; then
  fail "pip install put the C++ package into the venv (above)"
fi
"$v/bin/pip" uninstall -y pendavg >/dev/null || fail "pip uninstall -y pendavg"
if "$v/bin/python" -c 'import pendavg' 2>/dev/null; then fail "pendavg still imports after uninstall"; fi
[ -z "$(find "$v" -path '*-packages/pendavg*' | head -1)" ] || fail "uninstall left files behind"
echo "pip install/show/uninstall of pendavg $version: ok"
