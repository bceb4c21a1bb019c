#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_kill_ahead.sh -- a sweep killed outright (SIGKILL) keeps the rows it finished
# ahead of an unfinished one: rank 0 copies the rows waiting in its reorder buffer to a second
# temporary about every second, and --resume takes them from there.
#
# Row 0 of the test build (pendavg_row_faults, PENDAVG_TEST_SLOW_ROW=0:S) sleeps, so every
# other finished row waits behind it and the output file's own temporary holds only the header.
# The run is killed once the copy holds rows; the resumed run must then compute only the rows the
# copy did not hold (row 0 among them), and write the uninterrupted run's file byte for byte.
#
#   bash tests/cli/test_kill_ahead.sh PENDAVG_ROW_FAULTS CASE     (--list: the cases: threads in
#   each --format, and mpi)
set -uo pipefail
export SOURCE_DATE_EPOCH=1700000000  # the header's date: the same in every run
faulty=$1
case_name=${2:-}
cases=(threads.csv threads.json threads.text mpi.csv)
if [ "$case_name" = --list ]; then printf '%s\n' "${cases[@]}"; exit 0; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
fail() { echo "FAIL [$case_name] $*" >&2; failures=$((failures + 1)); }

sweep=(table --beta log:0.01:100:120 --mu1 0.3 --digits 24 --format "${case_name#*.}")

# killed_ahead NAME LAUNCH...: LAUNCH is how the test build is started (alone, or under mpirun).
killed_ahead() {
  local name=$1 k rows computed copy
  shift
  local out=$work/$name.csv reference=$work/$name.reference.csv
  OMP_NUM_THREADS=2 "$@" "${sweep[@]}" --output "$reference" 2>/dev/null ||
    { fail "$name: the uninterrupted run failed"; return; }
  rows=$(grep -c '^,\?{"N"\|^[0-9 ]' "$reference")
  PENDAVG_TEST_SLOW_ROW=0:60 OMP_NUM_THREADS=2 "$@" "${sweep[@]}" --output "$out" >/dev/null 2>&1 &
  local pid=$!
  # The copy: a second temporary of OUT with data rows (the file's own holds only its header
  # and column line).
  copy=
  for ((k = 0; k < 300; ++k)); do
    [ -n "$copy" ] && break
    for temporary in "$out".tmp.*; do  # a row (its "beta" field) after the header
      [ -e "$temporary" ] && [ "$(grep -c '^,\?{"N"\|^[0-9 ]' "$temporary")" -ge 2 ] && copy=$temporary
    done
    sleep 0.1
  done
  { kill -KILL "$pid" && wait "$pid"; } 2>/dev/null
  for ((k = 0; k < 100; ++k)); do pgrep -f -- "--output $out" >/dev/null || break; sleep 0.1; done
  [ -n "$copy" ] || { fail "$name: no temporary held rows ahead of row 0 after 30 s"; return; }
  [ -e "$out" ] && { fail "$name: the run with a slow row 0 finished before it was killed"; return; }
  PENDAVG_SWEEP_REPORT=1 OMP_NUM_THREADS=2 "$@" "${sweep[@]}" --resume "$out" >/dev/null 2>"$work/err"
  local rc=$?
  computed=$(sed -n 's/^pendavg: test: sweep of [0-9]* rows, \([0-9]*\) computed.*/\1/p' "$work/err")
  if [ "$rc" -ne 0 ]; then
    fail "$name: the resumed run exited $rc: $(head -1 "$work/err")"
  elif ! cmp -s "$out" "$reference"; then
    fail "$name: killed and resumed, the file differs from an uninterrupted run's"
  elif [ -n "$(find "$work" -name "$name.csv.tmp.*" | head -1)" ]; then
    fail "$name: a temporary is left after the resumed run"
  elif ! [ "${computed:-$rows}" -le $((rows - 2)) ]; then
    fail "$name: the resumed run computed ${computed:-?} of $rows rows: the rows finished ahead of row 0 were lost"
  fi
}

case $case_name in
  threads.*) killed_ahead "$case_name" "$faulty" ;;
  mpi.csv)
    command -v mpirun >/dev/null || { echo "SKIP [mpi] no mpirun"; exit 0; }
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
    killed_ahead "$case_name" mpirun -n 2 --mca btl self,vader --mca plm isolated \
      -x OMP_NUM_THREADS -x PENDAVG_TEST_SLOW_ROW -x PENDAVG_SWEEP_REPORT "$faulty" ;;
  *) echo "usage: $0 PENDAVG_ROW_FAULTS {$(IFS='|'; echo "${cases[*]}")|--list}" >&2; exit 2 ;;
esac
((failures == 0)) && echo "PASS [$case_name]"
exit $((failures > 0))
