#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_sweeps.sh -- the sweep commands (`table`, `average --cases`, `simulate
# --replicas`) as a batch job sees them: every row checked before any work, rows streamed with
# bounded memory, output files that follow symbolic links and never replace a device, no
# temporary file left by a signal, finished rows kept on SIGINT/SIGTERM, and --resume giving the
# file an uninterrupted run writes (issues 11 and 14). MPI runs: test_mpi.sh.
#
# Usage: test_sweeps.sh PATH/TO/pendavg CASE    (test_sweeps.sh --list: the cases)
# Prints "CASE: N passed, M failed" last and exits non-zero on any failure.
set -u

pendavg=${1:?usage: test_sweeps.sh PATH/TO/pendavg CASE, or test_sweeps.sh --list}
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=sweep_harness.sh
source "$here/sweep_harness.sh"
# peak_rss_kb PID: the process' peak resident memory so far (kB)
peak_rss_kb() { awk '/^VmHWM:/ { print $2 }' "/proc/$1/status"; }
# start_then_signal SECONDS SIGNAL ARGS...: runs pendavg ARGS in the background, sends SIGNAL
# after SECONDS; leaves its exit code in $rc and its peak memory (kB) in $peak.
start_then_signal() {
  local delay=$1 signal=$2
  shift 2
  "$pendavg" "$@" >"$work/out" 2>"$work/err" &
  local pid=$!
  sleep "$delay"
  peak=$(peak_rss_kb "$pid" 2>/dev/null || echo 0)
  kill "-$signal" "$pid" 2>/dev/null
  wait "$pid"
  rc=$?
}
# signal_after_progress PATTERN SIGNAL ARGS...: as start_then_signal, but the signal goes once
# stderr shows PATTERN (a progress line: rows are being computed), or after 120 s.
signal_after_progress() {
  local pattern=$1 signal=$2
  shift 2
  "$pendavg" "$@" >"$work/out" 2>"$work/err" &
  local pid=$!
  for ((k = 0; k < 600; ++k)); do
    grep -q "$pattern" "$work/err" && break
    sleep 0.2
  done
  peak=$(peak_rss_kb "$pid" 2>/dev/null || echo 0)
  kill "-$signal" "$pid" 2>/dev/null
  wait "$pid"
  rc=$?
}

# ---------------------------------------------------------------- every row checked first
# These computed for seconds to minutes before they were refused (or never ended).
case:checked_first.table() {
bad "table beta 1e300 at 16 digits, refused before the 600-digit rows" \
  table --beta log:1e-3:1e300:60 --digits 16,600 --output "$work/late.csv"
check "table refused: no file" test ! -e "$work/late.csv"
}
case:checked_first.cases_last_row() {
"$python" - "$work/late_cases.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for i in range(2000):
        f.write(f"{1 + i % 7},1,0.5,0.5,1,1\n")
    f.write("1,1,0.5,0.5,1,-1\n")  # bad last row: refused before 2000 rows at 1000 digits
PY
bad "cases bad last row, refused before any row" average --cases "$work/late_cases.csv" --digits 1000
check "cases bad last row: stderr names line 2002" grep -q 'line 2002: l2' "$work/err"
}
case:checked_first.transfer_row() {
# A transfer row (N >= 5) whose beta g S_j l_j overflows is refused before the 200 rows above it
# (N = 64, about 0.4 s each) are computed: it was found only when its turn came.
"$python" - "$work/late_transfer.csv" <<'PY'
import sys
n = 64
with open(sys.argv[1], "w") as f:
    f.write(",".join(["beta", "g"] + [f"m{i}" for i in range(1, n + 1)] + [f"l{i}" for i in range(1, n + 1)]) + "\n")
    for i in range(200):
        f.write(",".join([str(1 + i % 7), "1"] + ["1"] * (2 * n)) + "\n")
    f.write(",".join(["1e10", "1e200"] + ["1"] * n + ["1e200"] * n) + "\n")
PY
bad "cases transfer row out of the double range, refused before any row" average --cases "$work/late_transfer.csv"
check "cases transfer row: stderr names line 202 and the overflow" \
  grep -q "line 202: average: the joints' coefficients g S_j l_j sum to .*beyond double's range" "$work/err"
}
case:checked_first.wide_header() {
# A cases header of 100,000 columns (N = 49999) is read in linear time (it took minutes).
"$python" - "$work/wide.csv" <<'PY'
import random, sys
n = 49999
columns = ["beta", "g"] + [f"m{i}" for i in range(1, n + 1)] + [f"l{i}" for i in range(1, n + 1)]
random.Random(1).shuffle(columns)
with open(sys.argv[1], "w") as f:
    f.write(",".join(columns) + "\n" + ",".join("1" for _ in columns) + "\n")
PY
bad "cases header of 100,000 columns" average --cases "$work/wide.csv"
check "wide header: N read from 100,000 columns" grep -q "transfer takes N <= 16384, not N = 49999" "$work/err"
}

