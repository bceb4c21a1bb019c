#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_shards.sh -- a sweep split over a job array without MPI (--shard K/N) and joined
# by `pendavg merge`: for N = 1, 2 and 3 shards of a table (torus and transfer rows) and of an
# `average --cases` run, the merged file is the serial run's, byte for byte, whatever order the
# shards are given in; a shard stopped by SIGTERM at a random moment and resumed gives the same
# merged file, and one killed by SIGKILL and resumed is the uninterrupted shard's file; merge
# refuses a missing shard, a shard given twice, shards of other sweeps, an interrupted shard,
# and a file that is no shard; --shard refuses a malformed K/N.
#
# Usage: test_shards.sh PATH/TO/pendavg CASE PATH/TO/pendavg_row_faults   (test_shards.sh --list:
# the cases) Prints "CASE: N passed, M failed" last. (pendavg_row_faults, the test build, says
# how many rows a resumed shard computed.)
set -u
usage="usage: test_shards.sh PATH/TO/pendavg CASE PATH/TO/pendavg_row_faults, or test_shards.sh --list"
pendavg=${1:?$usage}
faulty=${3:-}
[ "$pendavg" = --list ] || [ -n "$faulty" ] || { echo "$usage" >&2; exit 2; }
# shellcheck source=sweep_harness.sh
source "$(cd "$(dirname "$0")" && pwd)/sweep_harness.sh"

table=(table --chain 3,8 --beta log:0.1:10:40 --g 1,2 --tol 1e-8)
# cases.csv: 500 rows of N = 2
cases_setup() {
"$python" - "$work/cases.csv" <<'PY'
import random, sys
rng = random.Random(29)
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for _ in range(500):
        mu1 = rng.uniform(0.01, 0.99)
        f.write(f"{10 ** rng.uniform(-2, 2):.6g},1,{mu1:.6g},{1 - mu1:.6g},1,{rng.uniform(0.5, 2):.6g}\n")
PY
cases=(average --cases "$work/cases.csv")
}

# same_merged NAME ARGS...: the shards of 1, 2 and 3, merged (in reverse order), against the
# serial file.
same_merged() {
  local name=$1 n k
  shift
  "$pendavg" "$@" --output "$work/serial.csv" 2>/dev/null || { fail "$name: serial run" "exit 0" "exit $?"; return; }
  for n in 1 2 3; do
    rm -f "$work"/shard*.csv
    for ((k = 1; k <= n; ++k)); do
      "$pendavg" "$@" --shard "$k/$n" --output "$work/shard$k.csv" 2>/dev/null ||
        fail "$name: shard $k/$n" "exit 0" "exit $?"
    done
    # A shard's file starts as every output does; its shard line follows the schema's.
    check "$name: shard 1/$n starts with '# schema: 1', then its shard line" \
      test "$(head -c 20 "$work/shard1.csv")" = "$(printf '# schema: 1\n# shard ')"
    local expected="exit 0, nothing printed, the serial file"
    run merge --output "$work/merged.csv" $(ls "$work"/shard*.csv | sort -r)
    if [ "$rc" -ne 0 ]; then
      fail "$name: merging $n shards" "$expected" "exit $rc"
    elif [ -s "$work/out" ] || [ -s "$work/err" ]; then
      fail "$name: merging $n shards" "$expected" "output on stdout or stderr"
    elif ! cmp -s "$work/merged.csv" "$work/serial.csv"; then
      fail "$name: merging $n shards" "$expected" "a file that differs from the serial file"
    else
      pass
    fi
  done
}
case:merge.table() {
same_merged "table" "${table[@]}"
}
case:merge.cases() {
same_merged "average --cases" "${cases[@]}" --columns beta_K,ratio
}

