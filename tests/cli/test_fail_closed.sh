#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_fail_closed.sh PENDAVG CASE -- the hostile-input audit's reproducers, one per
# root cause, through the command line: each either exits 0 with finite numbers, or exits 2 with
# exactly one line on stderr and nothing on stdout. Usage: test_fail_closed.sh build/pendavg CASE
# (test_fail_closed.sh --list: the cases); prints "CASE: N passed, M failed" last.
set -uo pipefail
pendavg=${1:?usage: test_fail_closed.sh PENDAVG CASE, or test_fail_closed.sh --list}
# shellcheck source=case_harness.sh
source "$(cd "$(dirname "$0")" && pwd)/case_harness.sh"
record_commands pendavg

# refused NAME EXPECTED-TEXT ARGS...: exit 2, one stderr line containing EXPECTED-TEXT, no stdout.
refused() {
  local name=$1 expected=$2
  shift 2
  timeout 60 "$pendavg" "$@" >"$work/out" 2>"$work/err"
  local rc=$? lines
  lines=$(wc -l <"$work/err")
  if [[ $rc -eq 2 && $lines -eq 1 && ! -s $work/out ]] && grep -qF -- "$expected" "$work/err"; then
    pass
  else
    fail "refused: $name" "exit 2 within 60 s, nothing on stdout, one stderr line containing: $expected" \
      "exit $rc, $lines stderr lines"
  fi
}

# finite NAME ARGS...: exit 0 and no nan or inf in the output (CSV: a missing value is empty).
finite() {
  local name=$1
  shift
  timeout 60 "$pendavg" "$@" >"$work/out" 2>"$work/err"
  local rc=$?
  if [[ $rc -eq 0 ]] && ! grep -qiE '(^|[,: \[])[-+]?(nan|inf)' "$work/out"; then
    pass
  else
    fail "finite: $name" "exit 0 within 60 s, no nan or inf in the output" "exit $rc"
  fi
}

case:limit.subnormal() {
# limit: NaN var_K_beta2 with converged true, subnormal values, Boost's ellint_rf domain error
refused "limit: subnormal mass fraction" "below double's normal range" \
  limit --masses 1e-300,1e20 --lengths 1,0.5
refused "limit: subnormal mass fraction (text)" "below double's normal range" \
  limit --masses 1e-300,1e20 --lengths 1,0.5 --format text
refused "limit: M/m_min beyond the trace formula" "trace formula" limit --masses 1,1e154,1
refused "limit: three scales" "below double's normal range" \
  limit --masses 0.5,1e-300,5.467694768196e306
refused "limit: mu1 = 1e-400 (was ellint_rf)" "below double's normal range" \
  limit --masses 1e-200,1e200
finite "limit: the advice works" limit --masses 1e-200,1e200 --digits 17 --format csv
}

case:simulate.tiny_links() {
# simulate: null averages with zero errors and exit 0 (a NaN frequency passed the dt check)
refused "simulate: length 1e-300" "choose units nearer 1" \
  simulate --masses 1,1 --lengths 1e-300,1 --theta 1 --time 1
refused "simulate: length 1e-300, Langevin" "choose units nearer 1" \
  simulate --masses 1,1 --lengths 1e-300,1 --theta 1 --time 1 --thermostat langevin --beta 1
refused "simulate: length 1e-300, rattle2" "choose units nearer 1" \
  simulate --masses 1,1 --lengths 1e-300,1 --theta 1 --time 1 --integrator rattle2
refused "simulate: length 1e-300, replicas" "choose units nearer 1" \
  simulate --masses 1,1 --lengths 1e-300,1 --theta 1 --time 1 --replicas 2
refused "simulate: length 1e-300, N = 3" "choose units nearer 1" \
  simulate --masses 1,1,1 --lengths 1,1e-300,1 --theta 1 --time 1
refused "simulate: --perturb 1e300" "--perturb must be in (0, 0.1]" \
  simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --replicas 4 --perturb 1e300
refused "poincare: length 1e-300" "choose units nearer 1" \
  poincare --masses 1,1 --lengths 1e-300,1 --energy -1
}

case:average.mpfr_torus() {
# average: the MPFR torus' stiffness was converted to double (unbounded runs)
refused "average: MPFR beta 1e400, N = 3" "beyond what the torus resolves in MPFR" \
  average --masses 1,1,1 --lengths 1,1,1 --beta 1e400 --digits 20
refused "average: MPFR beta 1e400, N = 4" "beyond what the torus resolves in MPFR" \
  average --masses 1,1,1,1 --lengths 1,1,1,1 --beta 1e400 --digits 20
refused "average: MPFR g 1e400" "beyond what the torus resolves in MPFR" \
  average --masses 1,1,1 --lengths 1,1,1 --beta 1 --g 1e400 --digits 20
refused "average: MPFR middle link 1e400" "times the softest joint's" \
  average --masses 1,1,1 --lengths 1,1e400,1 --beta 1 --digits 20
}

case:average.double_overflow() {
# double overflow inside the N >= 3 engines (minutes, then four lines)
refused "average: g 6e307, N = 3" "beyond double's range for the engines" \
  average --masses 1,1,1 --lengths 1,1,1 --beta 1 --g 6e307
refused "average: first link 6e307" "beyond double's range for the engines" \
  average --masses 1,1,1 --lengths 6e307,1,1 --beta 1
refused "average: last link 6e307" "link 3" \
  average --masses 1,1,1 --lengths 1,1,6e307 --beta 1
refused "table: g = DBL_MAX" "beyond double's range for the engines" \
  table --chain 3 --beta 1 --g 1.7976931348623157e308 --output "$work/table.csv"
check "table: a refused table left no file" test ! -e "$work/table.csv"
}