# ---------------------------------------------------------------- streaming, bounded memory
case:memory.cases_1e5_rows() {
# 1e5 rows at 1000 digits (each row's line ~7 kB; 720 MB were reserved up front before): the
# peak once rows are being computed stays under 100 MB; SIGINT keeps the finished rows, in order.
"$python" - "$work/many.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for i in range(100000):
        f.write(f"{0.5 + (i % 97) / 50},1,{0.3 + (i % 13) / 40},0.5,1,{1 + (i % 7) / 10}\n")
PY
signal_after_progress '^\[average\] [1-9]' INT average --cases "$work/many.csv" --digits 1000 --output "$work/many_out.csv"
check "cases 1e5 rows at 1000 digits: peak ${peak} kB < 100 MB" test "$peak" -gt 0 -a "$peak" -lt 102400
check "cases SIGINT: exit 0, footer, rows in order, no temporary" "$python" - "$work/many_out.csv" "$rc" <<'PY'
import sys
assert sys.argv[2] == "0", sys.argv[2]
lines = open(sys.argv[1]).read().splitlines()
assert lines[-1].startswith("# interrupted: ") and lines[-1].endswith("of 100000 rows computed; the rows of the others are left out"), lines[-1]
rows = [l for l in lines if not l.startswith("#")][1:]
assert 0 < len(rows) < 100000, len(rows)
PY
check "cases SIGINT: no temporary" no_temporaries
}
case:memory.chain_256() {
# A chain of 256 over 1e5 betas (1.6 GB of decimal strings were built before the first row).
signal_after_progress '^\[table\] [1-9]' TERM table --chain 256 --beta lin:0.1:10:100000 --method qmc --samples 1024 --shifts 4 \
  --output "$work/chain256.csv"
check "table chain 256 x 1e5 betas: peak ${peak} kB < 100 MB" test "$peak" -gt 0 -a "$peak" -lt 102400
check "table SIGTERM: exit 0 and footer" \
  bash -c "[ $rc -eq 0 ] && tail -1 '$work/chain256.csv' | grep -q '^# interrupted: [0-9]* of 100000 points computed'"
}

# ---------------------------------------------------------------- thread counts
case:threads.tables() {
for args in "table --chain 3,5 --beta 0.5,2 --g 1,2 --digits 16,20" \
            "table --chain 3,5 --beta 0.5,2 --g 1,2 --method qmc --samples 1024 --shifts 4" \
            "table --beta log:0.01:100:30 --mu1 0.01,0.5 --digits 16,25"; do
  # shellcheck disable=SC2086
  OMP_NUM_THREADS=1 "$pendavg" $args >"$work/t1.csv" 2>/dev/null
  # shellcheck disable=SC2086
  OMP_NUM_THREADS=3 "$pendavg" $args >"$work/t3.csv" 2>/dev/null
  # (a refused command leaves both files empty: equal, but nothing compared)
  check "$args: 1 and 3 threads give the same file" \
    bash -c "[ -s '$work/t1.csv' ] && cmp -s '$work/t1.csv' '$work/t3.csv'"
done
}

