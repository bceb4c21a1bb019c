#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_cli.sh -- end-to-end checks of the `pendavg` command-line contract.
#
# Usage: test_cli.sh PATH/TO/pendavg
# Bad input must exit 2 with exactly one stderr line "pendavg: error: ..." and nothing on stdout;
# good input must exit 0 with well-formed output. Prints "N passed, M failed" last and exits
# non-zero on any failure.
set -u

pendavg=${1:?usage: test_cli.sh PATH/TO/pendavg}
python=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
passed=0
failed=0

pass() { passed=$((passed + 1)); }
fail() {
  failed=$((failed + 1))
  echo "FAIL: $1"
  [ -s "$work/out" ] && sed 's/^/  stdout: /' "$work/out" | head -5
  [ -s "$work/err" ] && sed 's/^/  stderr: /' "$work/err" | head -5
}

# run ARGS... : runs pendavg, leaves stdout/stderr in $work/out, $work/err and the code in $rc.
run() {
  "$pendavg" "$@" >"$work/out" 2>"$work/err"
  rc=$?
}

# bad NAME ARGS... : expects exit 2, one stderr line "pendavg: error: ...", empty stdout.
bad() {
  local name=$1
  shift
  run "$@"
  if [ "$rc" -ne 2 ]; then
    fail "$name: exit code $rc, expected 2"
  elif [ -s "$work/out" ]; then
    fail "$name: stdout not empty"
  elif [ "$(wc -l <"$work/err")" -ne 1 ] || ! head -1 "$work/err" | grep -q '^pendavg: error: '; then
    fail "$name: stderr is not one 'pendavg: error: ' line"
  else
    pass
  fi
}

# good NAME CHECK ARGS... : expects exit 0, no stderr apart from progress lines ("[command] ...",
# printed by runs longer than 2 s), and CHECK (a shell command reading $work/out) to succeed.
good() {
  local name=$1 check=$2
  shift 2
  run "$@"
  if [ "$rc" -ne 0 ]; then
    fail "$name: exit code $rc, expected 0"
  elif grep -qv '^\[[a-z]*\] ' "$work/err"; then
    fail "$name: stderr not empty"
  elif ! eval "$check"; then
    fail "$name: output check failed"
  else
    pass
  fi
}

pendulum=(--masses 0.5,0.5 --lengths 1,1)

# ---------------------------------------------------------------- bad input
bad "mass 0"            average --masses 0,0.5 --lengths 1,1 --beta 1
bad "mass -1"           average --masses -1,0.5 --lengths 1,1 --beta 1
bad "mass nan"          average --masses nan,0.5 --lengths 1,1 --beta 1
bad "mass inf"          average --masses inf,0.5 --lengths 1,1 --beta 1
bad "mass 0x1p3"        average --masses 0x1p3,0.5 --lengths 1,1 --beta 1
bad "mass 1e400"        average --masses 1e400,0.5 --lengths 1,1 --beta 1
bad "length 0"          average --masses 0.5,0.5 --lengths 1,0 --beta 1
bad "beta 0"            average "${pendulum[@]}" --beta 0
bad "beta -1"           average "${pendulum[@]}" --beta -1
bad "beta nan"          average "${pendulum[@]}" --beta nan
bad "beta nan, mpfr"    average "${pendulum[@]}" --beta nan --digits 30
bad "beta empty"        average "${pendulum[@]}" --beta ""
bad "g -1"              average "${pendulum[@]}" --beta 1 --g -1
bad "g inf"             average "${pendulum[@]}" --beta 1 --g inf
bad "counts mismatch"   average --masses 1,1 --lengths 1 --beta 1
bad "malformed 1.0x"    average --masses 1.0x,1 --lengths 1,1 --beta 1
bad "empty element"     average --masses 1,,1 --lengths 1,1,1 --beta 1
bad "digits 15"         average "${pendulum[@]}" --beta 1 --digits 15
bad "digits 1001"       average "${pendulum[@]}" --beta 1 --digits 1001
bad "digits abc"        average "${pendulum[@]}" --beta 1 --digits abc
bad "digits 20.5"       average "${pendulum[@]}" --beta 1 --digits 20.5
bad "unknown method"    average "${pendulum[@]}" --beta 1 --method simpson
bad "unknown format"    average "${pendulum[@]}" --beta 1 --format xml
bad "unknown command"   averages "${pendulum[@]}" --beta 1
bad "no command"
bad "unknown option"    average "${pendulum[@]}" --beta 1 --temperature 1
bad "missing --beta"    average "${pendulum[@]}"
bad "missing --masses"  average --lengths 1,1 --beta 1
bad "option repeated"   average "${pendulum[@]}" --beta 1 --beta 2
bad "N = 3 series"      average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method series
bad "N = 3 integral"    average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method integral
bad "N = 0"             average --masses "" --lengths "" --beta 1
bad "limit mass 0"      limit --masses 0,1
bad "limit xml"         limit --masses 1,1 --format xml
bad "series beta 0"     series "${pendulum[@]}" --beta 0 --terms 3
bad "series terms -1"   series "${pendulum[@]}" --beta 1 --terms -1
bad "series terms 200001" series "${pendulum[@]}" --beta 1 --terms 200001  # the library's cap, checked before any work
bad "help unknown"      help nothing

# the any-N options: malformed values, and options of a method that does not run
unit3=(--masses 1,1,1 --lengths 1,1,1 --g 1)
bad "tol 0"                  average "${unit3[@]}" --beta 1 --tol 0
bad "tol -1e-10"             average "${unit3[@]}" --beta 1 --tol -1e-10
bad "tol nan"                average "${unit3[@]}" --beta 1 --tol nan
bad "tol 1"                  average "${unit3[@]}" --beta 1 --tol 1
bad "tol 1e-400"             average "${unit3[@]}" --beta 1 --tol 1e-400
bad "tol 1e-10x"             average "${unit3[@]}" --beta 1 --tol 1e-10x
bad "tol with qmc"           average "${unit3[@]}" --beta 1 --method qmc --tol 1e-10
bad "tol with N = 2 auto"    average "${pendulum[@]}" --beta 1 --tol 1e-10
bad "tol with digits 30"     average "${unit3[@]}" --beta 1 --tol 1e-10 --digits 30
bad "samples 1000"           average "${unit3[@]}" --beta 1 --method qmc --samples 1000
bad "samples 3072"           average "${unit3[@]}" --beta 1 --method qmc --samples 3072
bad "samples 2^21"           average "${unit3[@]}" --beta 1 --method qmc --samples 2097152
bad "samples 4096.0"         average "${unit3[@]}" --beta 1 --method qmc --samples 4096.0
bad "samples with torus"     average "${unit3[@]}" --beta 1 --method torus-trapezoid --samples 4096
bad "seed -1"                average "${unit3[@]}" --beta 1 --method qmc --seed -1
bad "seed 2^64"              average "${unit3[@]}" --beta 1 --method qmc --seed 18446744073709551616
bad "seed 1e3"               average "${unit3[@]}" --beta 1 --method qmc --seed 1e3
bad "seed empty"             average "${unit3[@]}" --beta 1 --method qmc --seed=
bad "seed with auto, N = 3"  average "${unit3[@]}" --beta 1 --seed 2
bad "seed with integral"     average "${pendulum[@]}" --beta 1 --method integral --seed 2
bad "shifts 3"               average "${unit3[@]}" --beta 1 --method qmc --shifts 3
bad "qmc digits 20"          average "${unit3[@]}" --beta 1 --method qmc --digits 20
bad "auto N = 6 digits 20"   average --masses 1,1,1,1,1,1 --lengths 1,1,1,1,1,1 --beta 1 --digits 20
bad "transfer digits 20"     average "${unit3[@]}" --beta 1 --method transfer --digits 20
bad "transfer samples"       average "${unit3[@]}" --beta 1 --method transfer --samples 4096
bad "auto N = 6 seed"        average --masses 1,1,1,1,1,1 --lengths 1,1,1,1,1,1 --beta 1 --seed 2
bad "torus N = 12"           average --masses 1,1,1,1,1,1,1,1,1,1,1,1 --lengths 1,1,1,1,1,1,1,1,1,1,1,1 --beta 1 --method torus-trapezoid
bad "method torus"           average "${unit3[@]}" --beta 1 --method torus
bad "N = 3 counts mismatch"  average --masses 1,1,1 --lengths 1,1 --beta 1
bad "N = 3 length 0"         average --masses 1,1,1 --lengths 1,0,1 --beta 1 --method qmc

printf 'beta,g,m1,m2,l1\n1,1,0.5,0.5,1\n' >"$work/missing_column.csv"
printf 'beta,g,m1,m2,l1,l2,T\n1,1,0.5,0.5,1,1,3\n' >"$work/extra_column.csv"
printf 'm1,m2,l1,l2,g,beta\n0.5,0.5,1,1,1,1\n0.5,0.5,1,1,1,-2\n' >"$work/bad_row.csv"
printf 'm1,m2,l1,l2,g,beta\n0.5,0.5,1,1\n' >"$work/short_row.csv"
bad "cases file missing"     average --cases "$work/no_such_file.csv"
bad "cases missing column"   average --cases "$work/missing_column.csv"
bad "cases extra column"     average --cases "$work/extra_column.csv"
bad "cases bad row"          average --cases "$work/bad_row.csv"
grep -q 'line 3' "$work/err" && pass || fail "cases bad row: stderr does not name line 3"
bad "cases short row"        average --cases "$work/short_row.csv"
bad "cases with --beta"      average --cases "$work/bad_row.csv" --beta 1
bad "cases is a directory"   average --cases "$work"
bad "cases --format json"    average --cases "$work/bad_row.csv" --format json

# ---------------------------------------------------------------- good input
json_keys='N beta digits method beta_K K error ratio cos_phi var_K evaluations seconds converged'
# Keys added after the original ones (issue 10: every error the library computes, and its kind).
json_added='error_kind K_error ratio_error cos_phi_error var_K_error error_kinds work_unit equipartition_residual run'
check_average_json() { # DIGITS
  "$python" -c '
import json, sys
keys, digits = sys.argv[1].split(), int(sys.argv[2])
lines = open(sys.argv[3]).read().splitlines()
assert len(lines) == 1, "one JSON line"
o = json.loads(lines[0])
assert list(o)[:len(keys) - 1] == keys[:-1] and set(keys) <= set(o), list(o)
assert o["N"] == 2 and o["digits"] == digits and isinstance(o["converged"], bool)
for k in ("beta_K", "K", "error", "cos_phi", "var_K"):
    assert isinstance(o[k], list) and len(o[k]) == 2, k
significant = sum(c.isdigit() for c in o["beta_K"][0].lower().split("e")[0].lstrip("0.-"))
assert significant == digits, (o["beta_K"][0], significant)
assert abs(float(o["beta_K"][0]) + float(o["beta_K"][1]) - 1) < 1e-12, "beta<K1> + beta<K2> = 1"
' "$json_keys" "$1" "$work/out"
}
good "average json"          'check_average_json 16' average "${pendulum[@]}" --beta 1
good "average json, digits 30" 'check_average_json 30' average "${pendulum[@]}" --beta 0.1 --digits 30
good "average series json"   'check_average_json 16' average "${pendulum[@]}" --beta 1 --method series
good "average csv" \
  '[ "$(wc -l <"$work/out")" -eq 2 ] && [ "$(head -1 "$work/out" | tr , "\n" | wc -l)" -eq "$(tail -1 "$work/out" | tr , "\n" | wc -l)" ]' \
  average "${pendulum[@]}" --beta 1 --format csv
good "average text"          'grep -q "beta<K_i>" "$work/out"' average "${pendulum[@]}" --beta 1 --format text

printf '# shuffled columns\nl2,m1,beta,g,l1,m2\n\n1,0.5,1,1,1,0.5\n1,0.2,10,1,1,0.8\n# comment\n2,1,0.1,9.81,1,3\n' >"$work/cases.csv"
# Columns added after the original ones (issue 10): the kinds of the other errors, the work unit,
# the equipartition residual and beta<K_i^(c)> with its errors.
canonical_added() { # N
  local i out=',cos_phi_error_kind,var_K_error_kind,work_unit,equipartition_residual'
  for ((i = 1; i <= $1; ++i)); do out+=",beta_Kc$i"; done
  for ((i = 1; i <= $1; ++i)); do out+=",beta_Kc_error$i"; done
  echo "$out,beta_Kc_error_kind"
}
cases_header='beta,g,m1,m2,l1,l2,beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,method,evaluations,ratio_error,cos_phi_error1,cos_phi_error2,var_K1,var_K2,var_K_error1,var_K_error2,error_kind,converged'"$(canonical_added 2)"
good "cases shuffled" \
  '[ "$(wc -l <"$work/out")" -eq 4 ] && [ "$(head -1 "$work/out")" = "$cases_header" ] && [ "$(sed -n 3p "$work/out" | cut -d, -f1-6)" = "10,1,0.2,0.8,1,1" ]' \
  average --cases "$work/cases.csv"
good "cases shuffled, digits 20" '[ "$(wc -l <"$work/out")" -eq 4 ]' \
  average --cases "$work/cases.csv" --digits 20

# Every --cases column equals `average --format csv` of the same point: var_K is Var K_i (not
# beta^2 Var K_i) and each error and kind as printed there; in double and in MPFR.
check_cases_as_average() { # DIGITS
  "$pendavg" average --cases "$work/cases.csv" --digits "$1" >"$work/cases_cmp.csv" 2>/dev/null || return 1
  "$python" - "$pendavg" "$work/cases_cmp.csv" "$1" <<'PY'
import csv, subprocess, sys
pendavg, path, digits = sys.argv[1], sys.argv[2], sys.argv[3]
rows = list(csv.DictReader(line for line in open(path) if not line.startswith("#")))
assert len(rows) == 3
for row in rows:
    args = [pendavg, "average", "--masses", row["m1"] + "," + row["m2"], "--lengths",
            row["l1"] + "," + row["l2"], "--g", row["g"], "--beta", row["beta"],
            "--digits", digits, "--format", "csv"]
    single = next(csv.DictReader(subprocess.run(args, capture_output=True, text=True,
                                                check=True).stdout.splitlines()))
    for key in ("beta_K1", "beta_K2", "error_K1", "var_K1", "var_K2", "var_K_error1",
                "var_K_error2", "cos_phi1", "cos_phi_error2", "ratio", "ratio_error", "method"):
        assert row[key] == single[key], (key, row[key], single[key])
PY
}
if check_cases_as_average 16; then pass; else fail "cases columns = average --format csv (double)"; fi
if check_cases_as_average 25; then pass; else fail "cases columns = average --format csv (MPFR)"; fi

