#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/isa.sh BUILD_DIR -- the library runs on any x86-64 CPU: in every object of
# libpendavg, the only functions with AVX registers or fused multiply-adds are the dynamics
# kernels compiled for x86-64-v3 (namespace dynamics_x86_64_v3, chosen at run time only on CPUs
# that have AVX2 and FMA) and the certified fast path's fma body (certified_fast::(anonymous
# namespace)::fused, engine/certified/fast_double.cpp, chosen at run time only on CPUs with FMA;
# internal functions only). Library templates those kernels instantiate (std::, Eigen) must stay
# baseline code: the linker keeps one copy of each for the whole program.
set -euo pipefail
library=$(find "$1" -maxdepth 1 -name 'libpendavg.a' -o -maxdepth 1 -name 'libpendavg.so' | head -1)
[ -n "$library" ] || { echo "FAIL: no libpendavg in $1" >&2; exit 1; }
objdump -d --no-show-raw-insn -C "$library" | awk '
  /^[0-9a-f]+ <.*>:$/ { name = $0; next }
  /%[yz]mm|vfn?madd|vfn?msub/ {
    if (name !~ /dynamics_x86_64_v3|certified_fast::\(anonymous namespace\)::fused::/) {
      bad[name] = 1
    } else {
      wide = 1
    }
  }
  END {
    n = 0
    for (f in bad) { print "FAIL: AVX/FMA outside the x86-64-v3 kernels: " f > "/dev/stderr"; n++ }
    if (n > 0) exit 1
    print "AVX/FMA only in the x86-64-v3 dynamics kernels and the certified fma body" (wide ? "" : " (none built)")
  }'
