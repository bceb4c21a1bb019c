#!/usr/bin/env bash
# tests/consumer/isa.sh BUILD_DIR -- the dynamics kernels' baseline build (the one an older
# x86-64 CPU runs) contains no AVX register or fused multiply-add instruction.
set -euo pipefail
object=$(find "$1" -path '*pendavg_dynamics_base.dir*' -name 'dynamics_kernels.cpp.o' | head -1)
[ -n "$object" ] || { echo "FAIL: no baseline dynamics object in $1" >&2; exit 1; }
count=$(objdump -d --no-show-raw-insn "$object" | grep -cE '%[yz]mm|vfmadd|vfnmadd' || true)
[ "$count" -eq 0 ] || { echo "FAIL: $count AVX/FMA instructions in $object" >&2; exit 1; }
echo "baseline dynamics kernels: no AVX or FMA instructions"