case:transfer.light_particles() {
# transfer: a particle below 1e-16 of the total, two adjacent light particles (unbounded runs)
refused "transfer: a particle of 3.7e-127" "below what the transfer operator resolves" \
  average --masses 0.369,0.597,1.19,1.58,3.7e-127,2.29 --lengths 0.913,1.66,1.03,1.7,1.55,0.338 \
  --g 2.3 --beta 2.59 --tol 1e-8
refused "transfer: four light particles before a heavy tail" "not two adjacent ones" \
  average --masses 1,1,1,1,1e14 --lengths 1,1,1,1,1 --beta 1 --tol 1e-4
finite "transfer: one light particle (1e-12) converges" \
  average --masses 1,1e-12,1,1,1 --lengths 1,1,1,1,1 --beta 1 --format csv
}

case:microcanonical.scales() {
# microcanonical: a light middle particle (unbounded), links 1e81 apart (error did not cover)
refused "microcanonical: a middle mass of 1e-82" "below the double quadrature's accurate range" \
  average --masses 2.454,1e-82,7.361 --lengths 2.04,2.44,2.29 --g 1 --energy -1 --tol 1e-8
refused "microcanonical: links 1e81 apart" "more than 1e30 times the shortest" \
  average --masses 1.12,0.638 --lengths 1.02,2e81 --g 0.412 --energy -0.6101
}

case:advice.fits() {
refused "simulate: refused exact values point to --exact no" "--exact no runs the trajectory" \
  simulate --masses 1e-12,1 --lengths 1,1 --theta 1 --time 1e-5 --dt 1e-8
refused "poincare: no --dt advice beyond the step cap" "choose units nearer 1" \
  poincare --masses 1,1 --lengths 1,1e-40 --g 1e40 --energy 0 --orbits 1 --points 2
}

case:average.underflow() {
# underflow: Var K_i = 5e-601 printed as 0 +- 0
refused "average: Var K underflows, N = 1" "leaves double's range" \
  average --masses 2 --lengths 3 --g 1 --beta 1e200
refused "average: Var K underflows, N = 5" "leaves double's range" \
  average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --beta 1e200
finite "average: N = 2 at beta 1e200 in MPFR" average --masses 1,1 --lengths 1,1 --beta 1e200 --digits 20 --format csv
}

case:average.near_subnormal() {
# <cos phi_2> = 5e-307 off by 3.6e-11 with an error of 1e-14 of it; 0 +- 0 for 3.8e-293
refused "average: <cos phi_2> near the subnormals" "request 17 or more digits" \
  average --masses 1,1e-300 --lengths 1e8,1e8 --beta 1e-14
refused "average: <cos phi_2> underflowed to 0" "request 17 or more digits" \
  average --masses 9.55e-36,6.94e-268 --lengths 1.27e4,3.53e73 --beta 6.04e-38 --g 5.14e-62
finite "average: ... and the advice works" average --masses 1,1e-300 --lengths 1e8,1e8 --beta 1e-14 --digits 17 --format csv
}

case:microcanonical.separatrix() {
# at the single pendulum's separatrix (E = m g l) Omega(E) diverges: was "not finite ...
# (please report it)"; beside it the averages are finite
for args in "--energy 1" "--energy 1 --digits 30" "--excitation 2"; do
  # shellcheck disable=SC2086
  refused "microcanonical at the separatrix: $args" "diverges at this energy, a critical energy" \
    average --masses 1 --lengths 1 $args
done
finite "microcanonical beside the separatrix" average --masses 1 --lengths 1 --energy 0.9999999 --format csv
}

case:output.full_stdout() {
# a full stdout is refused as a full --output is: exit 2 and one line, not an internal error
for args in "average --masses 1,1 --lengths 1,1 --beta 1" "table --beta 1,2"; do
  # shellcheck disable=SC2086
  timeout 60 "$pendavg" $args >/dev/full 2>"$work/err"
  rc=$?
  if [[ $rc -eq 2 && $(wc -l <"$work/err") -eq 1 ]] &&
     grep -q '^pendavg: error: cannot write to stdout: No space left on device$' "$work/err"; then
    pass
  else
    fail "$args >/dev/full" "exit 2, one line 'pendavg: error: cannot write to stdout: ...'" \
      "exit $rc: $(head -c 200 "$work/err")"
  fi
done
}

case:advice.digits() {
# advice that is true: at 30 digits the refusal names MPFR's exponent range
refused "average: MPFR exponent range" "MPFR's exponent range" \
  average --masses 1,1 --lengths 1,1 --beta 1e200000000 --digits 30
check "advice: a 30-digit run does not advise 17 digits" test -z "$(grep "request 17" "$work/err")"
refused "average: a far stiffer last link" "request 17 or more digits" \
  average --masses 1,1,1 --lengths 1,1,1e24 --beta 1
finite "average: ... and the advice works" average --masses 1,1,1 --lengths 1,1,1e24 --beta 1 --digits 17 --format csv
}

case:simulate.replicas_shell() {
finite "simulate: replicas on one energy shell" \
  simulate --masses 1,1 --lengths 1,1 --theta 1 --time 2 --replicas 3 --perturb 1e-3 --format json
spread=$(grep -oE '"replica_energy_spread": "?[0-9.e+-]+' "$work/out" | grep -oE '[0-9.e+-]+$')
check "simulate: replica energy spread ${spread:-missing} < 1e-13 (one shell)" \
  awk -v s="${spread:-1}" 'BEGIN { exit !(s < 1e-13) }'
}

cases_main "$@"
