#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/citation.sh SOURCE_DIR VERSION -- CITATION.cff is CFF 1.2.0 with the fields a
# citation needs (title, authors, license, preferred citation of the paper) and its `version`
# equals VERSION, CMake's project(VERSION); LICENSE is the GPL version 3 it names.
set -euo pipefail
cff="$1/CITATION.cff" version=$2
fail() { echo "FAIL: $*" >&2; exit 1; }
[ -f "$cff" ] || fail "no CITATION.cff"
field() { sed -n "s/^$1: *\"\{0,1\}\([^\"]*\)\"\{0,1\} *$/\1/p" "$cff"; }
[ "$(field cff-version)" = 1.2.0 ] || fail "cff-version is '$(field cff-version)', not 1.2.0"
[ "$(field version)" = "$version" ] ||
  fail "CITATION.cff says version '$(field version)', CMakeLists.txt project(VERSION $version)"
[ "$(field license)" = GPL-3.0-or-later ] || fail "CITATION.cff license is '$(field license)'"
for key in message title authors preferred-citation; do
  grep -q "^$key:" "$cff" || fail "CITATION.cff has no $key"
done
grep -q 'title: "Multiple pendulum and nonuniform distribution of average kinetic energy"' "$cff" ||
  fail "CITATION.cff does not cite the paper"
# A YAML parser, where there is one, reads the whole file.
if python3 -c 'import yaml' 2>/dev/null; then
  python3 - "$cff" "$version" <<'PY' || fail "CITATION.cff is not the YAML expected"
import sys, yaml
c = yaml.safe_load(open(sys.argv[1]))
assert c["version"] == sys.argv[2] and c["type"] == "software", c
p = c["preferred-citation"]
assert p["type"] == "article" and [a["family-names"] for a in p["authors"]] == ["Konishi", "Yanagita"], p
PY
fi
grep -q 'GNU GENERAL PUBLIC LICENSE' "$1/LICENSE" && grep -q 'Version 3, 29 June 2007' "$1/LICENSE" ||
  fail "LICENSE is not the GPL version 3"
echo "CITATION.cff: CFF 1.2.0, version $version, GPL-3.0-or-later; LICENSE: GPL-3.0"