# --columns LIST: the listed output columns (names or per-particle stems), in that order, each
# with the same text as in the full output; the input columns stay in front. Bad lists exit 2.
check_columns() { # DIGITS LIST EXPECTED-NAMES(comma separated)
  "$pendavg" average --cases "$work/cases.csv" --digits "$1" >"$work/cols_all.csv" 2>/dev/null &&
    "$pendavg" average --cases "$work/cases.csv" --digits "$1" --columns "$2" >"$work/cols_some.csv" 2>/dev/null &&
    "$python" - "$work/cols_all.csv" "$work/cols_some.csv" "$3" <<'PY'
import csv, sys
full = list(csv.reader(open(sys.argv[1])))
some = list(csv.reader(open(sys.argv[2])))
expected = ["beta", "g", "m1", "m2", "l1", "l2"] + sys.argv[3].split(",")
assert some[0] == expected, (some[0], expected)
assert len(some) == len(full) == 4
for a, b in zip(full[1:], some[1:]):
    row = dict(zip(full[0], a))
    assert b == [row[name] for name in expected], (a, b)
PY
}
check_columns 16 beta_K,error_K,ratio,cos_phi,method,evaluations \
  beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,method,evaluations &&
  pass || fail "cases --columns: the original seven numbers"
check_columns 16 var_K_error2,var_K1,beta_Kc_error_kind,converged,var_K_error1 \
  var_K_error2,var_K1,beta_Kc_error_kind,converged,var_K_error1 &&
  pass || fail "cases --columns: any order, variance errors before values"
check_columns 25 cos_phi_error,ratio_error,equipartition_residual,work_unit \
  cos_phi_error1,cos_phi_error2,ratio_error,equipartition_residual,work_unit &&
  pass || fail "cases --columns at 25 digits"
bad "cases --columns unknown"          average --cases "$work/cases.csv" --columns beta_K,foo
grep -q "unknown column 'foo'" "$work/err" && pass || fail "cases --columns unknown: message"
bad "cases --columns twice selected"   average --cases "$work/cases.csv" --columns cos_phi,cos_phi2
bad "cases --columns empty"            average --cases "$work/cases.csv" --columns ""
bad "cases --columns empty item"       average --cases "$work/cases.csv" --columns beta_K,,ratio
bad "cases --columns beyond N"         average --cases "$work/cases.csv" --columns beta_K3
bad "cases --columns input column"     average --cases "$work/cases.csv" --columns beta
bad "--columns without --cases"        average "${pendulum[@]}" --beta 1 --columns beta_K
printf 'excitation,g,m1,m2,l1,l2\n1,1,1,1,1,1\n' >"$work/micro_cases.csv"
good "cases --columns, microcanonical" \
  '[ "$(head -1 "$work/out")" = "excitation,g,m1,m2,l1,l2,K2,density_of_states,energy" ] && [ "$(tail -1 "$work/out" | tr , "\n" | wc -l)" -eq 9 ]' \
  average --cases "$work/micro_cases.csv" --columns K2,density_of_states,energy

# --cases --timing: stdout unchanged, one summary line on stderr (its presence and format, not
# its numbers); --timing-rows FILE: one CSV line per row with its file line. Bad uses exit 2.
run average --cases "$work/cases.csv"
cp "$work/out" "$work/cases_out.csv"
timing_line='^pendavg: timing: rows=3 median_us=[0-9]+\.[0-9]{3} p90_us=[0-9]+\.[0-9]{3} worst_us=[0-9]+\.[0-9]{3} worst_row=[0-2] worst_line=(4|5|7) threads=[1-9][0-9]* timer_us=[0-9]+\.[0-9]{3} \(thread CPU time per row, row to formatted line, timer overhead subtracted\)$'
check_timing() { # ARGS...: stdout as in $work/cases_out.csv, stderr one summary line
  run average --cases "$work/cases.csv" "$@"
  [ "$rc" -eq 0 ] && cmp -s "$work/out" "$work/cases_out.csv" &&
    [ "$(wc -l <"$work/err")" -eq 1 ] && grep -Eq "$timing_line" "$work/err"
}
check_timing --timing && pass || fail "cases --timing: stdout or the stderr summary line"
check_timing --timing-rows "$work/rows.csv" &&
  "$python" - "$work/rows.csv" <<'PY' && pass || fail "cases --timing-rows: file"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert [r["row"] for r in rows] == ["0", "1", "2"], rows
assert [r["line"] for r in rows] == ["4", "5", "7"], rows  # data lines of the shuffled file
float(rows[0]["us"])
PY
run average --cases "$work/cases.csv" --digits 20
cp "$work/out" "$work/cases_out.csv"
check_timing --timing --digits 20 && pass || fail "cases --timing --digits 20"
bad "cases --timing without --cases"   average "${pendulum[@]}" --beta 1 --timing
bad "cases --timing-rows without --cases" average "${pendulum[@]}" --beta 1 --timing-rows "$work/r.csv"
bad "cases --timing=1"                 average --cases "$work/cases.csv" --timing=1
bad "cases --timing twice"             average --cases "$work/cases.csv" --timing --timing
bad "cases --timing-rows unwritable"   average --cases "$work/cases.csv" --timing-rows /nonexistent/rows.csv
bad "cases --timing, bad row"          average --cases "$work/bad_row.csv" --timing
grep -q 'line 3' "$work/err" && pass || fail "cases --timing, bad row: stderr does not name line 3"

# Rows run in blocks of 256 on all cores: 600 rows give the same bytes on 1 and 2 threads.
"$python" - "$work/many.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for i in range(600):
        f.write(f"{10 ** (i % 9 - 4)},{1 + i % 3},{0.5 + i % 7},{1e-3 * (1 + i % 11)},1,{2 ** (i % 13 - 6)}\n")
PY
OMP_NUM_THREADS=1 "$pendavg" average --cases "$work/many.csv" >"$work/many1.csv" 2>/dev/null
OMP_NUM_THREADS=2 "$pendavg" average --cases "$work/many.csv" >"$work/many2.csv" 2>/dev/null
[ "$(wc -l <"$work/many1.csv")" -eq 601 ] && cmp -s "$work/many1.csv" "$work/many2.csv" && pass ||
  fail "cases 600 rows: 1 and 2 threads differ"

# ---------------------------------------------------------------- any N
check_any_n_json() { # N
  "$python" -c '
import json, sys
keys = sys.argv[1].split() + ["diagonal_approx", "beta_Kc"] + sys.argv[4].split()
n = int(sys.argv[2])
o = json.loads(open(sys.argv[3]).read())
assert list(o) == keys, list(o)
assert o["error_kind"] in ("bound", "estimate", "statistical"), o["error_kind"]
for k in ("K_error", "cos_phi_error", "var_K_error"):
    assert isinstance(o[k], list) and len(o[k]) == n and all(float(e) >= 0 for e in o[k]), k
assert (o["ratio_error"] is None) == (n == 1), o["ratio_error"]
assert set(o["error_kinds"]) == {"beta_K", "ratio", "cos_phi", "var_K"}, o["error_kinds"]
assert o["N"] == n and o["converged"] is True
for k in ("beta_K", "K", "error", "cos_phi", "var_K", "diagonal_approx", "beta_Kc"):
    assert isinstance(o[k], list) and len(o[k]) == n, k
assert all(v == "5.000000000000000e-01" for v in o["beta_Kc"]), o["beta_Kc"]
assert abs(sum(map(float, o["beta_K"])) - n / 2) < 1e-12, "sum_i beta<K_i> = N/2"
' "$json_keys" "$1" "$work/out" "$json_added"
}
# beta<K_i> of the unit 3-link chain at g = beta = 1 (published reference values)
check_unit3() {
  check_any_n_json 3 && "$python" -c '
import json, sys
o = json.loads(open(sys.argv[1]).read())
assert o["method"] == "torus-trapezoid", o["method"]
for value, prefix in zip(o["beta_K"], ("3.2908723613784", "4.8318092191398", "6.877318419481")):
    assert value.startswith(prefix), (value, prefix)
assert o["ratio"].startswith("6.81084912943"), o["ratio"]
' "$work/out"
}
good "N = 3 unit chain"      check_unit3 average "${unit3[@]}" --beta 1
cp "$work/out" "$work/unit3.json"
good "N = 3 diagonal approx" \
  'check_any_n_json 3 && "$python" -c "import json,sys; o = json.load(open(sys.argv[1])); assert o[\"diagonal_approx\"][0] == \"1.666666666666667e-01\", o" "$work/out"' \
  average "${unit3[@]}" --beta 0.1
good "N = 3 torus-gauss, digits 20" \
  '"$python" -c "import json,sys; o = json.load(open(sys.argv[1])); assert o[\"method\"] == \"torus-gauss\" and o[\"beta_K\"][0].startswith(\"3.29087236137842418\"), o" "$work/out"' \
  average "${unit3[@]}" --beta 1 --method torus-gauss --digits 20
good "N = 1"                 \
  'check_any_n_json 1 && "$python" -c "import json,sys; o = json.load(open(sys.argv[1])); assert o[\"ratio\"] is None and o[\"beta_K\"] == [\"5.000000000000000e-01\"], o" "$work/out"' \
  average --masses 2 --lengths 3 --beta 0.7
good "N = 4 csv"             '[ "$(wc -l <"$work/out")" -eq 2 ] && head -1 "$work/out" | grep -q ",beta_Kc4,error_kind," && head -1 "$work/out" | grep -q ",equipartition_residual$"' \
  average --masses 1,2,3,4 --lengths 1,1,1,1 --beta 1 --format csv
good "N = 3 text"            'grep -q "diagonal approx" "$work/out" && [ "$(grep -c "^ *[123]  " "$work/out")" -eq 3 ]' \
  average "${unit3[@]}" --beta 1 --format text
good "N = 2 json extras"     'check_any_n_json 2' average "${pendulum[@]}" --beta 1

# The any-N engines against the N = 2 engine: torus rules to 1e-12 relative, qmc within its bar.
check_agree() { # REFERENCE CANDIDATE TOLERANCE ("bar": within the candidate's error bars)
  "$python" -c '
import json, sys
a, b = (json.load(open(path)) for path in sys.argv[1:3])
tolerance = sys.argv[3]
assert a["N"] == b["N"] == 2 and a["method"] != b["method"], (a["method"], b["method"])
for key in ("beta_K", "cos_phi", "var_K"):
    for i, (x, y) in enumerate(zip(map(float, a[key]), map(float, b[key]))):
        if tolerance == "bar" and key == "beta_K":
            assert abs(x - y) <= float(b["error"][i]), (key, x, y, b["error"][i])
        elif tolerance != "bar":
            assert abs(x - y) <= float(tolerance) * abs(x), (key, x, y)
' "$1" "$work/out" "$2"
}
for params in "0.5,0.5 1,1 1 1" "0.2,0.8 1,2 10 9.81" "3,0.01 2,0.5 0.05 1"; do
  read -r m l b g <<<"$params"
  run average --masses "$m" --lengths "$l" --beta "$b" --g "$g"
  cp "$work/out" "$work/reference.json"
  for method in torus-trapezoid torus-gauss; do
    good "N = 2 $method vs default ($params)" 'check_agree "$work/reference.json" 1e-12' \
      average --masses "$m" --lengths "$l" --beta "$b" --g "$g" --method "$method"
  done
  good "N = 2 qmc vs default ($params)" 'check_agree "$work/reference.json" bar' \
    average --masses "$m" --lengths "$l" --beta "$b" --g "$g" --method qmc --samples 4096
done

# qmc: deterministic for a seed (all but the wall time), and its bars cover the exact values.
strip_seconds() { sed 's/"seconds": [^,]*,//' "$1"; }
run average "${unit3[@]}" --beta 1 --method qmc --seed 12345 --samples 4096
cp "$work/out" "$work/qmc1.json"
good "qmc N = 3 deterministic" '[ "$(strip_seconds "$work/out")" = "$(strip_seconds "$work/qmc1.json")" ]' \
  average "${unit3[@]}" --beta 1 --method qmc --seed 12345 --samples 4096