# ---------------------------------------------------------------- output files
case:output.links() {
echo old >"$work/target.csv"
ln -s target.csv "$work/link.csv"
run table --beta 1 --output "$work/link.csv"
check "--output onto a symlink writes its target" \
  bash -c "[ $rc -eq 0 ] && [ -L '$work/link.csv' ] && grep -q '^2,16,1,1,' '$work/target.csv'"
ln -s no/such/dir/x.csv "$work/dangling.csv"
bad "--output onto a dangling symlink" table --beta 1 --output "$work/dangling.csv"
ln -s loop_a "$work/loop_b"
ln -s loop_b "$work/loop_a"
bad "--output onto a loop of symlinks" table --beta 1 --output "$work/loop_a"
}
case:output.device() {
# A device node is written in place, never replaced by a regular file (as root, --output
# /dev/null used to replace the real device). A private copy of /dev/null when we may make one.
device=/dev/null
mknod "$work/null" c 1 3 2>/dev/null && device="$work/null"
run table --beta 1,2 --output "$device"
check "--output $device: exit 0, still a character device" bash -c "[ $rc -eq 0 ] && [ -c '$device' ]"
}
case:output.fifo() {
mkfifo "$work/fifo"
cat "$work/fifo" >"$work/from_fifo.csv" &
reader=$!
run table --beta 1,2 --output "$work/fifo"
wait "$reader"
check "--output onto a FIFO streams through it" \
  bash -c "[ $rc -eq 0 ] && [ -p '$work/fifo' ] && [ \"\$(grep -c '^2,16,' '$work/from_fifo.csv')\" -eq 2 ]"
}
case:output.pipe() {
# /dev/stdout onto a pipe is a link to "pipe:[N]", a name no readlink can follow: written in place.
"$pendavg" table --beta 1,2 --output /dev/stdout 2>/dev/null | cat >"$work/from_pipe.csv"
pipe_rc=${PIPESTATUS[0]}
check "--output /dev/stdout onto a pipe streams through it" \
  bash -c "[ $pipe_rc -eq 0 ] && [ \"\$(grep -c '^2,16,' '$work/from_pipe.csv')\" -eq 2 ]"
}
case:output.refusals() {
printf 'beta,g,m1,m2,l1,l2\n1,1,0.5,0.5,1,1\n2,1,0.2,0.8,1,2\n' >"$work/cases.csv"
ln -s cases.csv "$work/cases_link.csv"
bad "--timing-rows = the cases file"     average --cases "$work/cases.csv" --timing-rows "$work/cases.csv"
bad "--output = the cases file (symlink)" average --cases "$work/cases_link.csv" --output "$work/cases.csv"
bad "--output = the cases file (./)"      average --cases "$work/cases.csv" --output "$work/./cases.csv"
bad "--timing-rows = --output"          average --cases "$work/cases.csv" --output "$work/o.csv" --timing-rows "$work/o.csv"
bad "--resume and another --output"     table --beta 1 --resume "$work/r1.csv" --output "$work/r2.csv"
# (--output is every command's since output schema 1; --resume stays a sweep's)
bad "--resume without --cases"          average --masses 1,1 --lengths 1,1 --beta 1 --resume "$work/o.csv"
check "--resume without --cases: no file" test ! -e "$work/o.csv"
check "cases file untouched" grep -q '^2,1,0.2,0.8,1,2$' "$work/cases.csv"
}
case:signals.sigterm_table() {
# SIGTERM at any moment of a table written to a file: no temporary file survives, and the file
# is either absent (the signal came before it existed) or complete (all rows, or the finished
# ones and the footer).
for delay in 0.05 0.15 0.3 0.45 0.6 0.8 1.0 1.3; do
  rm -f "$work/sig.csv"
  start_then_signal "$delay" TERM table --beta log:1:1000:40 --mu1 0.001,0.3 --digits 300 \
    --output "$work/sig.csv"
  if ! no_temporaries; then
    fail "SIGTERM after $delay s" "no temporary file left" "$(find "$work" -name '*.tmp.*')"
  elif [ -e "$work/sig.csv" ] && ! "$python" - "$work/sig.csv" <<'PY'; then
import sys
text = open(sys.argv[1]).read()
assert text.endswith("\n")
lines = text.splitlines()
rows = [l for l in lines if not l.startswith("#")][1:]
assert len(rows) == 80 or lines[-1].startswith("# interrupted: %d of 80" % len(rows)), (len(rows), lines[-1])
PY
    fail "SIGTERM after $delay s" "no file, or all 80 rows, or the finished rows and the footer" "an incomplete file (the check's message above)"
  else
    pass
  fi
done
}
case:signals.poincare() {
# poincare writes its file at the end, with the signals deferred meanwhile.
for delay in 0.2 0.5; do
  start_then_signal "$delay" TERM poincare --masses 1,1 --lengths 1,1 --energy -1 --orbits 4 \
    --points 3000 --output "$work/section.csv"
  check "poincare SIGTERM after $delay s: no temporary" no_temporaries
done
}

