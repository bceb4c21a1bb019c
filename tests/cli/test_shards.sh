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
# Shards damaged after they were written, or that no --shard writes: refused in one line, and
# nothing written (JSON's end after the rows is checked byte for byte as CSV's rows are).
case:merge.damaged() {
local quick=(table --beta log:0.1:10:40 --mu1 0.1,0.5) f k cut
for f in csv json text; do
  for k in 1 2 3; do "$pendavg" "${quick[@]}" --format "$f" --shard "$k/3" --output "$work/q$k.$f"; done
done
# A row damaged inside a shard (a copy gone wrong): cut short, a blank line in its place, a cell
# that is not a number, a word or empty. Refused, as --resume would compute such a row again.
for f in csv json text; do
  cut='/.$/'  # CSV: its last field (a cut within it may leave a word or nothing, both cells)
  [ "$f" = csv ] && cut='/,[^,]*$/'
  awk "NR == 20 {sub($cut, \"\")} {print}" "$work/q2.$f" >"$work/cut.$f"
  bad "merge: a $f shard with a row cut short" merge --output "$work/m.$f" "$work/q1.$f" "$work/cut.$f" "$work/q3.$f"
  expect "... names the shard and its damaged row" "grep -q \"'$work/cut.$f' has a damaged row\" \"\$work/err\""
done
# ... as the refusal says, --resume with the shard's --shard computes the row again
"$pendavg" "${quick[@]}" --shard 2/3 --resume "$work/cut.csv" 2>/dev/null
"$pendavg" "${quick[@]}" --output "$work/q_serial.csv"
run merge --output "$work/q_resumed.csv" "$work/q1.csv" "$work/cut.csv" "$work/q3.csv"
check "... resumed, the shard merges into the serial file" \
  cmp -s <(grep -v ', generated ' "$work/q_resumed.csv") <(grep -v ', generated ' "$work/q_serial.csv")
awk 'NR == 20 {print ""} {print}' "$work/q2.csv" >"$work/blank.csv"
bad "merge: a blank line in place of a row" merge --output "$work/m.csv" "$work/q1.csv" "$work/blank.csv" "$work/q3.csv"
awk 'NR == 20 {sub(/,[^,]*,/, ",1.2.3,")} {print}' "$work/q2.csv" >"$work/cell.csv"
bad "merge: a cell that is not a number" merge --output "$work/m.csv" "$work/q1.csv" "$work/cell.csv" "$work/q3.csv"
# JSON: something after the document, its "failed" line gone, a line of its end twice
{ cat "$work/q3.json"; echo garbage; } >"$work/after.json"
bad "merge: a JSON shard with text after its end" merge --output "$work/m.json" "$work/q1.json" "$work/q2.json" "$work/after.json"
grep -v '^"failed": \[\],$' "$work/q2.json" >"$work/nofailed.json"
bad "merge: a JSON shard without its failed list" merge --output "$work/m.json" "$work/q1.json" "$work/nofailed.json" "$work/q3.json"
sed '/^"interrupted": null}$/i "interrupted": "SIGTERM",' "$work/q2.json" >"$work/twice.json"
bad "merge: a JSON shard with two interruptions" merge --output "$work/m.json" "$work/q1.json" "$work/twice.json" "$work/q3.json"
bad "merge: a JSON shard read from a pipe (it is read twice)" merge --output "$work/m.json" "$work/q1.json" <(cat "$work/q2.json") "$work/q3.json"
# the shard lines: a block size the rule does not give, a shard count beyond --shard's
sed -i '0,/blocks of 2 /s//blocks of 3 /' "$work/q1.csv" "$work/q2.csv" "$work/q3.csv"
bad "merge: shards whose blocks are not the rule's" merge --output "$work/m.csv" "$work/q1.csv" "$work/q2.csv" "$work/q3.csv"
sed '0,/shard 1\/3/s//shard 1\/18446744073709551615/' "$work/q1.json" >"$work/huge.json"
bad "merge: a shard of 2^64 - 1 shards" merge --output "$work/m.json" "$work/huge.json"
# one real shard of 999999999: the 999999998 missing are named at once (no table of N slots)
"$pendavg" table --beta 0.5,1 --mu1 0.5 --shard 1/999999999 --output "$work/one.csv"
bad "merge: shard 1 of 999999999 alone" merge --output "$work/m.csv" "$work/one.csv"
expect "... names shard 2 as missing" 'grep -q "shard 2/999999999 is missing" "$work/err"'
mkdir -p "$work/adir"
bad "merge: a directory" merge --output "$work/m.csv" "$work/adir"
check "merge of damaged shards wrote nothing" test ! -e "$work/m.csv" -a ! -e "$work/m.json" -a ! -e "$work/m.text"
check "... and left no temporary" no_temporaries
}
# The merged header is shard 1's (its date, its cases file's name), in whatever order the
# shards are given.
case:merge.header() {
local quick=(table --beta log:0.1:10:40 --mu1 0.1,0.5) k
SOURCE_DATE_EPOCH=86400 "$pendavg" "${quick[@]}" --shard 1/3 --output "$work/d1.csv"
for k in 2 3; do SOURCE_DATE_EPOCH=0 "$pendavg" "${quick[@]}" --shard "$k/3" --output "$work/d$k.csv"; done
SOURCE_DATE_EPOCH=86400 "$pendavg" "${quick[@]}" --output "$work/d_serial.csv"
run merge --output "$work/d_merged.csv" "$work/d3.csv" "$work/d2.csv" "$work/d1.csv"
check "shards in reverse order, shard 1 of another date: the serial file of shard 1's date" \
  cmp -s "$work/d_merged.csv" "$work/d_serial.csv"
# A cases file whose name holds a newline: the header line stays one line (escaped), and the
# file resumes and merges.
local odd=$'odd\nname.csv'
cp "$work/cases.csv" "$work/$odd"
(cd "$work" && "$pendavg" average --cases "$odd" --output "$work/o_serial.csv" &&
  for k in 1 2; do "$pendavg" average --cases "$odd" --shard "$k/2" --output "$work/o$k.csv"; done)
check "a cases file named with a newline: one header line" \
  test "$(grep -c '^# pendavg .* from odd name.csv$' "$work/o_serial.csv")" = 1
run merge --output "$work/o_merged.csv" "$work/o2.csv" "$work/o1.csv"
check "... its shards merge into the serial file" cmp -s "$work/o_merged.csv" "$work/o_serial.csv"
(cd "$work" && "$pendavg" average --cases "$odd" --resume "$work/o_serial.csv" 2>"$work/err")
check "... and the file resumes" test $? -eq 0
}
# A signal stops a merge: exit 130, one line, no output and no temporary (a shard read from a
# FIFO that stalls keeps the merge running when the signal comes).
# A signal stops a merge at once, also while it waits on a shard from a pipe whose writer stalls
# (60 s here) and while it opens a FIFO nobody writes to: exit 130 within 5 s, one line, nothing
# written. (It used to wait for the pipe's next data, and to call the FIFO unreadable.)
case:merge.signal() {
local quick=(table --beta log:0.1:10:40 --mu1 0.1,0.5) k what
for k in 1 2; do "$pendavg" "${quick[@]}" --shard "$k/2" --output "$work/g$k.csv"; done
for what in stalled fifo; do
  mkfifo "$work/stall"
  local writer=""
  if [ "$what" = stalled ]; then
    (head -c 3000 "$work/g2.csv"; sleep 60; tail -c +3001 "$work/g2.csv") >"$work/stall" &
    writer=$!
  fi
  "$pendavg" merge --output "$work/g.csv" "$work/g1.csv" "$work/stall" >"$work/out" 2>"$work/err" &
  local pid=$!
  sleep 1
  kill -TERM "$pid"
  for ((k = 0; k < 50; ++k)); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  kill -0 "$pid" 2>/dev/null && kill -KILL "$pid"
  wait "$pid"
  rc=$?
  [ -n "$writer" ] && { pkill -P "$writer"; kill "$writer"; wait "$writer"; } 2>/dev/null
  rm -f "$work/stall"
  if [ "$rc" -eq 130 ] && [ ! -e "$work/g.csv" ] && no_temporaries && [ ! -s "$work/out" ] &&
     [ "$(wc -l <"$work/err")" -eq 1 ] && grep -q '^pendavg: interrupted: merge: ' "$work/err"; then
    pass
  else
    fail "merge stopped by SIGTERM ($what shard)" \
      "exit 130 within 5 s, one 'pendavg: interrupted: merge:' line, no output, no temporary" \
      "exit $rc, $(head -c 200 "$work/err"), output $([ -e "$work/g.csv" ] && echo written || echo absent)"
  fi
done
}
case:shard.refusals() {
for spec in 0/3 4/3 3 a/3 2/0 -1/3 1/-3 "1/3x" 1/1000000000; do bad "--shard $spec" "${table[@]}" --shard "$spec"; done
expect "... the refusal names the largest N" 'grep -q "K <= N <= 999999999" "$work/err"'
bad "--shard with --timing" "${cases[@]}" --shard 1/2 --timing
}

cases_main "$@"