# Shard 2/3 of a slow sweep stopped by SIGTERM at a random moment, resumed with the same --shard:
# merged with the other two, the serial file.
case:resume.sigterm() {
slow=(table --beta log:1:1000:60 --mu1 0.001,0.05 --digits 200)
export OMP_NUM_THREADS=2
"$pendavg" "${slow[@]}" --output "$work/slow_serial.csv" 2>/dev/null
for k in 1 3; do "$pendavg" "${slow[@]}" --shard "$k/3" --output "$work/slow$k.csv" 2>/dev/null; done
delay=$("$python" -c 'import random; print(round(random.uniform(0.3, 1.5), 2))')
"$pendavg" "${slow[@]}" --shard 2/3 --output "$work/slow2.csv" >/dev/null 2>&1 &
pid=$!
sleep "$delay"
kill -TERM "$pid" 2>/dev/null
wait "$pid"
interrupted=$(grep -c '^# interrupted' "$work/slow2.csv" 2>/dev/null)
if [ "${interrupted:-0}" -gt 0 ]; then
  bad "merge of an interrupted shard" merge --output "$work/slow.csv" "$work/slow1.csv" "$work/slow2.csv" "$work/slow3.csv"
fi
expected="shard 2/3 stopped at $delay s (interrupted: ${interrupted:-none}), resumed and merged: the serial file"
"$pendavg" "${slow[@]}" --shard 2/3 --resume "$work/slow2.csv" 2>/dev/null
resumed=$?
run merge --output "$work/slow.csv" "$work/slow1.csv" "$work/slow2.csv" "$work/slow3.csv"
if [ "$resumed" -ne 0 ]; then
  fail "resuming shard 2/3 after SIGTERM" "$expected" "the resume exited $resumed"
elif [ "$rc" -ne 0 ] || ! cmp -s "$work/slow.csv" "$work/slow_serial.csv"; then
  fail "resuming shard 2/3 after SIGTERM" "$expected" "merge exited $rc, or another file"
else
  pass
fi
bad "--resume a shard with another --shard" "${slow[@]}" --shard 1/3 --resume "$work/slow2.csv"
}
# Shard 2/2 of a slower sweep killed outright (SIGKILL: a job array's task lost) and resumed:
# the uninterrupted shard's file, its rows taken from the killed run's temporary.
case:resume.sigkill() {
export OMP_NUM_THREADS=2
killed=(table --beta log:1:1000:60 --mu1 0.001,0.05 --digits 1000 --shard 2/2)
"$pendavg" "${killed[@]}" --output "$work/killed_reference.csv" 2>/dev/null
killed_and_resumed "shard 2/2" "$work/killed_reference.csv" "$work/killed.csv" "$faulty" "${killed[@]}"
}

# Refusals: one error line, exit 2, nothing written.
case:merge.refusals() {
for k in 1 2 3; do "$pendavg" "${table[@]}" --shard "$k/3" --output "$work/t$k.csv" 2>/dev/null; done
# a file that is no shard: the three merged (the serial file, merge.table)
"$pendavg" merge --output "$work/serial.csv" "$work/t1.csv" "$work/t2.csv" "$work/t3.csv"
"$pendavg" "${cases[@]}" --shard 2/3 --output "$work/c2.csv" 2>/dev/null
"$pendavg" "${table[@]}" --tol 1e-9 --shard 2/3 --output "$work/other2.csv" 2>/dev/null
bad "merge: a shard missing" merge --output "$work/m.csv" "$work/t1.csv" "$work/t3.csv"
bad "merge: a shard twice" merge --output "$work/m.csv" "$work/t1.csv" "$work/t2.csv" "$work/t2.csv" "$work/t3.csv"
bad "merge: a shard of another sweep (rows)" merge --output "$work/m.csv" "$work/t1.csv" "$work/c2.csv" "$work/t3.csv"
bad "merge: a shard of another sweep (header)" merge --output "$work/m.csv" "$work/t1.csv" "$work/other2.csv" "$work/t3.csv"
bad "merge: not a shard" merge --output "$work/m.csv" "$work/t1.csv" "$work/serial.csv"
bad "merge: no shards" merge --output "$work/m.csv"
bad "merge: output is a shard" merge --output "$work/t1.csv" "$work/t1.csv" "$work/t2.csv" "$work/t3.csv"
check "merge refusals wrote nothing" test ! -e "$work/m.csv"
check "merge refusals left no temporary" no_temporaries
}
case:shard.refusals() {
for spec in 0/3 4/3 3 a/3 2/0 -1/3 1/-3 "1/3x"; do bad "--shard $spec" "${table[@]}" --shard "$spec"; done
bad "--shard with --timing" "${cases[@]}" --shard 1/2 --timing
}

cases_main "$@"