case:signals.sigkill_temporary() {
# SIGKILL (no handler runs) leaves the temporary; the next write of the same file, once it is
# committed, removes it (its process is gone; --resume would have taken its rows: see
# test_sweep_files.sh), and leaves a live writer's temporary alone.
"$pendavg" table --beta log:1:1000:400 --mu1 0.001,0.05 --digits 300 --output "$work/killed.csv" \
  >/dev/null 2>&1 &
killed=$!
for _ in $(seq 100); do
  [ -n "$(find "$work" -name 'killed.csv.tmp.*' | head -1)" ] && break
  sleep 0.05
done
{ kill -KILL "$killed" && wait "$killed"; } 2>/dev/null  # (no "Killed" job notice)
check "SIGKILL leaves a temporary (the setup of the next check)" \
  test -n "$(find "$work" -name 'killed.csv.tmp.*' | head -1)"
live="$work/killed.csv.tmp.$(hostname | tr -cd 'A-Za-z0-9-' | cut -c1-64).$$.abcdef"
: >"$live"  # this shell's pid: a live writer
run table --beta 1,2 --mu1 0.5 --output "$work/killed.csv"
check "the next write, committed, removes the killed run's temporary" \
  test "$(find "$work" -name 'killed.csv.tmp.*')" = "$live"
rm -f "$live"
}

# ---------------------------------------------------------------- resume
case:resume.table() {
# A sweep killed at a random moment, then resumed: the same file as an uninterrupted run.
sweep=(table --beta log:1:1000:50 --mu1 0.001,0.05 --digits 350)
"$pendavg" "${sweep[@]}" --output "$work/reference.csv" 2>/dev/null
delay=$("$python" -c 'import random; print(round(random.uniform(0.3, 1.2), 2))')
start_then_signal "$delay" TERM "${sweep[@]}" --output "$work/resumed.csv"
interrupted=$(grep -c '^# interrupted' "$work/resumed.csv")
run "${sweep[@]}" --resume "$work/resumed.csv"
check "table killed after $delay s (interrupted: $interrupted) and resumed = uninterrupted" \
  cmp -s "$work/resumed.csv" "$work/reference.csv"
check "resume: no temporary" no_temporaries
# Rows missing anywhere (here every third, and the last ones) are computed again in place.
"$python" "$here/punch_holes.py" "$work/reference.csv" "$work/holes.csv" 5
run "${sweep[@]}" --resume "$work/holes.csv"
check "table with missing rows resumed = uninterrupted" cmp -s "$work/holes.csv" "$work/reference.csv"
run "${sweep[@]}" --resume "$work/holes.csv"
check "resuming a complete file changes nothing" cmp -s "$work/holes.csv" "$work/reference.csv"
run "${sweep[@]}" --resume "$work/fresh.csv"
check "--resume of a file not there yet writes it" cmp -s "$work/fresh.csv" "$work/reference.csv"
cp "$work/reference.csv" "$work/other.csv"
bad "resume with other digits" table --beta log:1:1000:50 --mu1 0.001,0.05 --digits 300 --resume "$work/other.csv"
check "resume mismatch: the differing line is named" grep -q 'digits = 350' "$work/err"
bad "resume with another beta range" table --beta log:1:100:50 --mu1 0.001,0.05 --digits 350 --resume "$work/other.csv"
sed 's/^# pendavg [0-9.]*,/# pendavg 0.0.1,/' "$work/reference.csv" >"$work/old_version.csv"
bad "resume of another version's file" "${sweep[@]}" --resume "$work/old_version.csv"
sed '20s/^2,350,[^,]*,/2,350,7.5,/' "$work/reference.csv" >"$work/foreign_row.csv"
bad "resume of a file with a foreign row" "${sweep[@]}" --resume "$work/foreign_row.csv"
check "failed resumes leave the file" cmp -s "$work/other.csv" "$work/reference.csv"
strip_added_columns "$work/reference.csv" "$work/before_issue10.csv"
cp "$work/before_issue10.csv" "$work/before_issue10_copy.csv"
bad "table resume of a file with the columns before issue 10" "${sweep[@]}" --resume "$work/before_issue10.csv"
check "table resume before issue 10: reason" grep -q "is not an output of this sweep" "$work/err"
check "table resume before issue 10: the file is left as it was" cmp -s "$work/before_issue10.csv" "$work/before_issue10_copy.csv"
}

