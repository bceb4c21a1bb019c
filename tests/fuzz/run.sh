#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/fuzz/run.sh -- runs the libFuzzer targets of a PENDAVG_FUZZ build, one after another.
#
# Usage: run.sh BUILD_DIR [SECONDS_PER_TARGET [TARGET...]]     (default: 60 s; args number cases)
#
# Each target starts from its seed corpus (tests/fuzz/corpus/TARGET, only read) with its
# dictionary (TARGET.dict); new inputs go to a scratch directory, removed at the end (set
# PENDAVG_FUZZ_KEEP=DIR to keep them in DIR/TARGET). A crash, leak, undefined behaviour, a broken
# invariant, an input slower than 10 s or above 2.5 GB fails the run: the input is saved as
# BUILD_DIR/fuzz-artifacts/<kind>-<hash> (replay it with BUILD_DIR/fuzz_TARGET FILE). Prints one
# summary line per target: executions, seconds, coverage (cov: edges, ft: features), corpus size.
set -euo pipefail

build=$(cd "${1:?usage: run.sh BUILD_DIR [SECONDS_PER_TARGET [TARGET...]]}" && pwd)
seconds=${2:-60}
shift $(($# < 2 ? $# : 2))
targets=("$@")
((${#targets[@]})) || targets=(args number cases)
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
artifacts=$build/fuzz-artifacts
mkdir -p "$artifacts"

# LeakSanitizer: the suppressions of the sanitizer builds (tests/sanitize/lsan.supp). UBSan
# stops at the first report (the build has -fno-sanitize-recover too).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$here/../sanitize/lsan.supp:print_suppressions=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

declare -A max_len=([args]=512 [number]=512 [cases]=2048)
status=0
for target in "${targets[@]}"; do
  binary=$build/fuzz_$target
  [ -x "$binary" ] || { echo "run.sh: $binary not built" >&2; exit 2; }
  corpus=${PENDAVG_FUZZ_KEEP:+$PENDAVG_FUZZ_KEEP/$target}
  corpus=${corpus:-$work/$target}
  mkdir -p "$corpus"
  log=$work/$target.log
  rc=0
  "$binary" "$corpus" "$here/corpus/$target" -dict="$here/$target.dict" \
    -max_total_time="$seconds" -max_len="${max_len[$target]:-1024}" -timeout=10 \
    -rss_limit_mb=2560 -print_final_stats=1 -artifact_prefix="$artifacts/$target-" \
    >"$log" 2>&1 || rc=$?
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  time=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" | tail -1)
  coverage=$(grep -o 'cov: [0-9]* ft: [0-9]* corp: [0-9]*/[0-9a-zA-Z]*' "$log" | tail -1)
  echo "fuzz_$target: ${runs:-?} executions in ${time:-?} s, ${coverage:-no coverage line}"
  if [ "$rc" -ne 0 ]; then
    status=1
    echo "fuzz_$target FAILED (exit $rc); its log:"
    grep -v '^#[0-9]' "$log" | tail -60
  fi
done
exit "$status"
