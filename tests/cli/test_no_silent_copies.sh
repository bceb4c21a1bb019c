#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_no_silent_copies.sh -- a pendavg built without MPI that finds itself started as
# one of several ranks (mpirun, mpiexec or srun set OMPI_COMM_WORLD_SIZE, PMI_SIZE or
# SLURM_STEP_NUM_TASKS above 1) would run the whole command in every rank and write the same
# files: it refuses instead. Rank 0 says so in one line, every rank exits 2, nothing goes to
# stdout and no file (nor temporary) is written; for table and average --cases, to a file and to
# stdout. Started as one rank, or by a batch script (SLURM_NTASKS alone), it runs.
#
# Usage: test_no_silent_copies.sh PATH/TO/pendavg-without-MPI CASE   (--list: the cases)
# (in a build with MPI, pendavg_without_mpi: the same command objects with the process group of
# a build without MPI, src/cli/distribute_serial.cpp)
# Prints "CASE: N passed, M failed" last and exits non-zero on any failure.
set -u
pendavg=${1:?usage: test_no_silent_copies.sh PATH/TO/pendavg-without-MPI CASE, or --list}
# shellcheck source=sweep_harness.sh
source "$(cd "$(dirname "$0")" && pwd)/sweep_harness.sh"
# The launchers' variables must come from this test alone.
unset OMPI_COMM_WORLD_SIZE OMPI_COMM_WORLD_RANK PMI_SIZE PMI_RANK SLURM_STEP_NUM_TASKS SLURM_PROCID \
      SLURM_NTASKS PMIX_RANK PENDAVG_MPI

refusal="^pendavg: error: started as 3 ranks (mpirun/srun), but this pendavg was built without MPI: "

case:refusal.first_rank() {
printf 'beta,g,m1,m2,l1,l2\n1,1,0.5,0.5,1,1\n2,1,0.3,0.7,1,2\n' >"$work/cases.csv"
commands=("table --beta log:0.1:10:20 --mu1 0.1,0.5"
          "average --cases $work/cases.csv")
for launched in OMPI_COMM_WORLD_SIZE PMI_SIZE SLURM_STEP_NUM_TASKS; do
  for command in "${commands[@]}"; do
    read -r -a args <<<"$command"
    name="${args[0]} with $launched=3"
    for target in file stdout; do
      out=()
      [ "$target" = file ] && out=(--output "$work/out.csv")
      # Rank 0 (no rank variable: the first rank's) refuses in one line.
      env "$launched=3" "$pendavg" "${args[@]}" "${out[@]}" >"$work/out" 2>"$work/err"
      rc=$?
      expected="exit 2, nothing on stdout, one line on stderr: $refusal..., no file"
      if [ "$rc" -ne 2 ] || [ -s "$work/out" ] || [ "$(wc -l <"$work/err")" -ne 1 ] ||
         ! grep -q "$refusal" "$work/err"; then
        fail "$name, to $target" "$expected" "exit $rc, $(wc -l <"$work/err") stderr lines"
      elif [ -n "$(find "$work" -name 'out.csv*' | head -1)" ]; then
        fail "$name, to $target" "$expected" "a file: $(find "$work" -name 'out.csv*' | head -1)"
      else
        pass
      fi
    done
  done
done
}
# The other ranks exit 2 without a word (rank 0 speaks for the job), whichever launcher numbers
# them.
case:refusal.other_ranks() {
for rank in OMPI_COMM_WORLD_RANK PMI_RANK SLURM_PROCID; do
  env SLURM_STEP_NUM_TASKS=3 "$rank=2" "$pendavg" table --beta 1,2 --output "$work/out.csv" \
    >"$work/out" 2>"$work/err"
  rc=$?
  if [ "$rc" -ne 2 ] || [ -s "$work/out" ] || [ -s "$work/err" ] || [ -e "$work/out.csv" ]; then
    fail "rank 2 by $rank" "exit 2, nothing printed, no file" "exit $rc"
  else
    pass
  fi
done
}
# One rank, and a batch script (SLURM_NTASKS without a step's tasks): the command runs.
case:runs.one_rank() {
for variables in "OMPI_COMM_WORLD_SIZE=1" "SLURM_NTASKS=4"; do
  env "$variables" "$pendavg" table --beta 1,2 --output "$work/one.csv" >"$work/out" 2>"$work/err"
  rc=$?
  if [ "$rc" -ne 0 ] || [ "$(grep -vc '^#' "$work/one.csv")" -ne 3 ]; then
    fail "started with $variables" "exit 0, the table's 2 rows" "exit $rc, $(grep -vc '^#' "$work/one.csv" 2>&1) lines but '#' lines"
  else
    pass
  fi
  rm -f "$work/one.csv"
done
}

cases_main "$@"