# Microcanonical sweeps (issue 15) share the engine: a table at fixed excitation and cases with
# an energy column, rows missing anywhere, resumed = uninterrupted.
punch_holes() { "$python" "$here/punch_holes.py" "$1" "$2"; }  # FILE OUT (punch_holes.py)
case:resume.microcanonical() {
micro_sweep=(table --excitation log:1e-9:1:10 --g 1,9.81 --chain 3)
"$pendavg" "${micro_sweep[@]}" --output "$work/micro_reference.csv" 2>/dev/null
punch_holes "$work/micro_reference.csv" "$work/micro_holes.csv"
run "${micro_sweep[@]}" --resume "$work/micro_holes.csv"
check "microcanonical table with missing rows resumed = uninterrupted" \
  cmp -s "$work/micro_holes.csv" "$work/micro_reference.csv"
printf 'energy,g,m1,m2,l1,l2\n' >"$work/micro_cases.csv"
for e in -2.9 -2 -1 0 1 3 10; do printf '%s,1,1,1,1,1\n%s,9.81,0.3,1,2,0.5\n' "$e" "$e"; done >>"$work/micro_cases.csv"
"$pendavg" average --cases "$work/micro_cases.csv" --output "$work/micro_cases_reference.csv" 2>/dev/null
punch_holes "$work/micro_cases_reference.csv" "$work/micro_cases_holes.csv"
run average --cases "$work/micro_cases.csv" --resume "$work/micro_cases_holes.csv"
check "microcanonical cases with missing rows resumed = uninterrupted" \
  cmp -s "$work/micro_cases_holes.csv" "$work/micro_cases_reference.csv"
bad "microcanonical resume of a beta file" table --beta log:1e-9:1:10 --g 1,9.81 --chain 3 \
  --resume "$work/micro_reference.csv"
}

