#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_mpi.sh -- pendavg under MPI (issue 14): the outputs of 1, 2 and 3 ranks
# (oversubscribed on this machine: correctness, not speed) are the outputs of the plain serial
# run, byte for byte apart from timing fields; a sweep killed under mpirun and resumed on
# another number of ranks gives the uninterrupted file; bad input is reported once; a failure on
# one rank stops the job and names the rank.
#
# Usage: test_mpi.sh PATH/TO/pendavg CASE MPIEXEC PATH/TO/pendavg_row_faults
# (the test build, whose hooks tests/cli/row_faults.cpp describes: rows or ranks that fail on
# demand, a small reorder window, the rows each rank computed; test_mpi.sh --list: the cases)
# Prints "CASE: N passed, M failed" last and exits non-zero on any failure.
set -u

usage="usage: test_mpi.sh PATH/TO/pendavg CASE MPIEXEC PATH/TO/pendavg_row_faults, or test_mpi.sh --list"
pendavg=${1:?$usage}
mpiexec=${3:-}
faulty=${4:-}
[ "$pendavg" = --list ] || [ -n "$faulty" ] || { echo "$usage" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=sweep_harness.sh
source "$here/sweep_harness.sh"

cases_setup() {
# What OpenMPI needs in a CI container: running as root, more ranks than cores, shared memory
# between the ranks only (no network), local launch without ssh, no CMA (ptrace may be
# forbidden), no binding (the ranks' OpenMP threads share the cores).
launcher=("$mpiexec")
if "$mpiexec" --version 2>&1 | grep -q "Open MPI\|OpenRTE"; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
  export OMPI_MCA_btl_vader_single_copy_mechanism=none
  launcher+=(--oversubscribe --bind-to none --mca btl self,vader --mca plm isolated)
fi
# cases.csv: 2,000 rows (the benchmark's spread of costs)
"$python" - "$work/cases.csv" <<'PY'
import math, random, sys
rng = random.Random(2026)
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for _ in range(2000):
        beta = 10 ** rng.uniform(-4, 4)
        x = 10 ** rng.uniform(-6, math.log10(0.5))
        mu1 = x if rng.random() < 0.5 else 1 - x
        f.write(f"{beta:.6g},1,{mu1:.9g},{1 - mu1:.9g},1,{10 ** rng.uniform(-2, 2):.6g}\n")
PY
}

# on_ranks K OUT ARGS...: mpiexec -n K pendavg ARGS > OUT (K = 0: the plain serial run)
on_ranks() {
  local ranks=$1 out=$2
  shift 2
  if [ "$ranks" -eq 0 ]; then
    "$pendavg" "$@" >"$out" 2>"$work/err"
  else
    "${launcher[@]}" -n "$ranks" "$pendavg" "$@" >"$out" 2>"$work/err"
  fi
}
# without_timing FILE: the file minus what depends on the clock ("seconds" in JSON)
without_timing() { sed 's/"seconds": [^,}]*//' "$1"; }
# same_on_ranks NAME ARGS...: serial, then 1, 2 and 3 ranks (threads 2, 1, 2, 1), compared.
same_on_ranks() {
  local name=$1
  shift
  OMP_NUM_THREADS=2 on_ranks 0 "$work/serial.out" "$@" || { fail "$name: serial run" "exit 0" "exit $?"; return; }
  [ -s "$work/serial.out" ] || { fail "$name: serial run" "an output" "nothing printed"; return; }
  local ranks threads=1
  for ranks in 1 2 3; do
    OMP_NUM_THREADS=$threads on_ranks "$ranks" "$work/ranks.out" "$@"
    rc=$?
    if [ "$rc" -ne 0 ]; then
      fail "$name: $ranks ranks" "exit 0, the serial run's output" "exit $rc"
    elif ! cmp -s <(without_timing "$work/serial.out") <(without_timing "$work/ranks.out"); then
      fail "$name: $ranks ranks" "the serial run's output" "another output"
    else
      pass
    fi
    threads=$((3 - threads))
  done
}

# 20,000 double rows (cases.csv ten times) on 1-3 ranks: with Open MPI's osc/sm under this
# launcher (no single-copy mechanism) the ranks other than 0 never saw rank 0 move the reorder
# window and the job hung; every run here is bounded (a liveness check, not a timing).
case:ranks.many_rows() {
{ head -n 1 "$work/cases.csv"; for k in 1 2 3 4 5 6 7 8 9 10; do tail -n +2 "$work/cases.csv"; done; } \
  >"$work/many.csv"
launcher=(timeout 120 "${launcher[@]}")
same_on_ranks "20,000 double rows" average --cases "$work/many.csv"
}
# --cases: 2,000 rows at 38 digits, to stdout and to a file.
case:ranks.cases_38_digits() {
same_on_ranks "cases 2000 rows, 38 digits" average --cases "$work/cases.csv" --digits 38
}
case:ranks.cases_columns() {
same_on_ranks "cases 2000 rows, --columns" average --cases "$work/cases.csv" --columns var_K,ratio,beta_K2
}
# cases_serial: $work/cases_serial.csv, the serial run's file
cases_serial() { "$pendavg" average --cases "$work/cases.csv" --output "$work/cases_serial.csv" 2>/dev/null; }
case:ranks.cases_output() {
cases_serial
for ranks in 2 3; do
  rm -f "$work/cases_ranks.csv"
  "${launcher[@]}" -n "$ranks" "$pendavg" average --cases "$work/cases.csv" --output "$work/cases_ranks.csv" 2>"$work/err"
  check "cases --output on $ranks ranks: the serial file" cmp -s "$work/cases_ranks.csv" "$work/cases_serial.csv"
done
}
# table: chains of 3 and 8 by qmc and by auto (torus, transfer), and a double-pendulum sweep
# mixing double and MPFR rows.
case:ranks.table_qmc() {
same_on_ranks "table --chain 8 qmc" table --chain 3,8 --beta log:0.1:10:12 --g 1,2 --method qmc --samples 2048 --shifts 8
}
case:ranks.table_auto() {
same_on_ranks "table --chain 8 auto" table --chain 3,8 --beta log:0.1:10:6 --g 1,2 --tol 1e-8
}
case:ranks.table_mixed_digits() {
same_on_ranks "table mixed digits" table --beta log:0.01:100:40 --mu1 0.01,0.5 --digits 16,30
}
# One qmc point at N = 64: its shifts shared by the ranks. (JSON, whose "seconds" without_timing
# leaves out: the default CSV has it as a column.)
case:ranks.qmc_point() {
unit64=$("$python" -c 'print(",".join(["1"] * 64))')
same_on_ranks "qmc point N = 64" average --masses "$unit64" --lengths "$unit64" --beta 1 --method qmc --samples 4096 --shifts 12 --format json
}
# Trajectory replicas, N = 3: Langevin (noise streams) and NVE (perturbed starts).
case:ranks.replicas() {
same_on_ranks "simulate --replicas 4, Langevin" simulate --masses 1,1,1 --lengths 1,1,1 --theta 0 --time 40 --thermostat langevin --beta 1 --replicas 4 --format json
same_on_ranks "simulate --replicas 4, NVE" simulate --masses 1,1,1 --lengths 1,1,1 --theta 90deg --time 40 --replicas 4 --exact no --format json
}
# Commands that do not distribute run on rank 0 alone and print once.
case:ranks.limit() {
same_on_ranks "limit on rank 0" limit --masses 0.5,0.5 --format json
}

# A sweep under mpirun killed with SIGTERM (what a batch scheduler sends; mpirun forwards it)
# at a random moment, then resumed on 3 ranks: the file of the uninterrupted serial run.
case:resume.killed() {
export OMP_NUM_THREADS=2
sweep=(table --beta log:1:1000:50 --mu1 0.001,0.05 --digits 1000)
"$pendavg" "${sweep[@]}" --output "$work/reference.csv" 2>/dev/null
delay=$("$python" -c 'import random; print(round(random.uniform(0.8, 2.0), 2))')
"${launcher[@]}" -n 2 "$pendavg" "${sweep[@]}" --output "$work/resumed.csv" \
  >/dev/null 2>"$work/killed.err" &
pid=$!
sleep "$delay"
kill -TERM "$pid" 2>/dev/null
wait "$pid"
[ -e "$work/resumed.csv" ] || cp /dev/null "$work/resumed.csv"  # killed before the file existed
interrupted=$(grep -c '^# interrupted' "$work/resumed.csv")
[ -s "$work/resumed.csv" ] || rm -f "$work/resumed.csv"
expected="killed under mpirun after $delay s (interrupted: $interrupted): no temporary; resumed on 3 ranks: exit 0, the serial file"
if [ -n "$(find "$work" -name '*.tmp.*' | head -1)" ]; then
  fail "SIGTERM under mpirun, resumed" "$expected" "a temporary file left"
elif ! "${launcher[@]}" -n 3 "$pendavg" "${sweep[@]}" --resume "$work/resumed.csv" >/dev/null 2>"$work/err"; then
  fail "SIGTERM under mpirun, resumed" "$expected" "the resume on 3 ranks failed"
elif ! cmp -s "$work/resumed.csv" "$work/reference.csv"; then
  fail "SIGTERM under mpirun, resumed" "$expected" "another file"
else
  pass
fi
# The whole mpirun killed with SIGKILL (a node lost, the job's processes killed outright): rank
# 0's temporary keeps the rows it had written, and --resume on 2 ranks takes them.
killed_and_resumed "table under mpirun -n 2" "$work/reference.csv" "$work/killed.csv" \
  "${launcher[@]}" -n 2 "$faulty" "${sweep[@]}"
}

# SIGTERM to mpirun while rows of ~1.5 s run (N = 3 at 30 digits): mpirun kills the ranks 1 s
# after it forwards the signal, so the rows' grace must end, and rank 0 write its file, before
# then. With a grace of 1 s only the temporary was left, in 5 of 6 tries.
case:stops.slow_rows() {
local out=$work/slow.csv k temporary rows=0
"${launcher[@]}" -n 2 "$pendavg" table --chain 3 --beta log:0.1:10:30 --digits 30 \
  --output "$out" >/dev/null 2>"$work/slow.err" &
local pid=$!
for ((k = 0; k < 600 && rows < 2; ++k)); do  # until the temporary holds 2 rows
  sleep 0.05
  temporary=$(find "$work" -name 'slow.csv.tmp.*' | head -1)
  [ -n "$temporary" ] && rows=$(grep -c '^3,' "$temporary")
done
kill -TERM "$pid"
wait "$pid"
if grep -q '^# interrupted: ' "$out" 2>/dev/null && [ -z "$(find "$work" -name 'slow.csv.tmp.*')" ]; then
  pass
else
  fail "SIGTERM to mpirun during rows of 1.5 s" "the file with an '# interrupted' line, no temporary" \
    "$(ls "$work" | grep slow.csv | tr '\n' ' ')"
fi
}

# stopped_simulate NAME DELAY N ARGS...: simulate of N unit particles (Langevin, dt 1e-5) under
# mpirun -n 2, SIGTERM to mpirun after DELAY s; the JSON file must hold the averages so far
# (interrupted) and no temporary be left.
stopped_simulate() {
local name=$1 delay=$2 unit out=$work/stopped.json
unit=$("$python" -c "print(','.join(['1'] * $3))")
shift 3
"${launcher[@]}" -n 2 "$pendavg" simulate --masses "$unit" --lengths "$unit" --theta 0 \
  --dt 1e-5 --thermostat langevin --beta 1 --exact no --format json --output "$out" "$@" \
  >/dev/null 2>"$work/stopped.err" &
local pid=$!
sleep "$delay"
kill -TERM "$pid"
wait "$pid"
if "$python" -c "import json, sys; assert json.load(open(sys.argv[1]))['interrupted']" "$out" 2>/dev/null &&
   [ -z "$(find "$work" -name 'stopped.json.tmp.*')" ]; then
  pass
else
  fail "$name" "the averages so far, interrupted, no temporary" \
    "$(ls "$work" | grep stopped.json | tr '\n' ' ')"
fi
}

# SIGTERM to mpirun while rank 0 runs both replicas of a simulate (its 2 threads take them; rank
# 1, with none, waits at the job's end): rank 1 must not die of the signal, which made mpirun
# kill rank 0 before it wrote the averages so far.
case:stops.idle_rank() {
OMP_NUM_THREADS=2 stopped_simulate "SIGTERM to mpirun with a rank idle" 3 200 --time 1000 --replicas 2
}

# SIGTERM to mpirun during one trajectory of N = 16384 (rank 0 alone; 1024 steps take seconds):
# the run must see the stop well within mpirun's 1 s. Checked every 1024 steps, it was killed
# before it wrote in 2 of 3 tries.
case:stops.long_chain() {
stopped_simulate "SIGTERM to mpirun during a trajectory of N = 16384" 4 16384 --time 100
}

# A signal to rank 0 alone (a stop set on rank 0's own window) stops every rank: with Open MPI's
# osc/sm (the launcher here has no single-copy mechanism) rank 1 never saw it and computed every
# row left. Rank 0 is signalled once its temporary holds 10 rows; the others stop within the
# rows' grace, so the file ends with far fewer than its 600 rows and an '# interrupted' line.
case:stops.rank0_alone() {
export OMP_NUM_THREADS=1
local out=$work/stop.csv rank0="" pid k rows=0 temporary
"${launcher[@]}" -n 2 "$pendavg" table --beta log:1:1000:200 --mu1 0.001,0.05,0.3 --digits 1000 \
  --output "$out" >/dev/null 2>"$work/stop.err" &
pid=$!
for ((k = 0; k < 600 && rows < 10; ++k)); do
  sleep 0.05
  temporary=$(find "$work" -name 'stop.csv.tmp.*' | head -1)
  [ -n "$temporary" ] && rows=$(grep -c '^2,' "$temporary")
done
for k in $(pgrep -f -- "--output $out"); do
  tr '\0' '\n' <"/proc/$k/environ" 2>/dev/null | grep -qxE '(OMPI_COMM_WORLD_RANK|PMI_RANK)=0' && rank0=$k
done
[ -n "$rank0" ] && kill -TERM "$rank0"
wait "$pid"
local written
written=$(grep -c '^2,' "$out" 2>/dev/null)
if [ -n "$rank0" ] && grep -q '^# interrupted: ' "$out" && [ "${written:-600}" -lt 300 ]; then
  pass
else
  fail "SIGTERM to rank 0 alone" "an '# interrupted' line, fewer than 300 of the 600 rows" \
    "rank 0 ${rank0:-not found}, $(tail -n 1 "$out" 2>/dev/null | cut -c1-60), $written rows"
fi
}

# The test build: a resumed file with holes (every third row missing) completed, and a file
# written afresh, on 2 and 3 ranks with a reorder window of 16 rows (PENDAVG_SWEEP_WINDOW_ROWS:
# rows wait for the window to move), are the serial file; the ranks other than 0 computed rows
# (PENDAVG_SWEEP_REPORT); every run ends (a bound of 120 s: a liveness check, not a timing).
# Rows finished on rank 1 ahead of rank 0's slow row 0 survive a SIGKILL of the whole job.
case:resume.killed_ahead() {
killed_ahead "rows ahead kept under mpirun" csv "${launcher[@]}" -n 2 "$faulty"
}
case:resume.window() {
export OMP_NUM_THREADS=2
"$pendavg" average --cases "$work/cases.csv" --digits 38 --output "$work/cases38.csv" 2>/dev/null
"$python" "$here/punch_holes.py" "$work/cases38.csv" "$work/holes.csv"
for ranks in 2 3; do
  cp "$work/holes.csv" "$work/holes_resumed.csv"
  rm -f "$work/cases_window.csv"
  for out in cases_window.csv holes_resumed.csv; do
    if [ "$out" = cases_window.csv ]; then target=(--output "$work/$out"); else target=(--resume "$work/$out"); fi
    PENDAVG_SWEEP_WINDOW_ROWS=16 PENDAVG_SWEEP_REPORT=1 timeout 120 "${launcher[@]}" -n "$ranks" \
      "$faulty" average --cases "$work/cases.csv" --digits 38 "${target[@]}" 2>"$work/err"
    rc=$?
    others=$(sed -n 's/^pendavg: test: sweep .*rows per rank: [0-9]*\([0-9 ]*\);.*/\1/p' "$work/err" |
             tr ' ' '\n' | awk '{ s += $1 } END { print s + 0 }')
    what="$out on $ranks ranks, a window of 16 rows"
    expected="exit 0, rows computed by the ranks other than 0, the serial file"
    if [ "$rc" -ne 0 ]; then
      fail "$what" "$expected" "exit $rc"
    elif [ "$others" -eq 0 ]; then
      fail "$what" "$expected" "the ranks other than 0 computed no row"
    elif ! cmp -s "$work/$out" "$work/cases38.csv"; then
      fail "$what" "$expected" "another file"
    else
      pass
    fi
  done
done
}

# PENDAVG_MPI=0 keeps the process out of MPI: started as several ranks, each would run the whole
# command (silent copies), so it refuses as a build without MPI does: rank 0 in one line, every
# rank exits 2, nothing written.
case:refusals.mpi_off() {
local refusal="^pendavg: error: started as 2 ranks (mpirun/srun), but PENDAVG_MPI=0 keeps this pendavg out of MPI: "
PENDAVG_MPI=0 "${launcher[@]}" -x PENDAVG_MPI -n 2 "$pendavg" table --beta 1,2 --output "$work/off.csv" \
  >"$work/out" 2>"$work/err"
rc=$?
if [ "$rc" -ne 0 ] && [ ! -s "$work/out" ] && [ "$(grep -c '^pendavg: ' "$work/err")" -eq 1 ] &&
   grep -q "$refusal" "$work/err" && [ -z "$(find "$work" -name 'off.csv*' | head -1)" ]; then
  pass
else
  fail "PENDAVG_MPI=0 under mpirun -n 2" "a non-zero exit, one line '$refusal...', no file" \
    "exit $rc, $(grep -c '^pendavg: ' "$work/err") pendavg lines"
fi
}
# A launcher whose ranks MPI does not connect (srun --mpi=none: Slurm's variables, each process an
# MPI singleton): every rank refuses, the first says so once, no file.
case:refusals.singletons() {
local refusal="^pendavg: error: started as 2 ranks (mpirun/srun), but MPI sees one rank "
local pids=()
for rank in 0 1; do
  SLURM_STEP_NUM_TASKS=2 SLURM_PROCID=$rank timeout 60 "$pendavg" table --beta 1,2 \
    --output "$work/single.csv" >"$work/out$rank" 2>"$work/err$rank" &
  pids+=($!)
done
wait "${pids[0]}"; rc0=$?
wait "${pids[1]}"; rc1=$?
if [ "$rc0" -eq 2 ] && [ "$rc1" -eq 2 ] && [ ! -s "$work/out0" ] && [ ! -s "$work/out1" ] &&
   [ "$(cat "$work/err0" "$work/err1" | grep -c '^pendavg: ')" -eq 1 ] && grep -q "$refusal" "$work/err0" &&
   [ -z "$(find "$work" -name 'single.csv*' | head -1)" ]; then
  pass
else
  fail "2 Slurm tasks that MPI does not connect" "exit 2 on both, one line '$refusal...', no file" \
    "exits $rc0 and $rc1, $(cat "$work/err0" "$work/err1" | grep -c '^pendavg: ') pendavg lines"
fi
}
# Bad input: every rank refuses it, rank 0 alone says so (mpirun may add its own lines).
case:refusals.bad_input() {
"${launcher[@]}" -n 2 "$pendavg" table --beta log:1e-3:1e300:60 --digits 16,600 >"$work/out" 2>"$work/err"
rc=$?
if [ "$rc" -eq 0 ] || [ -s "$work/out" ] || [ "$(grep -c '^pendavg: error: ' "$work/err")" -ne 1 ]; then
  fail "bad input under mpirun" "a non-zero exit, nothing on stdout, one error line" \
    "exit $rc, $(grep -c '^pendavg: error: ' "$work/err") error lines"
else
  pass
fi
}

# What rank 0 alone meets for the job (a command that does not distribute, an output it cannot
# write) is worded as a single process words it: the same line, no rank named.
case:refusals.root_alone() {
local name
for name in merge table; do
  local args=(merge --output "$work/merged.csv" "$work/no_such_shard.csv")
  [ "$name" = table ] && args=(table --beta log:0.1:10:20 --output /dev/full)
  "$pendavg" "${args[@]}" >/dev/null 2>"$work/err_serial"
  local rc_serial=$?
  timeout 60 "${launcher[@]}" -n 2 "$pendavg" "${args[@]}" >"$work/out" 2>"$work/err"
  rc=$?
  if [ "$rc" -eq "$rc_serial" ] && [ "$rc" -ne 0 ] && [ ! -s "$work/out" ] &&
     [ "$(grep -c '^pendavg: ' "$work/err")" -eq 1 ] &&
     [ "$(grep '^pendavg: ' "$work/err")" = "$(cat "$work/err_serial")" ]; then
    pass
  else
    fail "$name's failure on rank 0 under mpirun" "the serial run's exit ($rc_serial) and line"       "exit $rc: $(grep '^pendavg: ' "$work/err" | head -2)"
  fi
done
}

# An output no rank can write (a FIFO nobody reads): refused on every rank before any row, rank 0
# says so once (not a rank alone that stops the job after 10 s).
case:refusals.fifo() {
mkfifo "$work/fifo"
timeout 60 "${launcher[@]}" -n 2 "$pendavg" table --beta log:0.1:10:20 --output "$work/fifo" \
  >"$work/out" 2>"$work/err"
rc=$?
if [ "$rc" -ne 2 ] || [ "$(grep -c '^pendavg: ' "$work/err")" -ne 1 ] ||
   ! grep -q "^pendavg: error: table: cannot write '$work/fifo': it is a FIFO that no process reads$" "$work/err"; then
  fail "a FIFO nobody reads under mpirun" "exit 2, one error line by rank 0 naming the FIFO" "exit $rc"
else
  pass
fi
}

# A failure on one rank alone (the test build's PENDAVG_TEST_FAIL_ON_RANK=K: just before the
# sweep's first collective step, as a failing output on rank 0 would be; K:sweep: as its sweep
# begins) must not leave the others waiting for it forever. Before the sweep, or on rank 0 (the
# writer), that rank names itself and stops the job (MPI_Abort) once the others have not ended
# within 10 s, or (rank 0 in its sweep, when the others stopped and ended) just names itself; no
# output is left. Rank 1 failing in the sweep stops the sweep: rank 0 writes every
# finished row and an '# interrupted' line, rank 1 names itself, the job exits non-zero, and
# --resume completes the file (the serial one). The four cases at once (they mostly wait; a bound
# of 90 s: liveness, not timing). The same failure on every rank (all:sweep) is reported once, by
# rank 0, and leaves no file.
case:failures.one_rank() {
cases_serial
cases=(0 1 0:sweep 1:sweep)
pids=()
for k in "${!cases[@]}"; do
  PENDAVG_TEST_FAIL_ON_RANK=${cases[$k]} timeout 90 "${launcher[@]}" -n 2 "$faulty" average \
    --cases "$work/cases.csv" --output "$work/alone$k.csv" >/dev/null 2>"$work/alone$k.err" &
  pids+=($!)
done
for k in "${!pids[@]}"; do
  wait "${pids[$k]}"
  rc=$?
  failing=${cases[$k]%%:*}
  if [ "${cases[$k]}" = 1:sweep ]; then
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && grep -q '^# interrupted: ' "$work/alone$k.csv" &&
       grep -q "^pendavg: internal error: .*(PENDAVG_TEST_FAIL_ON_RANK) (rank 1)$" "$work/alone$k.err" &&
       "$pendavg" average --cases "$work/cases.csv" --resume "$work/alone$k.csv" 2>/dev/null &&
       cmp -s "$work/alone$k.csv" "$work/cases_serial.csv"; then
      pass
    else
      fail "a failure on rank 1 once the sweep began" \
        "a non-zero exit, a report naming rank 1, the finished rows kept, resumed to the whole output" \
        "exit $rc, or no such report, rows or resume"
      sed 's/^/  stderr: /' "$work/alone$k.err" | head -5
    fi
  elif [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && [ ! -e "$work/alone$k.csv" ] &&
     grep -Eq "^pendavg: internal error: .*\(PENDAVG_TEST_FAIL_ON_RANK\) \(rank $failing( alone; stopping the job)?\)$" \
       "$work/alone$k.err"; then
    pass
  else
    fail "a failure on rank ${cases[$k]} alone" "a non-zero exit, a report naming the rank, no output" \
      "exit $rc, or no such report, or an output written"
    sed 's/^/  stderr: /' "$work/alone$k.err" | head -5
  fi
done
}
case:failures.every_rank() {
  PENDAVG_TEST_FAIL_ON_RANK=all:sweep timeout 60 "${launcher[@]}" -n 3 "$faulty" average \
    --cases "$work/cases.csv" --output "$work/all.csv" >/dev/null 2>"$work/err"
  rc=$?
  if [ "$rc" -eq 1 ] && [ "$(grep -c '^pendavg: ' "$work/err")" -eq 1 ] &&
     grep -q '^pendavg: internal error: a failure injected on this rank (PENDAVG_TEST_FAIL_ON_RANK)$' "$work/err" &&
     [ -z "$(find "$work" -name 'all.csv*' | head -1)" ]; then
    pass
  else
    fail "the same failure on every rank" "exit 1, one report by rank 0, no file" "exit $rc"
  fi
}

# Rows that fail while they are computed (the test build): each becomes a '# failed:' line, the
# other rows are kept, the file is the serial run's on 1, 2 and 3 ranks, the job exits 3 and
# rank 0 alone says so in one line.
case:failures.rows() {
  export PENDAVG_TEST_FAILING_ROWS=7,1500,1999
  failing_cases=(average --cases "$work/cases.csv" --output)
  "$faulty" "${failing_cases[@]}" "$work/failed_serial.csv" >/dev/null 2>"$work/err"
  rc=$?
  check "failed rows, serial: exit 3, 3 '# failed:' lines" \
    test "$rc" -eq 3 -a "$(grep -c '^# failed: ' "$work/failed_serial.csv")" -eq 3
  for run in 1 2 3; do
    OMP_NUM_THREADS=1 timeout 120 "${launcher[@]}" -n "$run" \
      "$faulty" "${failing_cases[@]}" "$work/failed_ranks.csv" >"$work/out" 2>"$work/err"
    rc=$?
    if [ "$rc" -eq 3 ] && [ ! -s "$work/out" ] &&
       [ "$(grep -c '^pendavg: ' "$work/err")" -eq 1 ] &&
       grep -q '^pendavg: error: average: 3 of 2000 rows failed .* line 9: ' "$work/err" &&
       ! grep -q '(rank [0-9]' "$work/err" &&
       cmp -s "$work/failed_ranks.csv" "$work/failed_serial.csv"; then
      pass
    else
      fail "failed rows on $run ranks" "exit 3, one error line by rank 0, the serial file" "exit $rc"
    fi
  done
}

cases_main "$@"
