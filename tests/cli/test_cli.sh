#!/usr/bin/env bash
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

# good NAME CHECK ARGS... : expects exit 0, empty stderr, and CHECK (a shell command reading
# $work/out) to succeed.
good() {
  local name=$1 check=$2
  shift 2
  run "$@"
  if [ "$rc" -ne 0 ]; then
    fail "$name: exit code $rc, expected 0"
  elif [ -s "$work/err" ]; then
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
bad "N = 3 average"     average --masses 1,1,1 --lengths 1,1,1 --beta 1
bad "limit mass 0"      limit --masses 0,1
bad "limit csv"         limit --masses 1,1 --format csv
bad "series beta 0"     series "${pendulum[@]}" --beta 0 --terms 3
bad "series terms -1"   series "${pendulum[@]}" --beta 1 --terms -1
bad "help unknown"      help nothing

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
cases_header='beta,g,m1,m2,l1,l2,beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,method,evaluations'
good "cases shuffled" \
  '[ "$(wc -l <"$work/out")" -eq 4 ] && [ "$(head -1 "$work/out")" = "$cases_header" ] && [ "$(sed -n 3p "$work/out" | cut -d, -f1-6)" = "10,1,0.2,0.8,1,1" ]' \
  average --cases "$work/cases.csv"
good "cases shuffled, digits 20" '[ "$(wc -l <"$work/out")" -eq 4 ]' \
  average --cases "$work/cases.csv" --digits 20

check_limit() {
  "$python" -c '
import json, sys, decimal
o = json.loads(open(sys.argv[1]).read())
for part in ("high_temperature", "low_temperature"):
    assert list(o[part]) == ["beta_K", "error", "ratio", "var_K_beta2"], list(o[part])
value = format(decimal.Decimal(o["high_temperature"]["beta_K"][0]), "f")
assert value.startswith("0.3431834814709"), value
' "$work/out"
}
good "limit paper value"     check_limit limit --masses 0.5,0.5
good "limit paper value, digits 40" check_limit limit --masses 0.5,0.5 --digits 40
good "limit text"            '[ -s "$work/out" ]' limit --masses 0.5,0.5 --format text

good "series 5 terms text" \
  '[ "$(sed "1d;\$d" "$work/out" | grep -c "^ *[0-9]")" -eq 5 ]' \
  series "${pendulum[@]}" --beta 1 --terms 5
good "series 5 terms csv"    '[ "$(wc -l <"$work/out")" -eq 6 ]' \
  series "${pendulum[@]}" --beta 1 --terms 5 --format csv

for command in average limit series; do
  good "$command --help"     'grep -q "usage" "$work/out"' "$command" --help
done
good "--help"                'grep -q "usage" "$work/out"' --help
good "help"                  'grep -q "usage" "$work/out"' help
good "help average"          'grep -q "usage" "$work/out"' help average
good "--version"             '[ "$(wc -l <"$work/out")" -eq 1 ]' --version

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