# average --cases --output: the schema line, then '#' lines that name the cases (by hash),
# digits, method, version; the rows are stdout's (stdout: the schema line, the column line, the
# rows); interrupted and resumed gives the uninterrupted file.
case:resume.cases() {
"$python" - "$work/cases300.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("m1,m2,l1,l2,beta,g\n")
    for i in range(300):
        f.write(f"{0.001 + (i % 17) / 20},1,1,{2 ** (i % 5 - 2)},{10 ** ((i % 23) / 8 - 1)},1\n")
PY
"$pendavg" average --cases "$work/cases300.csv" --digits 250 --output "$work/cases_reference.csv" 2>/dev/null
"$pendavg" average --cases "$work/cases300.csv" --digits 250 >"$work/cases_stdout.csv" 2>/dev/null
check "cases --output: '#' lines, then stdout's CSV" "$python" - "$work/cases_reference.csv" "$work/cases_stdout.csv" <<'PY'
import sys
lines = open(sys.argv[1]).read().splitlines(keepends=True)
assert lines[0] == "# schema: 1\n", lines[0]
assert lines[1].startswith("# pendavg average --cases: 300 rows of N = 2, cases file fnv1a-64 "), lines[1]
assert lines[2] == "# digits = 250, method = auto\n", lines[2]
assert lines[3].startswith("# pendavg ") and ", generated 2026-01-01T00:00:00Z (UTC) from " in lines[3], lines[3]
assert "".join(lines[:1] + lines[4:]) == open(sys.argv[2]).read()
PY
# --columns: a resumed file keeps its columns (resumed = uninterrupted); other columns are refused.
columns=(average --cases "$work/cases300.csv" --columns ratio,var_K_error,beta_K1)
"$pendavg" "${columns[@]}" --output "$work/columns_reference.csv" 2>/dev/null
punch_holes "$work/columns_reference.csv" "$work/columns_holes.csv"
run "${columns[@]}" --resume "$work/columns_holes.csv"
check "cases --columns with missing rows resumed = uninterrupted" \
  cmp -s "$work/columns_holes.csv" "$work/columns_reference.csv"
bad "cases resume with other --columns" average --cases "$work/cases300.csv" --columns ratio \
  --resume "$work/columns_reference.csv"
bad "cases resume without its --columns" average --cases "$work/cases300.csv" \
  --resume "$work/columns_reference.csv"
delay=$("$python" -c 'import random; print(round(random.uniform(0.2, 0.8), 2))')
start_then_signal "$delay" INT average --cases "$work/cases300.csv" --digits 250 --output "$work/cases_resumed.csv"
run average --cases "$work/cases300.csv" --digits 250 --resume "$work/cases_resumed.csv"
check "cases interrupted after $delay s and resumed = uninterrupted" \
  cmp -s "$work/cases_resumed.csv" "$work/cases_reference.csv"
sed '2s/^0.001,/0.002,/' "$work/cases300.csv" >"$work/cases300b.csv"
cp "$work/cases_reference.csv" "$work/cases_other.csv"
bad "cases resume with other cases" average --cases "$work/cases300b.csv" --digits 250 --resume "$work/cases_other.csv"
bad "cases resume with another method" average --cases "$work/cases300.csv" --digits 250 --method series --resume "$work/cases_other.csv"
strip_added_columns "$work/cases_reference.csv" "$work/cases_before_issue10.csv"
bad "cases resume of a file with the columns before issue 10" average --cases "$work/cases300.csv" --digits 250 \
  --resume "$work/cases_before_issue10.csv"
}
# Issue 10 added columns (the kinds of every error, work_unit, the equipartition residual,
# beta<K_i^(c)>), which output schema 1 places after cos_phi_error_kind: the resumed files above
# carry them; a file written with the columns before them (same version and schema) is refused,
# not extended with ragged rows.
strip_added_columns() { # FILE OUT: the column line and rows cut before cos_phi_error_kind
  "$python" - "$1" "$2" <<'PY'
import sys
lines = open(sys.argv[1]).read().splitlines(keepends=True)
columns = next(l for l in lines if not l.startswith("#")).rstrip("\n").split(",")
keep = columns.index("cos_phi_error_kind")
cut = columns[keep:]
for added in ["cos_phi_error_kind", "var_K_error_kind", "work_unit", "equipartition_residual",
              "beta_Kc1", "beta_Kc1_error", "beta_Kc_error_kind"]:
    assert added in cut, added
assert columns[-1] == "interrupted", columns[-1]
out = [l if l.startswith("#") else ",".join(l.rstrip("\n").split(",")[:keep]) + "\n" for l in lines]
open(sys.argv[2], "w").write("".join(out))
PY
}