good "qmc N = 3 covers exact" '"$python" -c "
import json, sys
q, exact = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
assert q[\"method\"] == \"qmc\" and q[\"evaluations\"] == 4096 * 16, q
for x, y, e in zip(map(float, q[\"beta_K\"]), map(float, exact[\"beta_K\"]), map(float, q[\"error\"])):
    assert abs(x - y) <= e and e < 1e-5, (x, y, e)
" "$work/out" "$work/unit3.json"' \
  average "${unit3[@]}" --beta 1 --method qmc --seed 12345 --samples 4096
good "qmc N = 3 other seed differs" '[ "$(strip_seconds "$work/out")" != "$(strip_seconds "$work/qmc1.json")" ]' \
  average "${unit3[@]}" --beta 1 --method qmc --seed 12346 --samples 4096 --shifts 8

# --cases with N = 3 columns in any order: canonical input columns, then N = 3 results that
# match the single-case command.
printf 'l3,m2,beta,l1,g,m3,m1,l2\n1,1,1,1,1,1,1,1\n2,1,0.5,1,9.81,3,2,1\n' >"$work/cases3.csv"
cases3_header='beta,g,m1,m2,m3,l1,l2,l3,beta_K1,beta_K2,beta_K3,error_K1,error_K2,error_K3,ratio,cos_phi1,cos_phi2,cos_phi3,method,evaluations,ratio_error,cos_phi_error1,cos_phi_error2,cos_phi_error3,var_K1,var_K2,var_K3,var_K_error1,var_K_error2,var_K_error3,error_kind,converged'"$(canonical_added 3)"
check_cases3() {
  [ "$(wc -l <"$work/out")" -eq 3 ] && [ "$(head -1 "$work/out")" = "$cases3_header" ] &&
    [ "$(sed -n 3p "$work/out" | cut -d, -f1-8)" = "0.5,9.81,2,1,3,1,1,2" ] &&
    "$python" -c '
import csv, json, sys
rows = list(csv.DictReader(open(sys.argv[1])))
exact = json.load(open(sys.argv[2]))
assert rows[0]["method"] == "torus-trapezoid", rows[0]
assert [rows[0]["beta_K%d" % i] for i in (1, 2, 3)] == exact["beta_K"], rows[0]
assert rows[0]["ratio"] == exact["ratio"]
' "$work/out" "$work/unit3.json"
}
good "cases N = 3 shuffled"  check_cases3 average --cases "$work/cases3.csv"
good "cases N = 3 qmc"       '[ "$(wc -l <"$work/out")" -eq 3 ] && [ "$(sed -n 2p "$work/out" | cut -d, -f19)" = qmc ]' \
  average --cases "$work/cases3.csv" --method qmc --samples 1024 --seed 3
printf 'beta,g,m1,m2,m3,l1,l2\n1,1,1,1,1,1,1\n' >"$work/cases3_missing.csv"
printf 'beta,g,m1,m3,l1,l2,l3\n1,1,1,1,1,1,1\n' >"$work/cases3_gap.csv"
printf 'beta,g,m1,m02,l1,l2\n1,1,1,1,1,1\n' >"$work/cases3_m02.csv"
printf 'beta,g,m1,m2,m3,l1,l2,l3\n1,1,1,1,1,1,1,1\n1,1,1,1,0,1,1,1\n' >"$work/cases3_bad_row.csv"
bad "cases N = 3 missing l3"    average --cases "$work/cases3_missing.csv"
bad "cases N = 3 missing m2"    average --cases "$work/cases3_gap.csv"
bad "cases column m02"          average --cases "$work/cases3_m02.csv"
bad "cases N = 3 series"        average --cases "$work/cases3.csv" --method series
bad "cases N = 3 seed, torus"   average --cases "$work/cases3.csv" --seed 4
bad "cases N = 3 bad row"       average --cases "$work/cases3_bad_row.csv"
grep -q 'line 3: m3' "$work/err" && pass || fail "cases N = 3 bad row: stderr does not name line 3, m3"

check_limit() {
  "$python" -c '
import json, sys, decimal
o = json.loads(open(sys.argv[1]).read())
for part in ("high_temperature", "low_temperature"):
    assert list(o[part])[:4] == ["beta_K", "error", "ratio", "var_K_beta2"], list(o[part])
    assert o[part]["error_kind"] == "bound", o[part]
value = format(decimal.Decimal(o["high_temperature"]["beta_K"][0]), "f")
assert value.startswith("0.3431834814709"), value
' "$work/out"
}
good "limit paper value"     check_limit limit --masses 0.5,0.5
good "limit paper value, digits 40" check_limit limit --masses 0.5,0.5 --digits 40
good "limit text"            '[ -s "$work/out" ]' limit --masses 0.5,0.5 --format text
check_limit_any() { # N: beta -> 0 sums to N/2; beta -> infinity is 1/2 each
  "$python" - "$work/out" "$1" <<'PY'
import json, sys
d = json.load(open(sys.argv[1])); n = int(sys.argv[2])
h, l = d["high_temperature"], d["low_temperature"]
assert d["N"] == n and len(h["beta_K"]) == n
total = sum(float(x) for x in h["beta_K"]); bars = sum(float(x) for x in h["error"])
assert abs(total - n / 2) <= bars + 1e-13, (total, bars)
assert all(float(x) == 0.5 for x in l["beta_K"])
PY
}
good "limit N = 3"             'check_limit_any 3' limit --masses 1,2,0.5 --lengths 1,0.5,2
good "limit N = 7 (transfer)"  'check_limit_any 7' limit --masses 1,1,1,1,1,1,1
bad "limit N = 6 at 20 digits" limit --masses 1,1,1,1,1,1 --digits 20

# series: the run, then one row per term (text: a table under the field names)
good "series 5 terms text" \
  '[ "$(awk "/^n /{t=1; next} /^seconds = /{t=0} t" "$work/out" | grep -c "^ *[0-9]")" -eq 5 ] && grep -qx "terms = 5" "$work/out"' \
  series "${pendulum[@]}" --beta 1 --terms 5 --format text
good "series 5 terms csv" \
  '[ "$(head -2 "$work/out")" = "$(printf "# schema: 1\n# pendavg series")" ] && [ "$(grep -vc "^#" "$work/out")" -eq 6 ]' \
  series "${pendulum[@]}" --beta 1 --terms 5

# table: a small sweep's rows (every combination, in a fixed order) and its '#' header.
table_header='N,digits,beta,g,m1,m2,l1,l2,beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,var_K1,var_K2,diagonal_approx1,diagonal_approx2,method,evaluations,converged,error_kind,ratio_error,cos_phi_error1,cos_phi_error2,var_K_error1,var_K_error2'"$(canonical_added 2)"
check_table() {
  "$python" -c '
import csv, sys
lines = open(sys.argv[1]).read().splitlines()
comments = [l for l in lines if l.startswith("#")]
data = [l for l in lines if not l.startswith("#")]
assert lines[0].startswith("# pendavg table"), lines[0]
assert all(not l.startswith("#") for l in lines[len(comments):]), "comments after data"
text = "\n".join(comments)
for needle in ("beta = log:1e-3:1e3:7", "mu1 = 0.05,0.95", "l2 = 0.5,2", "method = auto", "digits = 16", "pendavg 0.2", "UTC"):
    assert needle in text, needle
assert data[0] == sys.argv[2], data[0]
rows = list(csv.DictReader(data))
assert len(rows) == 28, len(rows)
assert [r["beta"] for r in rows[:7]] == ["1e-3", "0.01", "0.1", "1", "10", "100", "1e3"], [r["beta"] for r in rows[:7]]
assert [(r["m1"], r["m2"], r["l2"]) for r in rows[::7]] == [("0.05", "0.95", "0.5"), ("0.05", "0.95", "2"), ("0.95", "0.05", "0.5"), ("0.95", "0.05", "2")]
for r in rows:
    k1, k2 = float(r["beta_K1"]), float(r["beta_K2"])
    assert 0 <= k1 <= 0.5 <= k2 <= 1 and abs(k1 + k2 - 1) < 1e-14, r
' "$1" "$table_header"
}
good "table sweep to stdout"  'check_table "$work/out"' \
  table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2
good "table sweep to file"    '[ ! -s "$work/out" ] && check_table "$work/table.csv" && [ -z "$(ls "$work" | grep tmp)" ]' \
  table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2 --output "$work/table.csv"
good "table l2 range innermost" \
  '[ "$(grep -v "^#" "$work/out" | sed 1d | cut -d, -f3,8 | tr "\n" " ")" = "1,0.1 1,1 1,10 2,0.1 2,1 2,10 " ]' \
  table --beta 1,2 --l2 log:0.1:10:3
good "table same with 1 thread" \
  'OMP_NUM_THREADS=1 "$pendavg" table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2 | grep -v generated >"$work/t1" &&
   grep -v generated "$work/out" | cmp -s - "$work/t1"' \
  table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2
good "table digits 30"        '[ "$(grep -v "^#" "$work/out" | sed -n 2p | cut -d, -f9 | wc -c)" -eq 36 ]' \
  table --beta 1 --mu1 1e-4 --digits 30
good "table chain 3"          '[ "$(grep -v "^#" "$work/out" | wc -l)" -eq 3 ] && grep -q "diagonal_approx3" "$work/out"' \
  table --chain 3 --beta 0.1,1
touch "$work/plain_file"
bad "table unwritable dir"    table --beta 1 --output "$work/plain_file/t.csv"
[ -f "$work/plain_file" ] && [ -z "$(ls "$work" | grep tmp)" ] && pass || fail "table unwritable dir left a file"
bad "table missing dir"       table --beta 1 --output "$work/no/such/dir/t.csv"
bad "table output is a dir"   table --beta 1 --output "$work"
bad "table bad point"         table --beta 1 --l2 0 --output "$work/bad.csv"
[ ! -e "$work/bad.csv" ] && [ -z "$(ls "$work" | grep 'bad.csv')" ] && pass || fail "table bad point left a file"
bad "table no beta"           table --mu1 0.5
bad "table log reversed"      table --beta log:10:1:5
bad "table log from 0"        table --beta log:0:1:5
bad "table log 1 point"       table --beta log:1:10:1
bad "table log missing N"     table --beta log:1:10
bad "table log N not integer" table --beta log:1:10:2.5
bad "table lin negative"      table --beta lin:-1:1:3
bad "table empty list"        table --beta list:
bad "table empty element"     table --beta 1,,2
bad "table malformed value"   table --beta 1,two
bad "table mu1 = 1"           table --beta 1 --mu1 1
bad "table mu1 > 1"           table --beta 1 --mu1 0.5,1.5
bad "table mu1 = 0"           table --beta 1 --mu1 0
bad "table chain too long"    table --chain 16385 --beta 1
bad "table chain qmc 257"     table --chain 257 --beta 1 --method qmc
bad "table tol, qmc only"     table --chain 5 --beta 1 --method qmc --tol 1e-6
bad "table tol, pendulum"     table --beta 1 --tol 1e-6
bad "table chain with l2"     table --chain 3 --beta 1 --l2 2
bad "table chain series"      table --chain 3 --beta 1 --method series
bad "table chain qmc digits"  table --chain 5 --beta 1 --digits 20
bad "table unknown option"    table --beta 1 --masses 1,1
# Any method the library has is taken; the library refuses it per row (before any work).
bad "table chain integral"    table --chain 3 --beta 1 --method integral
bad "table energy transfer"   table --chain 5 --energy 0 --method transfer
bad "table energy series"     table --energy 0 --method series
bad "table unknown method"    table --beta 1 --method simpson
good "table chain torus-gauss" 'grep -q "^3,16," "$work/out"' table --chain 3 --beta 1 --method torus-gauss --tol 1e-8
good "table pendulum torus"   'grep -q "^2,16," "$work/out"' table --beta 1 --method torus-trapezoid --tol 1e-10
# Microcanonical qmc runs as far as its lattices go (N <= 256), from the CLI as from the library.
good "micro qmc N = 40"       'python3 -c "import json,sys; o=json.load(open(sys.argv[1])); assert o[\"N\"] == 40 and len(o[\"K\"]) == 40" "$work/out"' \
  average --masses "$(printf '1%.0s,' {1..39})1" --lengths "$(printf '1%.0s,' {1..39})1" --energy 0 --samples 1024 --shifts 8
good "table --help"           'grep -q "usage" "$work/out"' table --help

# table: lists of N, digits and g (issue 5). check_mixed_table FILE: a table of chains N = 3 and
# 5 at digits 16 and 20 (N = 5 runs transfer: digits 16 only) and g = 1, 2, with the mixed-N
# layout.
check_mixed_table() {
  "$python" - "$1" <<'PY'
import csv, sys
from decimal import Decimal as D
lines = open(sys.argv[1]).read().splitlines()
comments = [l for l in lines if l.startswith("#")]
text = "\n".join(comments)
for needle in ("N = 3,5 (2 values)", "digits = 16,20 (2 values)", "g = 1,2 (2 values)",
               "beta = 0.5 (1 value)", "rows = 6, nested N, digits, g, beta",
               "N = 5 has rows at digits = 16 only", "method = auto: torus-trapezoid",
               "transfer (tolerance 1e-10, double only) for N > 4", "cells beyond its N empty",
               "UTC"):
    assert needle in text, needle
data = [l for l in lines if not l.startswith("#")]
header = data[0].split(",")
per = lambda stem: [f"{stem}{i}" for i in range(1, 6)]
expected = (["N", "digits", "beta", "g"] + per("m") + per("l") + per("beta_K") + per("error_K") +
            ["ratio"] + per("cos_phi") + per("var_K") + per("diagonal_approx") +
            ["method", "evaluations", "converged", "error_kind", "ratio_error"] +
            per("cos_phi_error") + per("var_K_error") +
            ["cos_phi_error_kind", "var_K_error_kind", "work_unit", "equipartition_residual"] +
            per("beta_Kc") + per("beta_Kc_error") + ["beta_Kc_error_kind"])
assert header == expected, header
assert all(len(l.split(",")) == len(header) for l in data), "ragged rows"
rows = list(csv.DictReader(data))
assert [(r["N"], r["digits"], r["g"]) for r in rows] == [
    ("3", "16", "1"), ("3", "16", "2"), ("3", "20", "1"), ("3", "20", "2"),
    ("5", "16", "1"), ("5", "16", "2")], [(r["N"], r["digits"], r["g"]) for r in rows]
for r in rows:
    n = int(r["N"])
    assert r["method"] == ("torus-trapezoid" if n == 3 else "transfer") and r["converged"] == "true", r
    for stem in ("m", "l", "beta_K", "error_K", "cos_phi", "var_K", "diagonal_approx", "beta_Kc",
                 "beta_Kc_error"):
        cells = [r[f"{stem}{i}"] for i in range(1, 6)]
        assert all(cells[:n]) and not any(cells[n:]), (stem, cells)
    # beta<K_i> has as many significant digits as the row's digits; equipartition sum = N/2.
    assert len(r["beta_K1"].split("e")[0].replace(".", "")) == int(r["digits"]), r["beta_K1"]
    total = sum(D(r[f"beta_K{i}"]) for i in range(1, n + 1))
    bound = sum(D(r[f"error_K{i}"]) for i in range(1, n + 1))
    assert abs(total - D(n) / 2) <= bound, (total, bound)
# The 20-digit rows agree with the 16-digit rows within the 16-digit error bars.
for lo, hi in ((rows[0], rows[2]), (rows[1], rows[3])):
    for i in range(1, 4):
        assert abs(D(lo[f"beta_K{i}"]) - D(hi[f"beta_K{i}"])) <= D(lo[f"error_K{i}"]) + D(hi[f"error_K{i}"]), i
        assert D(hi[f"error_K{i}"]) < D("1e-18"), hi[f"error_K{i}"]
PY
}
mixed_table=(table --chain 3,5 --beta 0.5 --g 1,2 --digits 16,20)
good "table lists of N, digits, g"   'check_mixed_table "$work/out"' "${mixed_table[@]}"
good "table mixed N to file"         '[ ! -s "$work/out" ] && check_mixed_table "$work/mixed.csv" && [ -z "$(ls "$work" | grep tmp)" ]' \
  "${mixed_table[@]}" --output "$work/mixed.csv"
good "table mixed N with 1 thread" \
  'OMP_NUM_THREADS=1 "$pendavg" "${mixed_table[@]}" | grep -v generated >"$work/t1" &&
   grep -v generated "$work/out" | cmp -s - "$work/t1"' "${mixed_table[@]}"

# beta<K_i>, <cos phi_i>, <K1>/<K2> and beta^2 Var K_i depend on beta and g only through beta g
# (fixed masses and lengths; MATH.md): the row beta = 2, g = 1 equals the row beta = 1, g = 2 to
# a few units of the last digit, in double and at 30 digits. g = 0 is the beta -> 0 limit at
# every beta.
check_beta_g() { # FILE
  "$python" - "$1" <<'PY'
import csv, sys
from decimal import Decimal as D, getcontext
getcontext().prec = 50
lines = open(sys.argv[1]).read().splitlines()
assert any(l.startswith("# g = 0,1,2 (3 values)") for l in lines)
rows = list(csv.DictReader(l for l in lines if not l.startswith("#")))
assert len(rows) == 2 * 3 * 2 and {r["N"] for r in rows} == {"2"}, len(rows)
at = {(r["digits"], r["g"], r["beta"]): r for r in rows}
for digits, tol in (("16", D("1e-14")), ("30", D("1e-29"))):
    a, b = at[(digits, "1", "2")], at[(digits, "2", "1")]
    for key in ("beta_K1", "beta_K2", "cos_phi1", "cos_phi2", "ratio"):
        assert abs(D(a[key]) - D(b[key])) <= tol, (digits, key, a[key], b[key])
    for i in (1, 2):  # beta^2 Var K_i
        va, vb = 4 * D(a[f"var_K{i}"]), D(b[f"var_K{i}"])
        assert abs(va - vb) <= tol * abs(vb), (digits, i, va, vb)
    z1, z2 = at[(digits, "0", "1")], at[(digits, "0", "2")]
    for key in ("beta_K1", "beta_K2", "cos_phi1", "ratio"):
        assert abs(D(z1[key]) - D(z2[key])) <= tol, (digits, key, z1[key], z2[key])
    # Colder (larger beta g) moves the kinetic energy towards the low-temperature split.
    assert D(at[(digits, "1", "1")]["beta_K1"]) != D(a["beta_K1"])
# digits-30 values agree with the double ones within the double error bars.
for key, r in at.items():
    if key[0] == "16":
        hi = at[("30",) + key[1:]]
        for i in (1, 2):
            assert abs(D(r[f"beta_K{i}"]) - D(hi[f"beta_K{i}"])) <= D(r[f"error_K{i}"]), (key, i)
PY
}
good "table beta g scaling"          'check_beta_g "$work/out"' \
  table --beta 1,2 --g 0,1,2 --digits 16,30 --mu1 0.3 --l1 1.5 --l2 0.7
check_chain_beta_g() { # FILE: chain N = 3 by the torus, beta = 2, g = 1 vs beta = 1, g = 2
  "$python" - "$1" <<'PY'
import csv, sys
rows = list(csv.DictReader(l for l in open(sys.argv[1]) if not l.startswith("#")))
at = {(r["g"], r["beta"]): r for r in rows}
a, b = at[("1", "2")], at[("2", "1")]
for i in (1, 2, 3):
    err = float(a[f"error_K{i}"]) + float(b[f"error_K{i}"])
    assert abs(float(a[f"beta_K{i}"]) - float(b[f"beta_K{i}"])) <= err, i
    assert abs(float(a[f"cos_phi{i}"]) - float(b[f"cos_phi{i}"])) <= 1e-12, i
PY
}
good "table chain beta g scaling"    'check_chain_beta_g "$work/out"' \
  table --chain 3 --beta 1,2 --g 1,2
good "table g range innermost" \
  '[ "$(grep -v "^#" "$work/out" | sed 1d | cut -d, -f3,4 | tr "\n" " ")" = "1,0 1,0.5 1,1 2,0 2,0.5 2,1 " ]' \
  table --beta 1,2 --g lin:0:1:3
good "table single N, no empty cells" \
  '! grep -v "^#" "$work/out" | grep -q ",," && ! grep -q "cells beyond" "$work/out" &&
   [ "$(grep -v "^#" "$work/out" | head -1 | tr "," "\n" | grep -c "^beta_K[0-9]")" -eq 3 ]' \
  table --chain 3 --beta 1
# qmc options are recorded and used: the table's row is the row of `average` with the same
# options (qmc's numbers do not depend on the thread count).
good "table qmc options" \
  'grep -q "^# qmc (N = 5): 2048 points x 8 shifts, seed 42" "$work/out" &&
   [ "$(grep -v "^#" "$work/out" | sed 1d | cut -d, -f15-19,41-42)" = \
     "$("$pendavg" average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --beta 1 --method qmc --samples 2048 --shifts 8 --seed 42 --format csv | sed 1d | cut -d, -f5-9),qmc,16384" ]' \
  table --chain 5 --method qmc --beta 1 --samples 2048 --shifts 8 --seed 42
good "table qmc seed changes values" \
  '[ "$(grep -v "^#" "$work/out" | sed 1d | cut -d, -f15)" != \
     "$("$pendavg" table --chain 5 --method qmc --beta 1 --samples 1024 --shifts 4 --seed 2 | grep -v "^#" | sed 1d | cut -d, -f15)" ]' \
  table --chain 5 --method qmc --beta 1 --samples 1024 --shifts 4 --seed 1
# transfer: the tolerance is recorded and used (the row is the row of `average` with the same
# tolerance), and chains beyond qmc's 256 particles run.
good "table transfer tolerance" \
  'grep -q "transfer (tolerance 1e-06, double only) for N > 4" "$work/out" &&
   [ "$(grep -v "^#" "$work/out" | sed 1d | cut -d, -f15-19)" = \
     "$("$pendavg" average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --beta 1 --tol 1e-6 --format csv | sed 1d | cut -d, -f5-9)" ]' \
  table --chain 5 --beta 1 --tol 1e-6
good "table chain 300 (transfer)" \
  '[ "$(grep -v "^#" "$work/out" | sed 1d | tr "," "\n" | grep -c "^transfer$")" -eq 1 ]' \
  table --chain 300 --beta 1 --tol 1e-4

# bad_table NAME ARGS...: bad input with --output: exit 2, one line, and no file left behind.
bad_table() {
  local name=$1
  shift
  bad "$name" table "$@" --output "$work/never.csv"
  [ -z "$(ls "$work" | grep never)" ] || fail "$name: left a file"
}
bad_table "table negative g"         --beta 1 --g -1
bad_table "table negative g in list" --chain 3 --beta 1 --g 1,-0.5
bad_table "table negative g range"   --beta 1 --g lin:-1:1:3
bad_table "table g log from 0"       --beta 1 --g log:0:1:3
bad_table "table malformed g"        --beta 1 --g 1,two
bad_table "table empty g element"    --beta 1 --g 1,,2
bad_table "table chain 16385"        --chain 16385 --beta 1
bad_table "table chain qmc 300"      --chain 3,300 --method qmc --beta 1
bad_table "table chain 2"            --chain 2,3 --beta 1
bad_table "table chain 0"            --chain 0 --beta 1
bad_table "table chain not integer"  --chain 3,4.5 --beta 1
bad_table "table chain range"        --chain lin:3:5:3 --beta 1
bad_table "table chain empty list"   --chain list: --beta 1
bad_table "table chain empty elem"   --chain 3,,4 --beta 1
bad_table "table chain torus N = 11" --chain 3,11 --method torus-trapezoid --beta 1
bad_table "table digits 15"          --beta 1 --digits 15,16
bad_table "table digits 1001"        --beta 1 --digits 16,1001
bad_table "table digits malformed"   --beta 1 --digits 16,x
bad_table "table digits empty elem"  --beta 1 --digits 16,
bad_table "table digits range"       --beta 1 --digits lin:16:32:3
bad_table "table qmc digits only"    --chain 5,8 --beta 1 --digits 16,30
bad_table "table qmc N without 16"   --chain 3,5 --beta 1 --digits 20
bad_table "table qmc method digits"  --chain 3 --method qmc --beta 1 --digits 16,20
bad_table "table samples not pow2"   --chain 5 --method qmc --beta 1 --samples 3000
bad_table "table samples too few"    --chain 5 --method qmc --beta 1 --samples 512
bad_table "table samples too many"   --chain 5 --method qmc --beta 1 --samples 2097152
bad_table "table shifts too few"     --chain 5 --method qmc --beta 1 --shifts 3
bad_table "table seed negative"      --chain 5 --method qmc --beta 1 --seed -1
bad_table "table samples, transfer"  --chain 5 --beta 1 --samples 1024
bad_table "table samples with torus" --chain 3 --method torus-trapezoid --beta 1 --samples 1024
bad_table "table shifts, auto torus" --chain 3,4 --beta 1 --shifts 8
bad_table "table seed, pendulum"     --beta 1 --seed 2
bad_table "table samples, series"    --beta 1 --method series --samples 1024
bad "table mixed unwritable"         table --chain 3,5 --beta 1 --output "$work/plain_file/t.csv"
bad "table mixed missing dir"        table --chain 3,5 --beta 1 --output "$work/no/such/dir/t.csv"
bad "table g sweep bad point"        table --beta 1 --g 1,2 --l2 0 --output "$work/bad.csv"
[ ! -e "$work/bad.csv" ] && [ -z "$(ls "$work" | grep 'bad.csv')" ] && pass || fail "table g sweep bad point left a file"

# ---------------------------------------------------------------- simulate and poincare
check_simulate_json() { # ENSEMBLE N
  "$python" - "$work/out" "$1" "$2" <<'PY'
import json, math, sys
d = json.load(open(sys.argv[1]))
n = int(sys.argv[3])
for key in ("K", "K_error", "Kc", "Kc_error", "exact_K", "ensemble", "energy_drift",
            "constraint_residual", "steps", "seconds"):
    assert key in d, key
assert d["ensemble"] == sys.argv[2]
for key in ("K", "K_error", "Kc", "Kc_error", "exact_K"):
    assert len(d[key]) == n and all(math.isfinite(x) for x in d[key]), key
assert d["constraint_residual"] <= 1e-12 and not d["interrupted"]
# The time averages agree with the exact values within 4 combined error bars.
for i in range(n):
    assert abs(d["K"][i] - d["exact_K"][i]) <= 4 * math.hypot(d["K_error"][i], d["exact_K_error"][i]), i
PY
}
good "simulate nve json"    'check_simulate_json microcanonical 2' \
  simulate --masses 1,1 --lengths 1,1 --theta 90deg --time 300 --format json
good "simulate langevin"    'check_simulate_json canonical 2' \
  simulate --masses 1,1 --lengths 1,1 --theta 0 --time 300 --thermostat langevin --beta 0.5 --seed 3 --format json
# CSV (the default): one row with the per-particle columns K1..KN, K1_error..KN_error, ...
check_simulate_csv_row() { # N
  "$python" - "$work/out" "$1" <<'PY'
import csv, sys
lines = open(sys.argv[1]).read().splitlines(); n = int(sys.argv[2])
assert lines[:2] == ["# schema: 1", "# pendavg simulate"], lines[:2]
rows = list(csv.DictReader(lines[2:]))
assert len(rows) == 1 and len(lines) == 4, len(lines)
r = rows[0]
for stem in ("K", "Kc", "cos_phi", "exact_K"):
    for i in range(1, n + 1):
        assert f"{stem}{i}" in r and f"{stem}{i}_error" in r, (stem, i)
assert f"K{n + 1}" not in r and r["N"] == str(n)
assert all(float(r[f"K{i}"]) > 0 and float(r[f"K{i}_error"]) > 0 for i in range(1, n + 1)), r
assert all(r[f"exact_K{i}"] == "" for i in range(1, n + 1)), r  # --exact no
PY
}
good "simulate csv"         'check_simulate_csv_row 3' \
  simulate --masses 1,2,1 --lengths 1,1,0.5 --phi 0.5,-1,2 --phidot 0,1,0 --time 20 --exact no
run simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --trajectory "$work/traj.csv" --every 100 --exact no
if [ "$rc" -eq 0 ] && [ "$(grep -c . "$work/traj.csv")" -eq 14 ] && head -1 "$work/traj.csv" | grep -qx '# schema: 1' \
   && sed -n 3p "$work/traj.csv" | grep -q '^t,E,phi1,phi2,phidot1,phidot2$' \
   && [ -z "$(ls "$work" | grep 'traj.csv.tmp')" ]; then pass; else fail "simulate trajectory file"; fi
# --output FILE: written atomically, nothing on stdout
run simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --exact no --format json --output "$work/simulate.json"
if [ "$rc" -eq 0 ] && [ ! -s "$work/out" ] && "$python" -c "import json, sys; d = json.load(open(sys.argv[1])); assert d['schema'] == 1 and d['command'] == 'simulate' and len(d['K']) == 2" "$work/simulate.json" \
   && [ -z "$(ls "$work" | grep 'simulate.json.tmp')" ]; then pass; else fail "simulate --output"; fi
bad "simulate unwritable output" simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --output /nonexistent/s.csv
bad "simulate no time"         simulate --masses 1,1 --lengths 1,1 --theta 1
bad "simulate theta and phi"   simulate --masses 1,1 --lengths 1,1 --theta 1 --phi 1,1 --time 1
bad "simulate no angles"       simulate --masses 1,1 --lengths 1,1 --time 1
bad "simulate phi count"       simulate --masses 1,1 --lengths 1,1 --phi 1 --time 1
bad "simulate phidot count"    simulate --masses 1,1 --lengths 1,1 --phi 1,1 --phidot 1 --time 1
bad "simulate bad theta"       simulate --masses 1,1 --lengths 1,1 --theta 90degrees --time 1
bad "simulate nan theta"       simulate --masses 1,1 --lengths 1,1 --theta nan --time 1
bad "simulate negative dt"     simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --dt -1e-3
bad "simulate zero time"       simulate --masses 1,1 --lengths 1,1 --theta 1 --time 0
bad "simulate time < dt"       simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1e-4
bad "simulate zero mass"       simulate --masses 0,1 --lengths 1,1 --theta 1 --time 1
bad "simulate count mismatch"  simulate --masses 1,1,1 --lengths 1,1 --theta 1 --time 1
bad "simulate langevin beta"   simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --thermostat langevin
bad "simulate beta without"    simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --beta 1
bad "simulate bad friction"    simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --thermostat langevin --beta 1 --friction 0
bad "simulate bad integrator"  simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --integrator euler
bad "simulate every alone"     simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --every 10
bad "simulate unwritable traj" simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --trajectory /nonexistent/t.csv --every 1
bad "simulate traj directory"  simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --trajectory "$work" --every 1
# SIGINT ends a run cleanly: exit 0, the averages so far, "interrupted": true.
"$pendavg" simulate --masses 1,1,1,1 --lengths 1,1,1,1 --theta 90deg --time 1e6 --exact no --format json >"$work/out" 2>"$work/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 0 ] && "$python" -c "import json,sys; d=json.load(open(sys.argv[1])); assert d['interrupted'] and 0 < d['steps'] < 10**9 and len(d['K']) == 4" "$work/out" \
   && grep -q "interrupted" "$work/err"; then pass; else fail "simulate SIGINT"; fi
# Issue 11: interrupted long before its blocks fill, a run reports unknown error bars (null and
# a reason), never 0; the exact values are still printed.
"$pendavg" simulate --masses 1,1 --lengths 1,1 --phi 1,0 --phidot 0,0 --time 1e9 --format json >"$work/out" 2>"$work/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 0 ] && "$python" -c "
import json, sys
d = json.load(open(sys.argv[1]))
assert d['interrupted'] and d['K_error'] == [None, None] and d['error_reason'], d
assert d['K_deviation_sigmas'] == [None, None] and len(d['exact_K']) == 2
assert 'nan' not in open(sys.argv[1]).read().lower()
" "$work/out"; then pass; else fail "simulate SIGINT before the blocks fill"; fi
# SIGINT during the series' Bessel table: exit 130, one line, nothing on stdout.
"$pendavg" series --masses 1,100 --lengths 1,1 --beta 1 >"$work/out" 2>"$work/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 130 ] && [ ! -s "$work/out" ] && grep -q '^pendavg: interrupted: ' "$work/err"; then pass; else fail "series SIGINT"; fi
bad "series beyond the term cap" series --masses 1,1e3 --lengths 1,1 --beta 1
# A light first particle: the refusal names mu2 = 1 - mu1 (not "1") and the a priori term
# count (~ln(tol mu1^2 / 2) / ln mu2 = 7.9e13 for mu1 = 1e-12; it stopped at 2^40 + 1).
bad "series, mu1 = 1e-12: refused" series --masses 1e-12,1 --lengths 1,1 --beta 1
if grep -Eq 'mu2 = 1 - 1e-12 converges like mu2\^n: about [1-9][0-9]{13} terms' "$work/err"; then
  pass
else
  fail "series, mu1 = 1e-12: message"
fi
# SIGINT during a long torus run: the last finished level, "interrupted": true, errors covering.
"$pendavg" average --masses 1,1,1,1 --lengths 1,1,1,1 --beta 1e3 --digits 30 >"$work/out" 2>"$work/err" &
pid=$!
sleep 4
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 0 ] && "$python" -c "
import json, sys
d = json.load(open(sys.argv[1]))
assert d['interrupted'] and not d['converged'], d
exact = 0.4991310458913583  # the converged double value (error ~3e-14)
assert abs(float(d['beta_K'][0]) - exact) <= float(d['error'][0]), d
" "$work/out"; then pass; else fail "average SIGINT"; fi
# Issue 11: one big qmc point, a long transfer run and a long microcanonical run stop within
# seconds of SIGINT (polled between lattice chunks, between links, every 256 nodes): exit 0 with
# what they finished ("interrupted": true, not converged), or 130 and one line when nothing
# finished. A liveness bound with a wide margin (the runs take minutes), not a timing.
interrupt_within() { # NAME SECONDS_BEFORE_SIGNAL ARGS... (env limit_tenths: the bound, 150)
  local name=$1 delay=$2 waited=0 limit=${limit_tenths:-150}
  shift 2
  "$pendavg" "$@" >"$work/out" 2>"$work/err" &
  local pid=$!
  sleep "$delay"
  kill -INT "$pid"
  while kill -0 "$pid" 2>/dev/null && [ "$waited" -lt "$limit" ]; do
    sleep 0.1
    waited=$((waited + 1))
  done
  if kill -0 "$pid" 2>/dev/null; then
    kill -KILL "$pid"
    wait "$pid"
    fail "$name: still running $((limit / 10)) s after SIGINT"
    return
  fi
  wait "$pid"
  rc=$?
  if [ "$rc" -eq 130 ] && [ ! -s "$work/out" ] && [ "$(grep -vc '^\[' "$work/err")" -eq 1 ] &&
     grep -q '^pendavg: interrupted: ' "$work/err"; then
    pass
  elif [ "$rc" -eq 0 ] && "$python" -c "
import json, sys
d = json.load(open(sys.argv[1]))
assert d['interrupted'] and not d['converged'], d
" "$work/out"; then
    pass
  else
    fail "$name: exit $rc"
  fi
}
ones() { printf '1%.0s,' $(seq 2 "$1"); printf '1'; }
# The text format says so too: a qmc run of 64 short shifts stopped once its progress shows a
# finished shift (4% of the points: more than two shifts' worth, so one is finished on up to two
# threads; a fixed 3 s was not always enough on a loaded machine) reports the shifts it
# finished, "converged = no" and an "interrupted:" line.
"$pendavg" average --masses "$(ones 64)" --lengths "$(ones 64)" --beta 1 --method qmc \
  --samples 65536 --shifts 64 --format text >"$work/out" 2>"$work/err" &
text_pid=$!
for _ in $(seq 600); do  # up to 60 s
  grep -Eq '^\[average\] +([4-9]|[1-9][0-9])% of the qmc points' "$work/err" && break
  sleep 0.1
done
kill -INT "$text_pid"
wait "$text_pid"
rc=$?
if [ "$rc" -eq 0 ] && grep -q 'converged = no' "$work/out" && grep -q '^interrupted: ' "$work/out"; then
  pass
else
  fail "average --format text, interrupted: marked (exit $rc)"
fi
interrupt_within "qmc N = 64 at 2^20 points: SIGINT" 2 \
  average --masses "$(ones 64)" --lengths "$(ones 64)" --beta 1 --method qmc --samples 1048576
interrupt_within "transfer N = 4096: SIGINT" 2 \
  average --masses "$(ones 4096)" --lengths "$(ones 4096)" --beta 1 --tol 1e-12
interrupt_within "microcanonical N = 4 at 20 digits: SIGINT" 2 \
  average --masses 1,1,1,1 --lengths 1,1,1,1 --energy 0 --digits 20
# A torus level at N = 10 takes seconds (its first: 8^9 nodes; at N = 8 and 9 the work cap now
# ends the run after a first level of ~1-2 s, before the signal) and its outermost slices ~1/16
# of it: the stop request is polled before every innermost row of nodes (it took 4-5 s, the end
# of the slice; now ~20 ms).
for rule in torus-trapezoid torus-gauss; do
  limit_tenths=20 interrupt_within "$rule N = 10, SIGINT inside a level of seconds" 2 \
    average --masses "$(ones 10)" --lengths "$(ones 10)" --beta 1 --method "$rule" --tol 1e-12
done
interrupt_within "microcanonical qmc N = 64: SIGINT" 2 \
  average --masses "$(ones 64)" --lengths "$(ones 64)" --energy 0 --samples 65536 --shifts 1024
# The microcanonical engine's double range is checked before any work, with advice that works.
bad "micro energy 1e308"       average --masses 1,1 --lengths 1,1 --energy 1e308
bad "micro excitation 1e300"   average --masses 1 --lengths 1 --excitation 1e300
bad "micro mass ratio 1e300"   average --masses 1,1,1e300 --lengths 1,1,1 --energy 0
bad "micro subnormal excitation" average --masses 1,1 --lengths 1,1 --excitation 1e-310
printf 'energy,m1,m2,l1,l2\n0,1,1,1,1\n1e308,1,1,1,1\n' >"$work/micro_far.csv"
bad "micro cases energy 1e308" average --cases "$work/micro_far.csv"
good "micro energy 1e300 in MPFR" 'python3 -c "import json,sys; o=json.load(open(sys.argv[1])); assert abs(float(o[\"K\"][0]) / 1e300 - 0.3431834814709248549) < 1e-15" "$work/out"' \
  average --masses 1,1 --lengths 1,1 --energy 1e300 --digits 20
# The transfer operator's double range (total over lightest mass <= 1e150), before any work.
bad "transfer mass ratio 1e200" average --masses 1e-100,1e100,1,1e-100,1e100 --lengths 1,1,1,1,1 --beta 1
# Refused before any integration: an unstable time step, a flung chain, no accessible states.
bad "simulate dt 10"           simulate --masses 1,1 --lengths 1,1 --phi 1,0 --phidot 0,0 --dt 10 --time 100
bad "simulate phidot 1e10"     simulate --masses 1,1 --lengths 1,1 --phi 0,0 --phidot 1e10,0 --time 1
bad "simulate at rest, bottom" simulate --masses 1,1 --lengths 1,1 --theta 0 --time 3000000

# SIGINT ends a long table sweep cleanly: exit 0, the finished rows written after an
# '# interrupted' line, atomically to --output.
"$pendavg" table --beta log:1:1000:60 --mu1 0.001 --digits 1000 --output "$work/partial.csv" 2>"$work/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 0 ] && grep -q '^# interrupted: [0-9]* of 60 points computed' "$work/partial.csv" \
   && [ "$(grep -c '^2,' "$work/partial.csv")" -lt 60 ] && [ -z "$(ls "$work" | grep 'partial.csv.tmp')" ] \
   && grep -q "interrupted" "$work/err"; then pass; else fail "table SIGINT"; fi

check_poincare() { # POINTS
  "$python" - "$work/out" "$1" <<'PY'
import csv, math, sys
lines = open(sys.argv[1]).read().splitlines()
assert lines[:2] == ["# schema: 1", "# pendavg poincare"], lines[:2]
rows = list(csv.DictReader(lines[2:]))
assert list(rows[0])[-5:] == ["orbit", "phi2", "p2", "time", "seconds"], list(rows[0])
data = [[float(r[k]) for k in ("orbit", "phi2", "p2", "time")] for r in rows]
assert len(data) == int(sys.argv[2]), len(data)
assert all(r["energy"] == "-2.5" and r["interrupted"] == "false" for r in rows)
assert all(-math.pi <= r[1] <= math.pi for r in data)
# Inside the allowed region on the section: p2^2 <= 2 m2 l2^2 (E - U(0, phi2)), E = -2.5.
assert all(r[2] ** 2 <= 2 * (-2.5 + 2 + math.cos(r[1])) + 1e-9 for r in data)
PY
}
good "poincare csv"            'check_poincare 40' poincare --masses 1,1 --lengths 1,1 --energy -2.5 --orbits 4 --points 10
run poincare --masses 1,1 --lengths 1,1 --energy -2.5 --orbits 2 --points 5 --output "$work/section.csv"
if [ "$rc" -eq 0 ] && [ ! -s "$work/out" ] && [ "$(grep -c '^[0-9]' "$work/section.csv")" -eq 10 ] \
   && head -1 "$work/section.csv" | grep -qx '# schema: 1'; then pass; else fail "poincare --output"; fi
good "poincare json"           '"$python" -c "
import json, sys
d = json.load(open(sys.argv[1]))
assert d[\"schema\"] == 1 and d[\"command\"] == \"poincare\" and d[\"orbits\"] == 2 and d[\"points_per_orbit\"] == 3
assert len(d[\"points\"]) == 6 and all(set(p) == {\"orbit\", \"phi2\", \"p2\", \"time\"} for p in d[\"points\"])
" "$work/out"' poincare --masses 1,1 --lengths 1,1 --energy -2.5 --orbits 2 --points 3 --format json
bad "poincare bad format"      poincare --masses 1,1 --lengths 1,1 --energy 0 --format xml
bad "poincare N = 3"           poincare --masses 1,1,1 --lengths 1,1,1 --energy 0
bad "poincare below minimum"   poincare --masses 1,1 --lengths 1,1 --energy -3
bad "poincare no energy"       poincare --masses 1,1 --lengths 1,1
bad "poincare zero orbits"     poincare --masses 1,1 --lengths 1,1 --energy 0 --orbits 0
bad "poincare g = 0"           poincare --masses 1,1 --lengths 1,1 --energy 1 --g 0
bad "poincare unwritable"      poincare --masses 1,1 --lengths 1,1 --energy 0 --output /nonexistent/p.csv
# Issue 11: inputs that once aborted inside the parallel region or never ended.
for extreme in "--energy 1e308" "--energy 1 --g 1e308" "--energy 1 --g 1e300" ; do
  bad "poincare $extreme"      poincare --masses 1,1 --lengths 1,1 $extreme --orbits 2 --points 5
done
bad "poincare heavy mass"      poincare --masses 1,1e308 --lengths 1,1 --energy 1 --orbits 2 --points 5
bad "poincare long link"       poincare --masses 1,1 --lengths 1,1e308 --energy 1 --orbits 2 --points 5
bad "poincare dt 1e-320"       poincare --masses 1,1 --lengths 1,1 --energy -2.5 --dt 1e-320 --orbits 2 --points 5
# The advice fits the command: scales that overflow say so (not "use --dt 0"), and a command
# without --digits does not advise it.
for extreme in "--energy 1e308" "--g 1e308 --energy 1"; do
  run poincare --masses 1,1 --lengths 1,1 $extreme --orbits 2 --points 5
  # the energy scale overflows, or g leaves the dynamics' range (1e-50..1e50): both say why
  if [ "$rc" -eq 2 ] && grep -qE '(overflow double|outside 1e-50..1e50).*; choose units nearer 1' "$work/err"; then pass
  else fail "poincare $extreme: the overflow named"; fi
done
run poincare --masses 1,1 --lengths 1,1 --energy 1e400
if [ "$rc" -eq 2 ] && grep -q "out of the range of double$" "$work/err"; then pass
else fail "poincare --energy 1e400: no --digits advice"; fi
run simulate --masses 1,1 --lengths 1,1 --theta 0.1 --time 1e400
if [ "$rc" -eq 2 ] && grep -q "out of the range of double$" "$work/err"; then pass
else fail "simulate --time 1e400: no --digits advice"; fi
run average --masses 1,1 --lengths 1,1 --beta 1e400
if [ "$rc" -eq 2 ] && grep -q "(use --digits > 16)$" "$work/err"; then pass
else fail "average --beta 1e400: the --digits advice"; fi

# ---------------------------------------------------------------- microcanonical (issue 15)
micro_keys='N energy excitation digits ensemble method K K_error Kc Kc_error cos_phi cos_phi_error var_K var_K_error K_total K_total_error density_of_states density_of_states_error error_kind evaluations work_unit seconds converged run'
check_micro_json() { # N DIGITS [K1 reference: |K1 - reference| <= K_error1]
  "$python" - "$micro_keys" "$1" "$2" "${3:-}" "$work/out" <<'PY'
import json, sys
keys, n, digits, prefix = sys.argv[1].split(), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
lines = open(sys.argv[5]).read().splitlines()
assert len(lines) == 1, "one JSON line"
o = json.loads(lines[0])
assert list(o) == keys, list(o)
assert o["N"] == n and o["digits"] == digits and o["ensemble"] == "microcanonical", o
assert o["converged"] is True and o["error_kind"] in ("estimate", "statistical"), o
for k in ("K", "K_error", "cos_phi", "cos_phi_error", "var_K", "var_K_error"):
    assert isinstance(o[k], list) and len(o[k]) == n, k
    assert all(v.lower().find("nan") < 0 for v in o[k]), (k, o[k])
significant = sum(c.isdigit() for c in o["K"][0].lower().split("e")[0].lstrip("0.-"))
assert significant == digits, (o["K"][0], significant)
for value, error in zip(o["K"], o["K_error"]):
    assert 0 < float(error) < 1e-8 * float(value) or o["error_kind"] == "statistical", (value, error)
assert abs(sum(map(float, o["K"])) - float(o["K_total"])) <= 1e-12 * float(o["K_total"])
assert abs(float(o["Kc"]) * n - float(o["K_total"])) <= 1e-12 * float(o["K_total"])
if prefix:  # the printed value and its printed error (which includes the rounding to print)
    from decimal import Decimal, getcontext
    getcontext().prec = 60
    deviation = abs(Decimal(o["K"][0]) - Decimal(prefix))
    assert deviation <= Decimal(o["K_error"][0]), (o["K"][0], o["K_error"][0], prefix)
    assert deviation <= Decimal(10) ** (1 - digits) * Decimal(prefix), (o["K"][0], prefix)
PY
}
# Near the bottom of the unit double pendulum (issue 15). References: the 40-digit mpmath
# quadrature of the definition, `python3 tests/bench/near_minimum_ladder.py --reference 1,1 1,1 1 D`:
# at the double E = -2.99999999 (D = 9.99999993922529029...e-9, exactly) <K_1>_E =
# 2.4999999684000729769e-9 (the issue's audit: 2.49999996840007298e-09; the old engine was off by
# 3e-9 relative); at D = 1e-8 (the double in double runs, the decimal in MPFR runs; they differ
# by 2e-17 relative) <K_1>_E = 2.49999998359375020479329115840663e-9.
good "micro --energy near the minimum" 'check_micro_json 2 16 2.4999999684000729769e-9' \
  average --masses 1,1 --lengths 1,1 --energy -2.99999999
good "micro --excitation"      'check_micro_json 2 16 2.49999998359375020479329115840663e-9' \
  average --masses 1,1 --lengths 1,1 --excitation 1e-8
good "micro --excitation digits 30" 'check_micro_json 2 30 2.49999998359375020479329115840663e-9' \
  average --masses 1,1 --lengths 1,1 --excitation 1e-8 --digits 30
good "micro N = 3 unit, E = 0" 'check_micro_json 3 16 && cp "$work/out" "$work/micro3.json"' \
  average --masses 1,1,1 --lengths 1,1,1 --energy 0
# the torus-trapezoid rule (a different quadrature of the same integrals) against the integral rule
good "micro N = 3 torus-trapezoid agrees" '"$python" -c "
import json, sys
t, i = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
assert t[\"method\"] == \"torus-trapezoid\" and i[\"method\"] == \"integral\", (t, i)
for key in (\"K\", \"cos_phi\", \"var_K\"):
    for a, ea, b, eb in zip(t[key], t[key + \"_error\"], i[key], i[key + \"_error\"]):
        assert abs(float(a) - float(b)) <= float(ea) + float(eb) and float(ea) < 1e-4 * abs(float(a)), (key, a, ea, b, eb)
" "$work/out" "$work/micro3.json"' average --masses 1,1,1 --lengths 1,1,1 --energy 0 --method torus-trapezoid --tol 1e-5
good "micro N = 5 qmc"         'check_micro_json 5 16' \
  average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --samples 1024 --shifts 8
good "micro csv"               '[ "$(wc -l <"$work/out")" -eq 2 ] && head -1 "$work/out" | grep -q "^N,energy,excitation,digits,ensemble,method,K1,K2,K_error1" && [ "$(head -1 "$work/out" | tr , "\n" | wc -l)" -eq "$(tail -1 "$work/out" | tr , "\n" | wc -l)" ]' \
  average --masses 1,1 --lengths 1,1 --energy 0.5 --format csv
good "micro text"              'grep -q "microcanonical" "$work/out" && grep -q "Var K_i" "$work/out"' \
  average --masses 1,1 --lengths 1,1 --energy 0.5 --format text
bad "micro energy below the minimum" average --masses 1,1 --lengths 1,1 --energy -4
grep -q 'minimum energy E_min = -3' "$work/err" && pass || fail "micro energy below the minimum: no valid range"
bad "micro energy at the minimum" average --masses 1,1 --lengths 1,1 --energy -3
bad "micro excitation 0"       average --masses 1,1 --lengths 1,1 --excitation 0
bad "micro excitation -1"      average --masses 1,1 --lengths 1,1 --excitation -1
bad "micro energy nan"         average --masses 1,1 --lengths 1,1 --energy nan
bad "micro beta and energy"    average --masses 1,1 --lengths 1,1 --beta 1 --energy 0
bad "micro energy and excitation" average --masses 1,1 --lengths 1,1 --energy 0 --excitation 1
bad "micro method series"      average --masses 1,1 --lengths 1,1 --energy 0 --method series
bad "micro qmc digits 20"      average --masses 1,1 --lengths 1,1 --energy 0 --method qmc --digits 20
bad "micro N = 5 digits 20"    average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --digits 20
bad "micro N = 3 torus digits 20" average --masses 1,1,1 --lengths 1,1,1 --energy 0 --method torus-trapezoid --digits 20
bad "micro tol with qmc"       average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --tol 1e-5
bad "micro samples with integral" average --masses 1,1 --lengths 1,1 --energy 0 --samples 1024
bad "micro samples 2^17"       average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --samples 131072

printf 'm2,energy,g,m1,l1,l2\n1,-1,1,1,1,1\n1,-2.99999999,1,1,1,1\n0.5,5,9.81,0.5,1,2\n' >"$work/energy.csv"
micro_added=',K_total,K_total_error,density_of_states,density_of_states_error,work_unit'  # issue 10
micro_cases_header='energy,g,m1,m2,l1,l2,K1,K2,K_error1,K_error2,Kc,cos_phi1,cos_phi2,method,evaluations,Kc_error,cos_phi_error1,cos_phi_error2,var_K1,var_K2,var_K_error1,var_K_error2,error_kind,converged,excitation'"$micro_added"
good "cases energy column" \
  '[ "$(wc -l <"$work/out")" -eq 4 ] && [ "$(head -1 "$work/out")" = "$micro_cases_header" ] && sed -n 3p "$work/out" | cut -d, -f7 | grep -q "^2.4999999684000"' \
  average --cases "$work/energy.csv"
printf 'excitation,g,m1,m2,l1,l2\n1e-8,1,1,1,1,1\n' >"$work/excitation.csv"
# the mpmath reference above, to 20 digits: 2.4999999835937502048e-9
good "cases excitation column, digits 20" \
  '[ "$(wc -l <"$work/out")" -eq 2 ] && head -1 "$work/out" | grep -q ",converged,energy$micro_added$" && sed -n 2p "$work/out" | cut -d, -f7 | grep -q "^2.4999999835937502"' \
  average --cases "$work/excitation.csv" --digits 20
printf 'beta,energy,g,m1,m2,l1,l2\n1,1,1,1,1,1,1\n' >"$work/beta_energy.csv"
bad "cases beta and energy"    average --cases "$work/beta_energy.csv"
printf 'energy,g,m1,m2,l1,l2\n0,1,1,1,1,1\n-4,1,1,1,1,1\n' >"$work/energy_low.csv"
bad "cases energy below min"   average --cases "$work/energy_low.csv"
grep -q 'line 3' "$work/err" && pass || fail "cases energy below min: stderr does not name line 3"
# microcanonical rows run through the same sweep engine: --timing as for beta rows
run average --cases "$work/energy.csv"
cp "$work/out" "$work/energy_out.csv"
run average --cases "$work/energy.csv" --timing
[ "$rc" -eq 0 ] && cmp -s "$work/out" "$work/energy_out.csv" && [ "$(wc -l <"$work/err")" -eq 1 ] &&
  grep -Eq '^pendavg: timing: rows=3 median_us=' "$work/err" && pass ||
  fail "cases energy --timing: stdout or the stderr summary line"
bad "cases energy and --energy" average --cases "$work/energy.csv" --energy 1

check_micro_table() { # ROWS STATE
  "$python" - "$work/out" "$1" "$2" <<'PY'
import csv, sys
lines = [l for l in open(sys.argv[1]) if not l.startswith("#")]
rows = list(csv.DictReader(lines))
assert len(rows) == int(sys.argv[2]), len(rows)
state = sys.argv[3]
other = "excitation" if state == "energy" else "energy"
header = lines[0].strip().split(",")
added = ["K_total", "K_total_error", "density_of_states", "density_of_states_error", "work_unit"]
assert header[2] == state and header[-6:] == [other] + added, header
for r in rows:
    assert r["converged"] == "true", r
    n = int(r["N"])
    total = sum(float(r["K%d" % (i + 1)]) for i in range(n))
    assert abs(float(r["Kc"]) * n - total) <= 1e-12 * total, r
    for i in range(n):
        assert float(r["K_error%d" % (i + 1)]) > 0, r
PY
}
good "table --excitation log sweep" 'check_micro_table 6 excitation' \
  table --excitation log:1e-12:1:3 --mu1 0.5,0.2
good "table --energy chains"   'check_micro_table 4 energy' \
  table --chain 3,5 --energy 0,1 --samples 1024 --shifts 8
good "table --energy digits 20" 'check_micro_table 2 energy' \
  table --energy -1,1 --digits 20 --l2 2
bad "table beta and energy"    table --beta 1 --energy 0
bad "table energy below min"   table --energy -2,0 --l2 2
bad "table energy method series" table --energy 0 --method series
bad "table energy qmc digits 20" table --chain 5 --energy 0 --digits 20

# simulate: exact values with every digit of the double (the shortest text that reads back as
# the same double, not rounded to fewer digits)
good "simulate exact full digits" '"$python" -c "
import json, sys
from decimal import Decimal
o = json.load(open(sys.argv[1]))
digits = lambda v: sum(c.isdigit() for c in v.lower().split(\"e\")[0].lstrip(\"0.-\"))
raw = open(sys.argv[1]).read()
import re
k = re.search(r\"\\\"exact_K\\\": \\[([^]]*)\\]\", raw).group(1).split(\", \")
assert all(Decimal(v) == Decimal(repr(float(v))) for v in k), k
assert max(digits(v) for v in k) >= 15, k
assert o[\"exact_excitation\"] > 0 and len(o[\"exact_var_K\"]) == 2, o
assert abs(o[\"exact_excitation\"] - (o[\"energy\"] + 3)) < 1e-8, o
" "$work/out"' simulate --masses 1,1 --lengths 1,1 --theta 90deg --time 50 --format json

# qmc weights cannot underflow (issue 15: this run printed NaN with "converged": true); its
# values within their bars of the tensor torus rule's
good "torus beta 100 (reference)" 'cp "$work/out" "$work/torus100.json"' \
  average --masses 1,1,1 --lengths 1,1,1 --beta 100 --method torus-trapezoid
good "qmc beta 100 seed 16 finite" '"$python" -c "
import json, sys, math
o, t = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
for k in (\"beta_K\", \"error\", \"cos_phi\", \"cos_phi_error\", \"var_K\", \"var_K_error\"):
    assert all(math.isfinite(float(v)) for v in o[k]), (k, o[k])
assert o[\"converged\"] is True and o[\"method\"] == \"qmc\", o
for key, error in ((\"beta_K\", \"error\"), (\"cos_phi\", \"cos_phi_error\"), (\"var_K\", \"var_K_error\")):
    for a, ea, b, eb in zip(o[key], o[error], t[key], t[error]):
        assert abs(float(a) - float(b)) <= float(ea) + float(eb), (key, a, ea, b, eb)
" "$work/out" "$work/torus100.json"' average --masses 1,1,1 --lengths 1,1,1 --beta 100 --method qmc --seed 16
# ---------------------------------------------------------------- issue 10: every error in every output
# The keys and columns added after the original ones: present, finite (JSON never holds a bare
# nan/inf: json.loads below refuses NaN and Infinity), errors positive, kinds valid, and equal to
# what `average` prints for the same point where both print it.
cat >"$work/strict_json.py" <<'PY'
import json
def strict(path):
    def refuse(token):
        raise ValueError("bare " + token)
    return json.loads(open(path).read(), parse_constant=refuse)
KINDS = {"bound", "estimate", "statistical"}
PY
strict_python() { PYTHONPATH="$work" "$python" "$@"; }

check_limit_added() { # N RUN_KEYS (the keys of high_temperature.run, "null" for none)
  strict_python - "$work/out" "$1" "$2" <<'PY'
from strict_json import strict, KINDS
import math, sys
from decimal import Decimal as D
d = strict(sys.argv[1]); n = int(sys.argv[2])
original = ["beta_K", "error", "ratio", "var_K_beta2", "method", "error_kind", "ratio_error",
            "cos_phi", "cos_phi_error", "var_K_beta2_error", "error_kinds", "evaluations", "work_unit"]
added = ["converged", "run", "equipartition_residual", "beta_Kc", "beta_Kc_error"]
assert list(d) == ["N", "digits", "high_temperature", "low_temperature", "seconds"], list(d)
assert isinstance(d["seconds"], float) and 0 <= d["seconds"] < 600, d["seconds"]
for part in ("high_temperature", "low_temperature"):
    o = d[part]
    assert list(o) == original + added, list(o)
    assert o["converged"] is True, o
    assert [D(x) for x in o["beta_Kc"]] == [D("0.5")] * n, o["beta_Kc"]
    assert len(o["beta_Kc_error"]) == n and all(0 < float(e) < 1e-14 for e in o["beta_Kc_error"]), o
    assert set(o["error_kinds"]) == {"beta_K", "ratio", "cos_phi", "var_K_beta2", "beta_Kc"}, o
    assert set(o["error_kinds"].values()) <= KINDS and o["error_kinds"]["beta_Kc"] == "bound", o
    # the residual |sum_i beta<K_i> - N/2| against the printed values (within their errors and
    # the residual's own 3 digits)
    residual = D(o["equipartition_residual"])
    assert residual >= 0, residual
    total = sum(D(x) for x in o["beta_K"])
    bars = sum(D(x) for x in o["error"])
    assert abs(abs(total - D(n) / 2) - residual) <= bars + residual / 100, (total, residual, bars)
run = d["high_temperature"]["run"]
if sys.argv[3] == "null":
    assert run is None, run
else:
    assert sorted(run) == sorted(sys.argv[3].split(",")) and all(v > 0 for v in run.values()), run
assert d["low_temperature"]["run"] is None
PY
}
good "limit json: converged, run, residual, beta_Kc, seconds (N = 2)" 'check_limit_added 2 null' \
  limit --masses 0.5,0.5
good "limit json: the torus run (N = 3)" 'check_limit_added 3 points_per_dim,levels,grid_points' \
  limit --masses 1,2,0.5 --lengths 1,0.5,2
good "limit json: the transfer run (N = 7)" 'check_limit_added 7 angle_nodes,pivot_nodes,levels' \
  limit --masses 1,1,1,1,1,1,1
good "limit json: digits 30" 'check_limit_added 2 null' limit --masses 0.2,0.8 --lengths 1,2 --digits 30

# limit --format csv: average's columns (the same writer), then the limit's own; its values are
# the JSON's.
check_limit_csv() { # N MASSES LENGTHS DIGITS
  "$pendavg" limit --masses "$2" --lengths "$3" --digits "$4" >"$work/limit.json" &&
  "$pendavg" average --masses "$2" --lengths "$3" --beta 1 --digits "$4" --format csv >"$work/average.csv" &&
  strict_python - "$work/out" "$work/limit.json" "$work/average.csv" "$1" "$4" <<'PY'
from strict_json import strict, KINDS
import csv, math, sys
from decimal import Decimal as D
lines = open(sys.argv[1]).read().splitlines()
d = strict(sys.argv[2]); n = int(sys.argv[4])
average_header = open(sys.argv[3]).readline().strip().split(",")
per = lambda stem: [f"{stem}{i}" for i in range(1, n + 1)]
assert lines[0].split(",") == (average_header + ["limit"] + per("beta2_var_K") + per("beta2_var_K_error")
                               + per("beta_Kc_error") + ["beta_Kc_error_kind"]), lines[0]
rows = list(csv.DictReader(lines))
assert [r["limit"] for r in rows] == ["high_temperature", "low_temperature"], rows
assert all(len(l.split(",")) == len(average_header) + 3 * n + 2 for l in lines), "ragged"
for r in rows:
    o = d[r["limit"]]
    assert r["N"] == str(n) and r["digits"] == sys.argv[5] and r["method"] == o["method"], r
    assert r["beta"] == "" and not any(r[k] for k in per("K") + per("var_K") + per("K_error") + per("var_K_error")), r
    assert [r[k] for k in per("beta_K")] == o["beta_K"] and [r[k] for k in per("error_K")] == o["error"]
    assert [r[k] for k in per("cos_phi")] == o["cos_phi"] and [r[k] for k in per("cos_phi_error")] == o["cos_phi_error"]
    assert [r[k] for k in per("beta2_var_K")] == o["var_K_beta2"]
    assert [r[k] for k in per("beta2_var_K_error")] == o["var_K_beta2_error"]
    assert [r[k] for k in per("beta_Kc")] == o["beta_Kc"] and [r[k] for k in per("beta_Kc_error")] == o["beta_Kc_error"]
    assert r["ratio"] == (o["ratio"] or "") and r["ratio_error"] == (o["ratio_error"] or "")
    assert r["equipartition_residual"] == o["equipartition_residual"] and r["converged"] == "true"
    assert r["evaluations"] == str(o["evaluations"]) and r["work_unit"] == o["work_unit"]
    assert r["error_kind"] == o["error_kind"] and r["cos_phi_error_kind"] == o["error_kinds"]["cos_phi"]
    assert r["var_K_error_kind"] == o["error_kinds"]["var_K_beta2"] and r["beta_Kc_error_kind"] == "bound"
    assert math.isfinite(float(r["seconds"])) and float(r["seconds"]) >= 0
    for k in per("error_K") + per("cos_phi_error") + per("beta2_var_K_error") + per("beta_Kc_error"):
        # positive, or 0 beside an exact 0 (<cos phi_i> = 0 at beta -> 0: kind bound)
        value = r[k.replace("_error", "").replace("error_K", "beta_K")]
        assert math.isfinite(float(r[k])) and (float(r[k]) > 0 or float(value) == 0), (k, r[k])
    for k in per("beta_K") + per("cos_phi") + per("beta2_var_K") + per("diagonal_approx"):
        assert math.isfinite(float(r[k])), (k, r[k])
PY
}
good "limit --format csv (N = 2)"            'check_limit_csv 2 0.5,0.5 1,1 16' limit --masses 0.5,0.5 --lengths 1,1 --format csv
good "limit --format csv (N = 3, torus)"     'check_limit_csv 3 1,2,0.5 1,0.5,2 16' limit --masses 1,2,0.5 --lengths 1,0.5,2 --format csv
good "limit --format csv (N = 2, digits 30)" 'check_limit_csv 2 0.2,0.8 1,2 30' limit --masses 0.2,0.8 --lengths 1,2 --digits 30 --format csv
good "limit --format csv (N = 1)"            'check_limit_csv 1 2 3 16' limit --masses 2 --lengths 3 --format csv
good "limit text: errors, work, residual per limit" \
  '[ "$(grep -c "^beta -> 0: " "$work/out")" -eq 3 ] && [ "$(grep -c "^beta -> inf: " "$work/out")" -eq 3 ] &&
   [ "$(grep -c "converged = yes" "$work/out")" -eq 2 ] && grep -q "^beta -> 0: |sum_i beta<K_i> - N/2| = " "$work/out"' \
  limit --masses 0.5,0.5 --format text

# simulate JSON: <K> and <U> over time, the energy trend, the work; Langevin: the canonical Var K_i.
check_simulate_added() { # ENSEMBLE [AVERAGE_JSON: the canonical values at the run's beta]
  strict_python - "$work/out" "$1" "${2:-}" <<'PY'
from strict_json import strict, KINDS
import math, sys
from decimal import Decimal as D
d = strict(sys.argv[1]); ensemble = sys.argv[2]; n = d["N"]
assert d["schema"] == 1 and d["command"] == "simulate" and d["ensemble"] == ensemble, d
# every key of the schema's simulation table, null where the run has no value
expected = ["K_total", "K_total_error", "K_total_error_kind", "potential", "potential_error",
            "potential_error_kind", "energy_trend", "energy_trend_reason", "unconverged_stages",
            "samples", "exact_var_K", "exact_var_K_error", "exact_K_error_kind", "exact_Kc_error_kind",
            "exact_cos_phi_error_kind", "exact_var_K_error_kind", "exact_var_K_reason", "error_reason"]
assert set(expected) <= set(d), set(expected) - set(d)
for k in ("K_total", "K_total_error", "potential", "potential_error"):
    assert isinstance(d[k], float) and math.isfinite(d[k]), k
assert d["K_total_error"] > 0 and d["potential_error"] > 0
assert d["K_total_error_kind"] == d["potential_error_kind"] == d["K_error_kind"] == "statistical"
assert d["error_reason"] is None and d["exact_var_K_reason"] is None
# <K> is the sum of the <K_i>
assert abs(d["K_total"] - sum(d["K"])) <= 1e-9 * d["K_total"], (d["K_total"], d["K"])
assert isinstance(d["unconverged_stages"], int) and d["unconverged_stages"] >= 0
assert isinstance(d["samples"], int) and 0 < d["samples"] <= d["steps"], d["samples"]
kinds = {q: d[f"exact_{q}_error_kind"] for q in ("K", "Kc", "cos_phi", "var_K")}
assert set(kinds.values()) <= KINDS, kinds
for value, error in zip(d["exact_var_K"], d["exact_var_K_error"]):
    assert math.isfinite(value) and value > 0 and math.isfinite(error) and error > 0, (value, error)
assert len(d["exact_var_K"]) == n
if ensemble == "microcanonical":
    assert d["energy_trend_reason"] is None and d["beta"] is None and d["exact_excitation"] > 0
    # <K> + <U> = E: every sample lies within energy_error_max x scale of E, scale = (sum m) g (sum l)
    scale = 2 * 2
    # (energy_error_max is printed with 3 digits, rounded up: it covers the computed one)
    bound = d["energy_error_max"]
    assert abs(d["K_total"] + d["potential"] - d["energy"]) <= bound * scale + 1e-8
    # the least-squares change of E over the run is at most 6 x the largest deviation
    assert math.isfinite(d["energy_trend"]) and abs(d["energy_trend"]) <= 6 * bound, d
else:
    assert d["energy_trend"] is None and d["energy_trend_reason"], d
    assert d["exact_excitation"] is None
    # canonical <K> = N / (2 beta) exactly: within 4 error bars
    assert abs(d["K_total"] - n / (2 * d["beta"])) <= 4 * d["K_total_error"], (d["K_total"], d["K_total_error"])
    a = strict(sys.argv[3])  # average --format json at the same chain and beta
    for i in range(n):  # Var K_i: both the doubles computed (the printed error covers the rounding)
        assert abs(D(repr(d["exact_var_K"][i])) - D(repr(a["var_K"][i]))) <= D(repr(a["var_K_error"][i])), i
    assert kinds["K"] == a["beta_K_error_kind"] and kinds["cos_phi"] == a["cos_phi_error_kind"], (kinds, a)
    assert kinds["var_K"] == a["var_K_error_kind"] and kinds["Kc"] == "bound"
PY
}
good "simulate json: K_total, potential, energy_trend, samples (NVE)" 'check_simulate_added microcanonical' \
  simulate --masses 1,1 --lengths 1,1 --theta 90deg --time 300 --format json
"$pendavg" average --masses 1,1 --lengths 1,1 --beta 0.5 --format json >"$work/canonical.json" 2>/dev/null
good "simulate json: exact_var_K and kinds (Langevin)" 'check_simulate_added canonical "$work/canonical.json"' \
  simulate --masses 1,1 --lengths 1,1 --theta 0 --time 300 --thermostat langevin --beta 0.5 --seed 3 --format json
"$pendavg" average --masses 1,2,1 --lengths 1,1,0.5 --beta 2 --format json >"$work/canonical3.json" 2>/dev/null
good "simulate json: exact_var_K (Langevin, N = 3)" 'check_simulate_added canonical "$work/canonical3.json"' \
  simulate --masses 1,2,1 --lengths 1,1,0.5 --theta 0 --time 200 --thermostat langevin --beta 2 --seed 5 --format json

# simulate CSV (the default): every column holds the JSON's value (the same deterministic run):
# a per-particle key X is the columns X1..XN (its error X_error X1_error..XN_error).
check_simulate_csv() { # JSON_OF_THE_SAME_RUN [replicas]
  strict_python - "$work/out" "$1" "${2:-}" <<'PY'
from strict_json import strict, KINDS
import csv, math, re, sys
lines = open(sys.argv[1]).read().splitlines()
assert lines[:2] == ["# schema: 1", "# pendavg simulate"], lines[:2]
rows = list(csv.DictReader(lines[2:]))
d = strict(sys.argv[2]); replicas = sys.argv[3] == "replicas"; n = d["N"]
assert len(rows) == 1 and len(lines) == 4 and len(lines[3].split(",")) == len(lines[2].split(","))
r = rows[0]
def column(key, i):  # the particle's index before "_error" (K_error_blocking -> K1_error_blocking)
    m = re.search(r"_error(_|$)", key)
    at = m.start() if m else len(key)
    return key[:at] + str(i + 1) + key[at:]
def same(cell, value):
    if value is None:
        return cell == ""
    if isinstance(value, bool):
        return cell == ("true" if value else "false")
    if isinstance(value, (int, float)):
        return cell != "" and float(cell) == value
    return cell == value
columns = set()
for key, value in d.items():
    if key in ("schema", "command", "seconds"):
        continue
    if isinstance(value, list):
        assert len(value) == n, key
        for i, v in enumerate(value):
            columns.add(column(key, i))
            assert same(r[column(key, i)], v), (key, i, r[column(key, i)], v)
    else:
        columns.add(key)
        assert same(r[key], value), (key, r[key], value)
assert set(r) == columns | {"seconds"}, set(r) ^ (columns | {"seconds"})
exact = d["exact_method"] is not None
for i in range(n):
    assert float(r[f"cos_phi{i + 1}_error"]) > 0 and r["cos_phi_error_kind"] == "statistical"
    if not exact:
        assert not any(r[k] for k in r if k.startswith("exact_")), r
        continue
    for stem in ("exact_cos_phi", "exact_var_K"):
        assert float(r[f"{stem}{i + 1}"]) > 0 and float(r[f"{stem}{i + 1}_error"]) > 0, stem
    assert float(r["exact_Kc_error"]) > 0 or r["exact_Kc_error_kind"] == "bound"
    assert {r[f"exact_{q}_error_kind"] for q in ("K", "Kc", "cos_phi", "var_K")} <= KINDS, r
    if replicas:
        for stem in ("Kc", "cos_phi"):
            for part in ("blocking", "replicas"):
                assert float(r[f"{stem}{i + 1}_error_{part}"]) > 0, (stem, part)
assert ("replicas" in r) == replicas
PY
}
nve3=(simulate --masses 1,2,1 --lengths 1,1,0.5 --phi 0.5,-1,2 --phidot 0,1,0 --time 50)
"$pendavg" "${nve3[@]}" --format json >"$work/nve3.json" 2>/dev/null
good "simulate csv: cos_phi, exact values and kinds (NVE)" 'check_simulate_csv "$work/nve3.json"' "${nve3[@]}"
"$pendavg" "${nve3[@]}" --exact no --format json >"$work/nve3_no_exact.json" 2>/dev/null
good "simulate csv: --exact no leaves the exact cells empty" 'check_simulate_csv "$work/nve3_no_exact.json"' "${nve3[@]}" --exact no --format csv
langevin2=(simulate --masses 1,1 --lengths 1,1 --theta 0 --time 100 --thermostat langevin --beta 0.5 --seed 3)
"$pendavg" "${langevin2[@]}" --format json >"$work/langevin2.json" 2>/dev/null
good "simulate csv: exact_var_K (Langevin)" 'check_simulate_csv "$work/langevin2.json"' "${langevin2[@]}" --format csv
replicas3=(simulate --masses 1,1,1 --lengths 1,1,1 --theta 0 --time 40 --thermostat langevin --beta 1 --replicas 4)
"$pendavg" "${replicas3[@]}" --format json >"$work/replicas3.json" 2>/dev/null
good "simulate csv: the replicas' error columns" 'check_simulate_csv "$work/replicas3.json" replicas' "${replicas3[@]}" --format csv
# --replicas: <K> and <U> combined like the other averages (the larger of the two errors)
check_replicas_added() {
  strict_python - "$work/out" <<'PY'
from strict_json import strict, KINDS
import sys
d = strict(sys.argv[1])
assert d["replicas"] == 4 and d["samples"] > 0 and d["unconverged_stages"] >= 0
for stem in ("K_total", "potential"):
    b, r = d[stem + "_error_blocking"], d[stem + "_error_replicas"]
    assert b > 0 and r > 0 and d[stem + "_error"] == max(b, r), (stem, b, r, d[stem + "_error"])
assert abs(d["K_total"] - sum(d["K"])) <= 1e-9 * d["K_total"]
assert d["replicas_error_reason"] is None
PY
}
good "simulate json: K_total and potential over replicas" check_replicas_added "${replicas3[@]}" --format json

# table and --cases rows: the added columns equal `average --format csv`'s for the same point
# (the same library call); a series row's beta_K error is a bound, its cos_phi and var_K errors
# estimates.
canonical_columns='cos_phi_error_kind var_K_error_kind work_unit equipartition_residual'
check_rows_as_average() { # FILE KIND (table | cases): every row against `average --format csv`
  "$python" - "$1" "$2" "$pendavg" "$canonical_columns" <<'PY'
import csv, math, subprocess, sys
kind, pendavg, shared = sys.argv[2], sys.argv[3], sys.argv[4].split()
lines = [l for l in open(sys.argv[1]).read().splitlines() if not l.startswith("#")]
rows = list(csv.DictReader(lines))
assert rows and all(len(l.split(",")) == len(lines[0].split(",")) for l in lines), "ragged"
kinds = {"bound", "estimate", "statistical"}
for r in rows:
    n = int(r["N"]) if kind == "table" else sum(1 for k in r if k.startswith("m") and k[1:].isdigit())
    masses = ",".join(r[f"m{i}"] for i in range(1, n + 1))
    lengths = ",".join(r[f"l{i}"] for i in range(1, n + 1))
    args = [pendavg, "average", "--masses", masses, "--lengths", lengths, "--beta", r["beta"],
            "--g", r["g"], "--format", "csv"]
    if kind == "table":
        args += ["--digits", r["digits"]]
    if r["method"] == "series":
        args += ["--method", "series"]
    a = next(csv.DictReader(subprocess.run(args, capture_output=True, text=True, check=True).stdout.splitlines()))
    names = shared + [f"beta_Kc{i}" for i in range(1, n + 1)]
    names += ["beta_K1", "error_K1", "cos_phi1", "cos_phi_error1", "method", "evaluations", "error_kind"]
    assert [r[k] for k in names] == [a[k] for k in names], [(k, r[k], a[k]) for k in names if r[k] != a[k]]
    assert {r["cos_phi_error_kind"], r["var_K_error_kind"], r["beta_Kc_error_kind"]} <= kinds, r
    assert r["beta_Kc_error_kind"] == "bound" and r["work_unit"] in ("terms", "nodes", "samples"), r
    assert math.isfinite(float(r["equipartition_residual"])) and float(r["equipartition_residual"]) >= 0
    for i in range(1, n + 1):
        assert float(r[f"beta_Kc{i}"]) == 0.5 and 0 < float(r[f"beta_Kc_error{i}"]) < 1e-14, r
    if r["method"] == "series":
        assert (r["error_kind"], r["cos_phi_error_kind"], r["var_K_error_kind"]) == ("bound", "estimate", "estimate"), r
PY
}
good "table: error kinds, work_unit, residual, beta_Kc (series rows)" 'check_rows_as_average "$work/out" table' \
  table --beta 0.5,2 --mu1 0.3 --l2 0.7 --method series
good "table: the same for chains N = 3, 5 (torus, transfer)" 'check_rows_as_average "$work/out" table' \
  table --chain 3,5 --beta 1 --g 1,2
good "table: the same at digits 30" 'check_rows_as_average "$work/out" table' \
  table --beta 1 --mu1 0.3 --digits 30
good "cases: error kinds, work_unit, residual, beta_Kc" 'check_rows_as_average "$work/out" cases' \
  average --cases "$work/cases.csv"
good "cases: the same for N = 3" 'check_rows_as_average "$work/out" cases' \
  average --cases "$work/cases3.csv"
good "cases: the same for series rows" 'check_rows_as_average "$work/out" cases' \
  average --cases "$work/cases.csv" --method series

# microcanonical rows: K_total, density_of_states (each with its error) and work_unit, equal to
# `average --energy/--excitation --format csv`'s.
check_micro_added() { # FILE KIND (table | cases) STATE
  "$python" - "$1" "$2" "$3" "$pendavg" <<'PY'
import csv, math, subprocess, sys
kind, state, pendavg = sys.argv[2], sys.argv[3], sys.argv[4]
lines = [l for l in open(sys.argv[1]).read().splitlines() if not l.startswith("#")]
rows = list(csv.DictReader(lines))
assert rows and all(len(l.split(",")) == len(lines[0].split(",")) for l in lines), "ragged"
added = ["K_total", "K_total_error", "density_of_states", "density_of_states_error", "work_unit"]
assert lines[0].split(",")[-5:] == added, lines[0]
for r in rows:
    n = int(r["N"]) if kind == "table" else sum(1 for k in r if k.startswith("m") and k[1:].isdigit())
    args = [pendavg, "average", "--masses", ",".join(r[f"m{i}"] for i in range(1, n + 1)),
            "--lengths", ",".join(r[f"l{i}"] for i in range(1, n + 1)), f"--{state}", r[state],
            "--g", r["g"], "--format", "csv"]
    if kind == "table":
        args += ["--digits", r["digits"]]
    if r["method"] == "qmc":
        args += ["--samples", "1024", "--shifts", "8"]
    a = next(csv.DictReader(subprocess.run(args, capture_output=True, text=True, check=True).stdout.splitlines()))
    assert [r[k] for k in added] == [a[k] for k in added], [(k, r[k], a[k]) for k in added]
    for k in ("K_total", "K_total_error", "density_of_states", "density_of_states_error"):
        assert math.isfinite(float(r[k])) and float(r[k]) > 0, (k, r[k])
    total = sum(float(r[f"K{i}"]) for i in range(1, n + 1))
    bars = sum(float(r[f"K_error{i}"]) for i in range(1, n + 1)) + float(r["K_total_error"])
    assert abs(total - float(r["K_total"])) <= bars, (total, r["K_total"], bars)
    assert r["work_unit"] == ("samples" if r["method"] == "qmc" else "nodes"), r
PY
}
good "table --excitation: K_total, density_of_states, work_unit" 'check_micro_added "$work/out" table excitation' \
  table --excitation log:1e-6:1:3 --mu1 0.5,0.2
good "table --energy chains: the same (integral, qmc)" 'check_micro_added "$work/out" table energy' \
  table --chain 3,5 --energy 0,1 --samples 1024 --shifts 8
good "table --energy digits 20: the same" 'check_micro_added "$work/out" table energy' \
  table --energy -1,1 --digits 20 --l2 2
good "cases energy column: K_total, density_of_states, work_unit" 'check_micro_added "$work/out" cases energy' \
  average --cases "$work/energy.csv"
good "cases excitation column: the same" 'check_micro_added "$work/out" cases excitation' \
  average --cases "$work/excitation.csv"

# --certified (N = 2): every printed error a bound that covers the printed value; the JSON's
# kinds are all "bound" and the printed value lies within its printed error of a 60-digit run.
check_certified() { # FILE DIGITS REFERENCE-FILE
  "$python" - "$1" "$2" "$3" <<'PY'
import json, sys
from decimal import Decimal, getcontext
getcontext().prec = 80
run, digits, ref = json.load(open(sys.argv[1])), int(sys.argv[2]), json.load(open(sys.argv[3]))
assert run["method"] == "certified-integral" and run["error_kind"] == "bound", run
assert run["converged"] is True, run
assert all(k == "bound" for k in run["error_kinds"].values()), run["error_kinds"]
for key, err in (("beta_K", "error"), ("K", "K_error"), ("cos_phi", "cos_phi_error"),
                 ("var_K", "var_K_error")):
    for v, e, r in zip(run[key], run[err], ref[key]):
        assert abs(Decimal(v) - Decimal(r)) <= Decimal(e), (key, v, e, r)
        assert Decimal(e) <= Decimal(10) ** (2 - digits) * abs(Decimal(v)) + Decimal("1e-300"), (key, v, e)
assert abs(Decimal(run["ratio"]) - Decimal(ref["ratio"])) <= Decimal(run["ratio_error"])
PY
}
if "$pendavg" --version | grep -q '^certified enclosures (--certified): Arb'; then
  run average --masses 1,3 --lengths 1,2 --beta 7 --g 2 --certified --digits 60
  cp "$work/out" "$work/certified_ref.json"
  good "average --certified: bounds (double)" 'check_certified "$work/out" 16 "$work/certified_ref.json"' \
    average --masses 1,3 --lengths 1,2 --beta 7 --g 2 --certified
  good "average --certified --digits 30: bounds" 'check_certified "$work/out" 30 "$work/certified_ref.json"' \
    average --masses 1,3 --lengths 1,2 --beta 7 --g 2 --certified --digits 30
  good "limit --certified: beta -> 0 in balls" 'grep -q "\"certified-integral\"" "$work/out"' \
    limit --masses 1,3 --certified
  printf 'beta,g,m1,m2,l1,l2\n7,2,1,3,1,2\n' >"$work/certified.csv"
  good "average --cases --certified: kind bound" 'grep -q ",certified-integral," "$work/out" && ! grep -q estimate "$work/out"' \
    average --cases "$work/certified.csv" --certified
  bad "average --certified N = 3" average --masses 1,1,1 --lengths 1,1,1 --beta 1 --certified
  bad "average --certified --method series" average --masses 1,1 --lengths 1,1 --beta 1 --certified --method series
  bad "average --certified --energy" average --masses 1,1 --lengths 1,1 --energy 1 --certified
else
  bad "average --certified without Arb" average --masses 1,1 --lengths 1,1 --beta 1 --certified
fi

good "average --help: microcanonical and MPFR" 'grep -q "excitation D" "$work/out" && grep -q "runs in MPFR" "$work/out"' average --help

for command in average limit series simulate poincare; do
  good "$command --help"     'grep -q "usage" "$work/out"' "$command" --help
done
good "--help"                'grep -q "usage" "$work/out"' --help
good "help"                  'grep -q "usage" "$work/out"' help
good "help average"          'grep -q "usage" "$work/out"' help average
good "--version"             'head -n 1 "$work/out" | grep -Eqx "pendavg [0-9]+\.[0-9]+\.[0-9]+"' --version

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