# ---------------------------------------------------------------- simulate --replicas
case:replicas.langevin() {
replicas=(simulate --masses 1,1 --lengths 1,1 --theta 0 --time 100 --thermostat langevin --beta 1 --seed 7 --replicas 4 --format json)
OMP_NUM_THREADS=1 "$pendavg" "${replicas[@]}" >"$work/rep1.json" 2>/dev/null
OMP_NUM_THREADS=2 "$pendavg" "${replicas[@]}" >"$work/rep2.json" 2>/dev/null
check "replicas: 1 and 2 threads give the same numbers" \
  bash -c "diff <(sed 's/\"seconds\": [^,}]*//' '$work/rep1.json') <(sed 's/\"seconds\": [^,}]*//' '$work/rep2.json') >/dev/null"
check "replicas: combined averages and both error bars" "$python" - "$work/rep2.json" <<'PY'
import json, math, sys
d = json.load(open(sys.argv[1]))
assert d["replicas"] == d["replicas_requested"] == 4 and not d["interrupted"], d
assert d["steps"] == 4 * 100000, d["steps"]
for i in range(2):
    assert d["K_error"][i] == max(d["K_error_blocking"][i], d["K_error_replicas"][i]), i
    assert d["K_error_replicas"][i] > 0 and d["K_error_blocking"][i] > 0
    assert abs(d["K"][i] - d["exact_K"][i]) <= 4 * math.hypot(d["K_error"][i], d["exact_K_error"][i]), i
PY
"$pendavg" simulate --masses 1,1 --lengths 1,1 --theta 0 --time 100 --thermostat langevin --beta 1 --seed 7 --format json >"$work/single.json" 2>/dev/null
"$pendavg" simulate --masses 1,1 --lengths 1,1 --theta 0 --time 100 --thermostat langevin --beta 1 --seed 7 --replicas 1 --format json >"$work/rep_one.json" 2>/dev/null
check "--replicas 1 is the single run" \
  bash -c "diff <(sed 's/\"seconds\": [^,}]*//' '$work/single.json') <(sed 's/\"seconds\": [^,}]*//' '$work/rep_one.json') >/dev/null"
}
case:replicas.nve() {
run simulate --masses 1,1,1 --lengths 1,1,1 --theta 90deg --time 30 --replicas 3 --seed 2 --format csv --exact no
check "NVE replicas (perturbed starts), csv" "$python" - "$work/out" "$rc" <<'PY'
import csv, sys
assert sys.argv[2] == "0", sys.argv[2]
lines = open(sys.argv[1]).read().splitlines()
assert lines[0] == "# schema: 1" and len(lines) == 4, lines[:2]
r = next(csv.DictReader(lines[2:]))
assert r["replicas"] == r["replicas_requested"] == "3", r
for i in (1, 2, 3):
    for column in (f"K_autocorrelation_time{i}", f"K{i}_error_blocking", f"K{i}_error_replicas"):
        assert float(r[column]) > 0, column
PY
}
case:replicas.refusals() {
bad "replicas with --trajectory" simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --replicas 2 --trajectory "$work/t.csv" --every 1
bad "replicas 0"                 simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --replicas 0
bad "perturb with langevin"      simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --replicas 2 --thermostat langevin --beta 1 --perturb 1e-3
bad "seed, one NVE run"          simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --seed 3
}
case:replicas.sigint() {
start_then_signal 1 INT simulate --masses 1,1,1 --lengths 1,1,1 --theta 0 --time 1e6 --thermostat langevin --beta 1 --replicas 4 --exact no --format json
check "replicas SIGINT: exit 0, interrupted averages of the replicas so far" "$python" - "$work/out" "$rc" <<'PY'
import json, sys
assert sys.argv[2] == "0", sys.argv[2]
d = json.load(open(sys.argv[1]))
assert d["interrupted"] and 1 <= d["replicas"] <= 4 and d["steps"] > 0, d
PY
}


cases_main "$@"
