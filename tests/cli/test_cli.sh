#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_cli.sh -- end-to-end checks of the `pendavg` command-line contract, as named
# cases (case_harness.sh: one ctest test cli.CASE each).
#
# Usage: test_cli.sh PATH/TO/pendavg CASE    (test_cli.sh --list: the cases)
# Bad input must exit 2 with exactly one stderr line "pendavg: error: ..." and nothing on stdout;
# good input must exit 0 with well-formed output. Prints "CASE: N passed, M failed" last and
# exits non-zero on any failure.
set -u

pendavg=${1:?usage: test_cli.sh PATH/TO/pendavg CASE, or test_cli.sh --list}
# shellcheck source=case_harness.sh
source "$(cd "$(dirname "$0")" && pwd)/case_harness.sh"
record_commands pendavg

# bad NAME ARGS... : expects exit 2, one stderr line "pendavg: error: ...", empty stdout.
bad() {
  local name=$1 expected="exit 2, nothing on stdout, one stderr line 'pendavg: error: ...'"
  shift
  run "$@"
  if [ "$rc" -ne 2 ]; then
    fail "$name" "$expected" "exit $rc"
  elif [ -s "$work/out" ]; then
    fail "$name" "$expected" "output on stdout"
  elif [ "$(wc -l <"$work/err")" -ne 1 ] || ! head -1 "$work/err" | grep -q '^pendavg: error: '; then
    fail "$name" "$expected" "$(wc -l <"$work/err") stderr lines"
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
    fail "$name" "exit 0" "exit $rc"
  elif grep -qv '^\[[a-z]*\] ' "$work/err"; then
    fail "$name" "nothing on stderr but progress lines" "other lines on stderr"
  elif ! eval "$check"; then
    fail "$name" "exit 0 and an output that passes: $check" "an output that does not (the check's message, if any, above)"
  else
    pass
  fi
}

# Schema 1 of the outputs (issue 27): schema1.py (written by cases_setup, below) reads them for
# the checks (run them with `py`); `data FILE` prints a CSV output's header and rows ('#' lines
# skipped) and `cols FILE NAME...` the named cells of each row, comma-joined (MISSING:NAME for a
# column the header does not have). cases_setup also writes the cases files several cases read.
cases_setup() {
cat >"$work/schema1.py" <<'PY'
"""Schema 1 of pendavg's outputs, for the checks of test_cli.sh."""
import csv
import json
from decimal import Decimal

KINDS = {"bound", "estimate", "statistical"}


class Number(Decimal):
    """A JSON number with a fraction or exponent: its value, and its text as printed (.text)."""

    def __new__(cls, text):
        self = Decimal.__new__(cls, text)
        self.text = text
        return self


def _refuse(token):
    raise ValueError("bare " + token)


def load(path):
    """The one JSON line of PATH: numbers kept exact (Number, int), a bare NaN/Infinity refused."""
    lines = open(path).read().splitlines()
    assert len(lines) == 1, "one JSON line"
    return json.loads(lines[0], parse_float=Number, parse_constant=_refuse)


def D(v):
    """The value of a JSON number (a double run) or of a decimal string (an MPFR run, a CSV cell)."""
    assert v is not None and not isinstance(v, bool) and v != "", repr(v)
    return v if isinstance(v, Decimal) else Decimal(v)


def text(v):
    """A JSON value as a CSV cell prints it."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, Number):
        return v.text
    return str(v)


def significant(s):
    return sum(c.isdigit() for c in s.lower().split("e")[0].lstrip("0.-"))


def real(v, digits, cell=False):
    """A real as a run at DIGITS prints it: in double a JSON number (CELL: a CSV cell's text)
    whose text is the shortest that round-trips (every digit of the double, exactly); in MPFR a
    decimal string of DIGITS significant digits. Returns its value."""
    if digits <= 16:
        if cell:
            assert isinstance(v, str), repr(v)
        else:
            assert isinstance(v, (Number, int)) and not isinstance(v, bool), repr(v)
        x = D(v)
        assert x == Decimal(repr(float(x))), ("not the shortest round trip of a double", v)
        return x
    assert isinstance(v, str) and significant(v) == digits, (v, digits)
    return D(v)


def has_prefix(v, prefix):
    """v lies in [prefix, prefix + one unit of its last digit): the digits of the old prefix checks."""
    p = Decimal(prefix)
    return p <= D(v) < p + Decimal(1).scaleb(p.as_tuple().exponent)


def per(stem, n):
    return ["%s%d" % (stem, i) for i in range(1, n + 1)]


def per_error(stem, n):
    return ["%s%d_error" % (stem, i) for i in range(1, n + 1)]


def with_errors(stem, n):
    """A per-particle quantity's CSV columns: X1..XN, X1_error..XN_error, X_error_kind."""
    return per(stem, n) + per_error(stem, n) + [stem + "_error_kind"]


def with_error(name):
    return [name, name + "_error", name + "_error_kind"]


def canonical_columns(n):
    """The canonical results' CSV columns (average, --cases, table, limit) after the inputs."""
    return (["method"] + with_errors("beta_K", n) + with_errors("K", n) + with_error("ratio") +
            with_errors("cos_phi", n) + with_errors("var_K", n) + with_errors("beta2_var_K", n) +
            with_errors("beta_Kc", n) + per("diagonal_approx", n) +
            ["equipartition_residual", "evaluations", "work_unit", "converged", "interrupted"])


def other_state(state):
    return {"energy": "excitation", "excitation": "energy"}[state]


def micro_columns(n, state):
    """The microcanonical results' CSV columns after the inputs (STATE: energy or excitation)."""
    return ([other_state(state), "ensemble", "method"] + with_errors("K", n) + with_error("Kc") +
            with_errors("cos_phi", n) + with_errors("var_K", n) + with_error("K_total") +
            with_error("density_of_states") +
            ["proposal_beta", "effective_sample_fraction", "evaluations", "work_unit", "converged"])


def header(kind, n, state="beta"):
    """The CSV header of KIND (average: one result; cases; table; limit) for N particles."""
    results = canonical_columns(n) if state == "beta" else micro_columns(n, state)
    inputs = [state, "g"] + per("m", n) + per("l", n)
    if kind == "average":
        return ["N", "digits"] + inputs + results + ["seconds"]
    if kind == "cases":
        return inputs + results
    if kind == "table":
        return ["N", "digits"] + inputs + results
    assert kind == "limit" and state == "beta"
    return ["limit", "N", "digits", "g"] + per("m", n) + per("l", n) + results + ["seconds"]


CANONICAL_JSON = (["method"] + with_error("beta_K") + with_error("K") + with_error("ratio") +
                  with_error("cos_phi") + with_error("var_K") + with_error("beta2_var_K") +
                  with_error("beta_Kc") + ["diagonal_approx", "equipartition_residual",
                                           "evaluations", "work_unit", "converged",
                                           "interrupted", "run"])
AVERAGE_JSON = ["schema", "command", "N", "digits", "beta", "g", "m", "l"] + CANONICAL_JSON + [
    "seconds"]
LIMIT_JSON = ["schema", "command", "N", "digits", "g", "m", "l", "high_temperature",
              "low_temperature", "seconds"]


def micro_json(state):
    return (["schema", "command", "N", "digits", state, "g", "m", "l", other_state(state),
             "ensemble", "method"] + with_error("K") + with_error("Kc") + with_error("cos_phi") +
            with_error("var_K") + with_error("K_total") + with_error("density_of_states") +
            ["proposal_beta", "effective_sample_fraction", "evaluations", "work_unit",
             "converged", "run", "seconds"])


def columns_of(obj):
    """A JSON object's values under their CSV column names (per-particle X[i] as X{i+1} and
    X_error[i] as X{i+1}_error); schema, command, run and the limits' objects left out."""
    out = {}
    for key, value in obj.items():
        if key in ("schema", "command", "run", "high_temperature", "low_temperature"):
            continue
        if isinstance(value, list):
            stem, suffix = (key[:-6], "_error") if key.endswith("_error") else (key, "")
            for i, v in enumerate(value):
                out["%s%d%s" % (stem, i + 1, suffix)] = v
        else:
            out[key] = value
    return out


def read_csv(path, text=None):
    """(comment lines, header, rows as dicts) of a CSV output; every row as long as the header."""
    lines = (open(path).read() if text is None else text).splitlines()
    comments = [l for l in lines if l.startswith("#")]
    data = [l for l in lines if not l.startswith("#")]
    assert data, "no CSV header"
    head = data[0].split(",")
    assert all(len(l.split(",")) == len(head) for l in data), "ragged rows"
    return comments, head, list(csv.DictReader(data))
PY
# the cases files (bad ones, then the shuffled N = 2 and N = 3 files, energy and excitation)
printf 'beta,g,m1,m2,l1\n1,1,0.5,0.5,1\n' >"$work/missing_column.csv"
printf 'beta,g,m1,m2,l1,l2,T\n1,1,0.5,0.5,1,1,3\n' >"$work/extra_column.csv"
printf 'm1,m2,l1,l2,g,beta\n0.5,0.5,1,1,1,1\n0.5,0.5,1,1,1,-2\n' >"$work/bad_row.csv"
printf 'm1,m2,l1,l2,g,beta\n0.5,0.5,1,1\n' >"$work/short_row.csv"
printf '# shuffled columns\nl2,m1,beta,g,l1,m2\n\n1,0.5,1,1,1,0.5\n1,0.2,10,1,1,0.8\n# comment\n2,1,0.1,9.81,1,3\n' >"$work/cases.csv"
printf 'l3,m2,beta,l1,g,m3,m1,l2\n1,1,1,1,1,1,1,1\n2,1,0.5,1,9.81,3,2,1\n' >"$work/cases3.csv"
touch "$work/plain_file"  # (a directory that is a file: --output refused)
printf 'm2,energy,g,m1,l1,l2\n1,-1,1,1,1,1\n1,-2.99999999,1,1,1,1\n0.5,5,9.81,0.5,1,2\n' >"$work/energy.csv"
printf 'excitation,g,m1,m2,l1,l2\n1e-8,1,1,1,1,1\n' >"$work/excitation.csv"
# strict_json.py: JSON without a bare NaN/Infinity (the checks of the issue 10 keys)
cat >"$work/strict_json.py" <<'PY'
import json
def strict(path):
    def refuse(token):
        raise ValueError("bare " + token)
    return json.loads(open(path).read(), parse_constant=refuse)
KINDS = {"bound", "estimate", "statistical"}
PY
}
py() { PYTHONPATH="$work" "$python" "$@"; }
data() { grep -v '^#' "$1"; }
cols() { # FILE NAME...
  local file=$1
  shift
  awk -F, -v names="$*" '
    BEGIN { n = split(names, want, " ") }
    /^#/ { next }
    !seen { for (i = 1; i <= NF; ++i) at[$i] = i; seen = 1; next }
    { line = ""
      for (j = 1; j <= n; ++j) line = line (j > 1 ? "," : "") (want[j] in at ? $(at[want[j]]) : "MISSING:" want[j])
      print line }' "$file"
}

pendulum=(--masses 0.5,0.5 --lengths 1,1)
unit3=(--masses 1,1,1 --lengths 1,1,1 --g 1)
# unit3_reference: $work/unit3.json, the unit 3-link chain at beta = 1 (average.any_n checks it)
unit3_reference() { "$pendavg" average "${unit3[@]}" --beta 1 --format json >"$work/unit3.json"; }

# ---------------------------------------------------------------- bad input
case:input.refusals() {
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
}

# the any-N options: malformed values, and options of a method that does not run
case:average.option_refusals() {
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
}

case:cases.refusals() {
bad "cases file missing"     average --cases "$work/no_such_file.csv"
bad "cases missing column"   average --cases "$work/missing_column.csv"
bad "cases extra column"     average --cases "$work/extra_column.csv"
bad "cases bad row"          average --cases "$work/bad_row.csv"
expect "cases bad row: stderr names line 3" 'grep -q "line 3" "$work/err"'
bad "cases short row"        average --cases "$work/short_row.csv"
bad "cases with --beta"      average --cases "$work/bad_row.csv" --beta 1
bad "cases is a directory"   average --cases "$work"
printf 'm1,m2,l1,l2,g,beta\n0.5,0.5,1,1,1,1\n' >"$work/one_row.csv"
bad "cases --format xml"     average --cases "$work/one_row.csv" --format xml
expect "cases --format xml: stderr names the formats" 'grep -q "json" "$work/err"'
}

# ---------------------------------------------------------------- good input
# average --format json: one line, schema 1's keys in their order, reals as JSON numbers with every
# digit of the double (shortest round trip) or, in MPFR, decimal strings of --digits digits.
check_average_json() { # DIGITS
  py - "$1" "$work/out" <<'PY'
import sys
from schema1 import load, real, D, AVERAGE_JSON, KINDS
digits = int(sys.argv[1])
o = load(sys.argv[2])
assert list(o) == AVERAGE_JSON, list(o)
assert o["schema"] == 1 and o["command"] == "average", o
assert o["N"] == 2 and o["digits"] == digits and isinstance(o["converged"], bool)
assert o["interrupted"] is False and o["beta_K_error_kind"] in KINDS, o
for k in ("beta_K", "K", "beta_K_error", "cos_phi", "var_K", "m", "l"):
    assert isinstance(o[k], list) and len(o[k]) == 2, k
for k in ("beta_K", "K", "cos_phi", "var_K", "beta2_var_K", "beta_Kc", "diagonal_approx"):
    for v in o[k]:
        real(v, digits)
real(o["ratio"], digits)
assert abs(D(o["beta_K"][0]) + D(o["beta_K"][1]) - 1) < D("1e-12"), "beta<K1> + beta<K2> = 1"
PY
}
# CSV: '# schema: 1', '# pendavg average', the header, one row as long as the header.
check_average_csv() { # N [STATE]
  py - "$work/out" "$1" "${2:-beta}" <<'PY'
import sys
from schema1 import read_csv, header
comments, head, rows = read_csv(sys.argv[1])
assert comments == ["# schema: 1", "# pendavg average"], comments
assert open(sys.argv[1]).read().splitlines()[:2] == comments, "the '#' lines come first"
assert head == header("average", int(sys.argv[2]), sys.argv[3]), head
assert len(rows) == 1, len(rows)
PY
}
# csv is every command's default format: the same output as --format csv, but for the run time
strip_csv_seconds() { sed 's/,[^,]*$//' "$1"; }
case:average.formats() {
good "average json"          'check_average_json 16' average "${pendulum[@]}" --beta 1 --format json
good "average json, digits 30" 'check_average_json 30' average "${pendulum[@]}" --beta 0.1 --digits 30 --format json
good "average series json"   'check_average_json 16' average "${pendulum[@]}" --beta 1 --method series --format json
good "average csv"           'check_average_csv 2' average "${pendulum[@]}" --beta 1 --format csv
run average "${pendulum[@]}" --beta 1 --format csv
cp "$work/out" "$work/average_csv.csv"
good "average: csv by default" \
  '[ "$(strip_csv_seconds "$work/out")" = "$(strip_csv_seconds "$work/average_csv.csv")" ]' \
  average "${pendulum[@]}" --beta 1
run limit --masses 0.5,0.5 --format csv
cp "$work/out" "$work/limit_csv.csv"
good "limit: csv by default" \
  '[ "$(strip_csv_seconds "$work/out")" = "$(strip_csv_seconds "$work/limit_csv.csv")" ]' \
  limit --masses 0.5,0.5
good "average text"          'grep -Eq "^i +beta_K +beta_K_error " "$work/out"' average "${pendulum[@]}" --beta 1 --format text
}

# The canonical CSV header of schema 1: the inputs, then the results.
canonical_header() { # KIND (average | cases | table | limit) N [STATE]
  py -c 'import sys, schema1; print(",".join(schema1.header(sys.argv[1], int(sys.argv[2]), sys.argv[3])))' \
    "$1" "$2" "${3:-beta}"
}

# Every --cases column equals `average --format csv` of the same point: var_K is Var K_i (not
# beta^2 Var K_i) and each error and kind as printed there; in double and in MPFR.
check_cases_as_average() { # DIGITS
  "$pendavg" average --cases "$work/cases.csv" --digits "$1" >"$work/cases_cmp.csv" 2>/dev/null || return 1
  py - "$pendavg" "$work/cases_cmp.csv" "$1" <<'PY'
import subprocess, sys
from schema1 import read_csv
pendavg, path, digits = sys.argv[1], sys.argv[2], sys.argv[3]
_, _, rows = read_csv(path)
assert len(rows) == 3
for row in rows:
    args = [pendavg, "average", "--masses", row["m1"] + "," + row["m2"], "--lengths",
            row["l1"] + "," + row["l2"], "--g", row["g"], "--beta", row["beta"],
            "--digits", digits, "--format", "csv"]
    single = read_csv(None, subprocess.run(args, capture_output=True, text=True,
                                           check=True).stdout)[2][0]
    for key in ("beta_K1", "beta_K2", "beta_K1_error", "var_K1", "var_K2", "var_K1_error",
                "var_K2_error", "cos_phi1", "cos_phi2_error", "ratio", "ratio_error", "method",
                "beta2_var_K1", "beta2_var_K2_error", "K_error_kind", "interrupted"):
        assert row[key] == single[key], (key, row[key], single[key])
PY
}
case:cases.shuffled() {
cases_header=$(canonical_header cases 2)
good "cases shuffled" \
  '[ "$(head -1 "$work/out")" = "# schema: 1" ] && [ "$(data "$work/out" | wc -l)" -eq 4 ] &&
   [ "$(data "$work/out" | head -1)" = "$cases_header" ] && [ "$(data "$work/out" | sed -n 3p | cut -d, -f1-6)" = "10,1,0.2,0.8,1,1" ]' \
  average --cases "$work/cases.csv"
good "cases shuffled, digits 20" '[ "$(data "$work/out" | wc -l)" -eq 4 ]' \
  average --cases "$work/cases.csv" --digits 20
check "cases columns = average --format csv (double)" check_cases_as_average 16
check "cases columns = average --format csv (MPFR)" check_cases_as_average 25
}

# --columns LIST: the listed output columns (names or per-particle stems), in that order, each
# with the same text as in the full output; the input columns stay in front. Bad lists exit 2.
# The names of schema 0 are still taken, printed under their old names (error_K2: the column
# beta_K2_error).
check_columns() { # DIGITS LIST EXPECTED-NAMES(comma separated)
  "$pendavg" average --cases "$work/cases.csv" --digits "$1" >"$work/cols_all.csv" 2>/dev/null &&
    "$pendavg" average --cases "$work/cases.csv" --digits "$1" --columns "$2" >"$work/cols_some.csv" 2>/dev/null &&
    py - "$work/cols_all.csv" "$work/cols_some.csv" "$3" <<'PY'
import csv, re, sys
from schema1 import read_csv
full_comments, full_head, _ = read_csv(sys.argv[1])
some_comments, some_head, _ = read_csv(sys.argv[2])
assert some_comments == full_comments == ["# schema: 1"], (some_comments, full_comments)
full = [r for r in csv.reader(open(sys.argv[1])) if not r[0].startswith("#")]
some = [r for r in csv.reader(open(sys.argv[2])) if not r[0].startswith("#")]
expected = ["beta", "g", "m1", "m2", "l1", "l2"] + sys.argv[3].split(",")
assert some[0] == expected, (some[0], expected)
assert len(some) == len(full) == 4
def schema1_name(name):  # error_K2, K_error2, cos_phi_error2, ... -> beta_K2_error, K2_error, ...
    m = re.fullmatch(r"error_K(\d+)", name)
    if m:
        return "beta_K%s_error" % m.group(1)
    m = re.fullmatch(r"(K|cos_phi|var_K|beta_Kc)_error(\d+)", name)
    if m:
        return "%s%s_error" % m.groups()
    return {"error_kind": "beta_K_error_kind"}.get(name, name)
for a, b in zip(full[1:], some[1:]):
    row = dict(zip(full[0], a))
    assert b == [row[schema1_name(name)] for name in expected], (a, b)
PY
}
case:cases.columns() {
check "cases --columns: the original seven numbers" check_columns 16 beta_K,error_K,ratio,cos_phi,method,evaluations \
  beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,method,evaluations
check "cases --columns: the original seven numbers, schema 1's names" check_columns 16 beta_K,beta_K_error,ratio,cos_phi,method,evaluations \
  beta_K1,beta_K2,beta_K1_error,beta_K2_error,ratio,cos_phi1,cos_phi2,method,evaluations
check "cases --columns: any order, variance errors before values" check_columns 16 var_K_error2,var_K1,beta_Kc_error_kind,converged,var_K_error1 \
  var_K_error2,var_K1,beta_Kc_error_kind,converged,var_K_error1
check "cases --columns: any order, schema 1's names" check_columns 16 var_K2_error,var_K1,beta_Kc_error_kind,converged,var_K1_error,beta2_var_K2,interrupted \
  var_K2_error,var_K1,beta_Kc_error_kind,converged,var_K1_error,beta2_var_K2,interrupted
check "cases --columns at 25 digits" check_columns 25 cos_phi_error,ratio_error,equipartition_residual,work_unit \
  cos_phi1_error,cos_phi2_error,ratio_error,equipartition_residual,work_unit
bad "cases --columns unknown"          average --cases "$work/cases.csv" --columns beta_K,foo
check "cases --columns unknown: message" grep -q "unknown column 'foo'" "$work/err"
bad "cases --columns twice selected"   average --cases "$work/cases.csv" --columns cos_phi,cos_phi2
bad "cases --columns empty"            average --cases "$work/cases.csv" --columns ""
bad "cases --columns empty item"       average --cases "$work/cases.csv" --columns beta_K,,ratio
bad "cases --columns beyond N"         average --cases "$work/cases.csv" --columns beta_K3
bad "cases --columns input column"     average --cases "$work/cases.csv" --columns beta
bad "--columns without --cases"        average "${pendulum[@]}" --beta 1 --columns beta_K
printf 'excitation,g,m1,m2,l1,l2\n1,1,1,1,1,1\n' >"$work/micro_cases.csv"
good "cases --columns, microcanonical" \
  '[ "$(data "$work/out" | head -1)" = "excitation,g,m1,m2,l1,l2,K2,density_of_states,energy" ] && [ "$(data "$work/out" | tail -1 | tr , "\n" | wc -l)" -eq 9 ]' \
  average --cases "$work/micro_cases.csv" --columns K2,density_of_states,energy
}

# --cases --timing: stdout unchanged, one summary line on stderr (its presence and format, not
# its numbers); --timing-rows FILE: one CSV line per row with its file line. Bad uses exit 2.
check_timing() { # ARGS...: stdout as in $work/cases_out.csv, stderr one summary line
  run average --cases "$work/cases.csv" "$@"
  [ "$rc" -eq 0 ] && cmp -s "$work/out" "$work/cases_out.csv" &&
    [ "$(wc -l <"$work/err")" -eq 1 ] && grep -Eq "$timing_line" "$work/err"
}
case:cases.timing() {
run average --cases "$work/cases.csv"
cp "$work/out" "$work/cases_out.csv"
timing_line='^pendavg: timing: rows=3 median_us=[0-9]+\.[0-9]{3} p90_us=[0-9]+\.[0-9]{3} worst_us=[0-9]+\.[0-9]{3} worst_row=[0-2] worst_line=(4|5|7) threads=[1-9][0-9]* timer_us=[0-9]+\.[0-9]{3} \(thread CPU time per row, row to formatted line, timer overhead subtracted\)$'
check "cases --timing: stdout and the stderr summary line" check_timing --timing
check "cases --timing-rows: stdout and the stderr summary line" check_timing --timing-rows "$work/rows.csv"
check "cases --timing-rows: file" "$python" - "$work/rows.csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert [r["row"] for r in rows] == ["0", "1", "2"], rows
assert [r["line"] for r in rows] == ["4", "5", "7"], rows  # data lines of the shuffled file
float(rows[0]["us"])
PY
run average --cases "$work/cases.csv" --digits 20
cp "$work/out" "$work/cases_out.csv"
check "cases --timing --digits 20" check_timing --timing --digits 20
bad "cases --timing without --cases"   average "${pendulum[@]}" --beta 1 --timing
bad "cases --timing-rows without --cases" average "${pendulum[@]}" --beta 1 --timing-rows "$work/r.csv"
bad "cases --timing=1"                 average --cases "$work/cases.csv" --timing=1
bad "cases --timing twice"             average --cases "$work/cases.csv" --timing --timing
bad "cases --timing-rows unwritable"   average --cases "$work/cases.csv" --timing-rows /nonexistent/rows.csv
bad "cases --timing, bad row"          average --cases "$work/bad_row.csv" --timing
expect "cases --timing, bad row: stderr names line 3" 'grep -q "line 3" "$work/err"'
}

# Rows run in blocks of 256 on all cores: 600 rows give the same bytes on 1 and 2 threads.
case:cases.threads() {
"$python" - "$work/many.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for i in range(600):
        f.write(f"{10 ** (i % 9 - 4)},{1 + i % 3},{0.5 + i % 7},{1e-3 * (1 + i % 11)},1,{2 ** (i % 13 - 6)}\n")
PY
OMP_NUM_THREADS=1 "$pendavg" average --cases "$work/many.csv" >"$work/many1.csv" 2>/dev/null
OMP_NUM_THREADS=2 "$pendavg" average --cases "$work/many.csv" >"$work/many2.csv" 2>/dev/null
expect "cases 600 rows: 1 and 2 threads give the same bytes" \
  '[ "$(data "$work/many1.csv" | wc -l)" -eq 601 ] && cmp -s "$work/many1.csv" "$work/many2.csv"'
}

# ---------------------------------------------------------------- any N
check_any_n_json() { # N
  py - "$1" "$work/out" <<'PY'
import sys
from schema1 import load, D, real, AVERAGE_JSON, KINDS
n = int(sys.argv[1])
o = load(sys.argv[2])
assert list(o) == AVERAGE_JSON, list(o)
assert o["beta_K_error_kind"] in KINDS, o["beta_K_error_kind"]
for k in ("K_error", "cos_phi_error", "var_K_error", "beta2_var_K_error"):
    assert isinstance(o[k], list) and len(o[k]) == n and all(D(e) >= 0 for e in o[k]), k
assert (o["ratio_error"] is None) == (n == 1), o["ratio_error"]
# every error's kind (none for the ratio of a single particle); beta<K_i^c> = 1/2 is exact
for q in ("beta_K", "K", "ratio", "cos_phi", "var_K", "beta2_var_K", "beta_Kc"):
    kind = o[q + "_error_kind"]
    assert kind in KINDS or (q == "ratio" and n == 1 and kind is None), (q, kind)
assert o["beta_Kc_error_kind"] == "bound", o
assert o["N"] == n and o["converged"] is True and o["interrupted"] is False
for k in ("beta_K", "K", "beta_K_error", "cos_phi", "var_K", "beta2_var_K", "diagonal_approx",
          "beta_Kc", "beta_Kc_error", "m", "l"):
    assert isinstance(o[k], list) and len(o[k]) == n, k
assert all(D(v) == D("0.5") for v in o["beta_Kc"]), o["beta_Kc"]
for k in ("beta_K", "K", "cos_phi", "var_K", "beta2_var_K", "beta_Kc", "diagonal_approx"):
    for v in o[k]:
        real(v, o["digits"])  # JSON numbers (every digit of the double) or MPFR strings
assert abs(sum(map(D, o["beta_K"])) - D(n) / 2) < D("1e-12"), "sum_i beta<K_i> = N/2"
PY
}
# beta<K_i> of the unit 3-link chain at g = beta = 1 (published reference values)
check_unit3() {
  check_any_n_json 3 && py - "$work/out" <<'PY'
import sys
from schema1 import load, has_prefix
o = load(sys.argv[1])
assert o["method"] == "torus-trapezoid", o["method"]
for value, prefix in zip(o["beta_K"], ("0.32908723613784", "0.48318092191398", "0.6877318419481")):
    assert has_prefix(value, prefix), (value, prefix)
assert has_prefix(o["ratio"], "0.681084912943"), o["ratio"]
PY
}
# text: the per-particle table of the results (its header ends with diagonal_approx), one row per particle
text_rows() { awk '/^i .*diagonal_approx$/ { on = 1; next } on && /^ *[0-9]+  / { ++rows; next } { on = 0 } END { print rows + 0 }' "$1"; }
case:average.any_n() {
good "N = 3 unit chain"      check_unit3 average "${unit3[@]}" --beta 1 --format json
# 1/6 to the 16 digits the old check read (1.666666666666667e-01)
good "N = 3 diagonal approx" \
  'check_any_n_json 3 && py -c "import sys; from schema1 import *; o = load(sys.argv[1]); assert round(D(o[\"diagonal_approx\"][0]), 16) == D(\"0.1666666666666667\"), o" "$work/out"' \
  average "${unit3[@]}" --beta 0.1 --format json
good "N = 3 torus-gauss, digits 20" \
  'py -c "import sys; from schema1 import *; o = load(sys.argv[1]); assert o[\"method\"] == \"torus-gauss\" and real(o[\"beta_K\"][0], 20) and o[\"beta_K\"][0].startswith(\"3.29087236137842418\"), o" "$work/out"' \
  average "${unit3[@]}" --beta 1 --method torus-gauss --digits 20 --format json
good "N = 1"                 \
  'check_any_n_json 1 && py -c "import sys; from schema1 import *; o = load(sys.argv[1]); assert o[\"ratio\"] is None and o[\"beta_K\"] == [D(\"0.5\")] and isinstance(o[\"beta_K\"][0], Number), o" "$work/out"' \
  average --masses 2 --lengths 3 --beta 0.7 --format json
good "N = 4 csv"             'check_average_csv 4' \
  average --masses 1,2,3,4 --lengths 1,1,1,1 --beta 1 --format csv
good "N = 3 text"            '[ "$(text_rows "$work/out")" -eq 3 ]' \
  average "${unit3[@]}" --beta 1 --format text
good "N = 2 json extras"     'check_any_n_json 2' average "${pendulum[@]}" --beta 1 --format json
}

# The any-N engines against the N = 2 engine: torus rules to 1e-12 relative, qmc within its bar.
check_agree() { # REFERENCE CANDIDATE TOLERANCE ("bar": within the candidate's error bars)
  py - "$1" "$work/out" "$2" <<'PY'
import sys
from decimal import Decimal
from schema1 import load, D
a, b = (load(path) for path in sys.argv[1:3])
tolerance = sys.argv[3]
assert a["N"] == b["N"] == 2 and a["method"] != b["method"], (a["method"], b["method"])
for key in ("beta_K", "cos_phi", "var_K"):
    for i, (x, y) in enumerate(zip(map(D, a[key]), map(D, b[key]))):
        if tolerance == "bar" and key == "beta_K":
            assert abs(x - y) <= D(b["beta_K_error"][i]), (key, x, y, b["beta_K_error"][i])
        elif tolerance != "bar":
            assert abs(x - y) <= Decimal(tolerance) * abs(x), (key, x, y)
PY
}
case:average.engines_agree() {
for params in "0.5,0.5 1,1 1 1" "0.2,0.8 1,2 10 9.81" "3,0.01 2,0.5 0.05 1"; do
  read -r m l b g <<<"$params"
  run average --masses "$m" --lengths "$l" --beta "$b" --g "$g" --format json
  cp "$work/out" "$work/reference.json"
  for method in torus-trapezoid torus-gauss; do
    good "N = 2 $method vs default ($params)" 'check_agree "$work/reference.json" 1e-12' \
      average --masses "$m" --lengths "$l" --beta "$b" --g "$g" --method "$method" --format json
  done
  good "N = 2 qmc vs default ($params)" 'check_agree "$work/reference.json" bar' \
    average --masses "$m" --lengths "$l" --beta "$b" --g "$g" --method qmc --samples 4096 --format json
done
}

# qmc: deterministic for a seed (all but the wall time), and its bars cover the exact values.
strip_seconds() { sed 's/"seconds": [^,}]*//' "$1"; }
case:average.qmc_seeds() {
unit3_reference  # (qmc N = 3 covers exact)
run average "${unit3[@]}" --beta 1 --method qmc --seed 12345 --samples 4096 --format json
cp "$work/out" "$work/qmc1.json"
good "qmc N = 3 deterministic" '[ "$(strip_seconds "$work/out")" = "$(strip_seconds "$work/qmc1.json")" ]' \
  average "${unit3[@]}" --beta 1 --method qmc --seed 12345 --samples 4096 --format json
good "qmc N = 3 covers exact" 'py -c "
import sys
from schema1 import load, D
q, exact = load(sys.argv[1]), load(sys.argv[2])
assert q[\"method\"] == \"qmc\" and q[\"evaluations\"] == 4096 * 16, q
for x, y, e in zip(map(D, q[\"beta_K\"]), map(D, exact[\"beta_K\"]), map(D, q[\"beta_K_error\"])):
    assert abs(x - y) <= e and e < D(\"1e-5\"), (x, y, e)
" "$work/out" "$work/unit3.json"' \
  average "${unit3[@]}" --beta 1 --method qmc --seed 12345 --samples 4096 --format json
good "qmc N = 3 other seed differs" '[ "$(strip_seconds "$work/out")" != "$(strip_seconds "$work/qmc1.json")" ]' \
  average "${unit3[@]}" --beta 1 --method qmc --seed 12346 --samples 4096 --shifts 8 --format json
}

# --cases with N = 3 columns in any order: canonical input columns, then N = 3 results that
# match the single-case command.
check_cases3() {
  [ "$(data "$work/out" | wc -l)" -eq 3 ] && [ "$(data "$work/out" | head -1)" = "$cases3_header" ] &&
    [ "$(data "$work/out" | sed -n 3p | cut -d, -f1-8)" = "0.5,9.81,2,1,3,1,1,2" ] &&
    py - "$work/out" "$work/unit3.json" <<'PY'
import sys
from schema1 import load, read_csv, text
rows = read_csv(sys.argv[1])[2]
exact = load(sys.argv[2])
assert rows[0]["method"] == "torus-trapezoid", rows[0]
assert [rows[0]["beta_K%d" % i] for i in (1, 2, 3)] == [text(v) for v in exact["beta_K"]], rows[0]
assert rows[0]["ratio"] == text(exact["ratio"])
PY
}
case:cases.any_n() {
unit3_reference  # (cases N = 3 shuffled)
cases3_header=$(canonical_header cases 3)
good "cases N = 3 shuffled"  check_cases3 average --cases "$work/cases3.csv"
good "cases N = 3 qmc"       '[ "$(data "$work/out" | wc -l)" -eq 3 ] && [ "$(cols "$work/out" method | head -1)" = qmc ]' \
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
expect "cases N = 3 bad row: stderr names line 3, m3" 'grep -q "line 3: m3" "$work/err"'
}

check_limit() { # DIGITS
  py - "$work/out" "$1" <<'PY'
import sys
from schema1 import load, real, has_prefix, LIMIT_JSON, CANONICAL_JSON
o, digits = load(sys.argv[1]), int(sys.argv[2])
assert list(o) == LIMIT_JSON and o["command"] == "limit", list(o)
for part in ("high_temperature", "low_temperature"):
    assert list(o[part]) == CANONICAL_JSON, list(o[part])
    assert o[part]["beta_K_error_kind"] == "bound", o[part]
value = real(o["high_temperature"]["beta_K"][0], digits)
assert has_prefix(value, "0.3431834814709"), value
PY
}
check_limit_any() { # N: beta -> 0 sums to N/2; beta -> infinity is 1/2 each
  py - "$work/out" "$1" <<'PY'
import sys
from decimal import Decimal
from schema1 import load, D
d = load(sys.argv[1]); n = int(sys.argv[2])
h, l = d["high_temperature"], d["low_temperature"]
assert d["N"] == n and len(h["beta_K"]) == n
total = sum(D(x) for x in h["beta_K"]); bars = sum(D(x) for x in h["beta_K_error"])
assert abs(total - Decimal(n) / 2) <= bars + Decimal("1e-13"), (total, bars)
assert all(D(x) == Decimal("0.5") for x in l["beta_K"])
PY
}
case:limit.values() {
good "limit paper value"     'check_limit 16' limit --masses 0.5,0.5 --format json
good "limit paper value, digits 40" 'check_limit 40' limit --masses 0.5,0.5 --digits 40 --format json
good "limit text"            '[ -s "$work/out" ]' limit --masses 0.5,0.5 --format text
good "limit N = 3"             'check_limit_any 3' limit --masses 1,2,0.5 --lengths 1,0.5,2 --format json
good "limit N = 7 (transfer)"  'check_limit_any 7' limit --masses 1,1,1,1,1,1,1 --format json
bad "limit N = 6 at 20 digits" limit --masses 1,1,1,1,1,1 --digits 20
}

# text reports: `name = value` of the scalars, comma separated on one line (count_scalar FILE
# NAME VALUE: how many lines hold it)
count_scalar() { grep -Ec "(^|, )$2 = $3(,|\$)" "$1"; }

# series: the run, then one row per term (text: a table under the field names)
case:series.output() {
good "series 5 terms text" \
  '[ "$(awk "/^n /{t=1; next} /^seconds = /{t=0} t" "$work/out" | grep -c "^ *[0-9]")" -eq 5 ] && [ "$(count_scalar "$work/out" terms 5)" -eq 1 ]' \
  series "${pendulum[@]}" --beta 1 --terms 5 --format text
good "series 5 terms csv" \
  '[ "$(head -2 "$work/out")" = "$(printf "# schema: 1\n# pendavg series")" ] && [ "$(grep -vc "^#" "$work/out")" -eq 6 ]' \
  series "${pendulum[@]}" --beta 1 --terms 5
}

# table: a small sweep's rows (every combination, in a fixed order) and its '#' header.
check_table() {
  "$python" -c '
import csv, sys
lines = open(sys.argv[1]).read().splitlines()
comments = [l for l in lines if l.startswith("#")]
data = [l for l in lines if not l.startswith("#")]
assert lines[0] == "# schema: 1" and lines[1].startswith("# pendavg table"), lines[:2]
assert all(not l.startswith("#") for l in lines[len(comments):]), "comments after data"
text = "\n".join(comments)
for needle in ("beta = log:1e-3:1e3:7", "mu1 = 0.05,0.95", "l2 = 0.5,2", "method = auto", "digits = 16", ", generated ", "UTC"):
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
case:table.basics() {
table_header=$(canonical_header table 2)
good "table sweep to stdout"  'check_table "$work/out"' \
  table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2
good "table sweep to file"    '[ ! -s "$work/out" ] && check_table "$work/table.csv" && [ -z "$(ls "$work" | grep tmp)" ]' \
  table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2 --output "$work/table.csv"
good "table l2 range innermost" \
  '[ "$(cols "$work/out" beta l2 | tr "\n" " ")" = "1,0.1 1,1 1,10 2,0.1 2,1 2,10 " ]' \
  table --beta 1,2 --l2 log:0.1:10:3
good "table same with 1 thread" \
  'OMP_NUM_THREADS=1 "$pendavg" table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2 | grep -v generated >"$work/t1" &&
   grep -v generated "$work/out" | cmp -s - "$work/t1"' \
  table --beta log:1e-3:1e3:7 --mu1 0.05,0.95 --l2 0.5,2
good "table digits 30"        '[ "$(cols "$work/out" beta_K1 | wc -c)" -eq 36 ] && py -c "import sys; from schema1 import *; assert real(read_csv(sys.argv[1])[2][0][\"beta_K1\"], 30)" "$work/out"' \
  table --beta 1 --mu1 1e-4 --digits 30
good "table chain 3"          '[ "$(grep -v "^#" "$work/out" | wc -l)" -eq 3 ] && grep -q "diagonal_approx3" "$work/out"' \
  table --chain 3 --beta 0.1,1
}
case:table.refusals() {
bad "table unwritable dir"    table --beta 1 --output "$work/plain_file/t.csv"
expect "table unwritable dir: no file left" '[ -f "$work/plain_file" ] && [ -z "$(ls "$work" | grep tmp)" ]'
bad "table missing dir"       table --beta 1 --output "$work/no/such/dir/t.csv"
bad "table output is a dir"   table --beta 1 --output "$work"
bad "table bad point"         table --beta 1 --l2 0 --output "$work/bad.csv"
expect "table bad point: no file left" '[ ! -e "$work/bad.csv" ] && [ -z "$(ls "$work" | grep "bad.csv")" ]'
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
}
case:table.methods() {
good "table chain torus-gauss" 'grep -q "^3,16," "$work/out"' table --chain 3 --beta 1 --method torus-gauss --tol 1e-8
good "table pendulum torus"   'grep -q "^2,16," "$work/out"' table --beta 1 --method torus-trapezoid --tol 1e-10
# Microcanonical qmc runs as far as its lattices go (N <= 256), from the CLI as from the library.
good "micro qmc N = 40"       '"$python" -c "import json,sys; o=json.load(open(sys.argv[1])); assert o[\"N\"] == 40 and len(o[\"K\"]) == 40" "$work/out"' \
  average --masses "$(printf '1%.0s,' {1..39})1" --lengths "$(printf '1%.0s,' {1..39})1" --energy 0 --samples 1024 --shifts 8 --format json
good "table --help"           'grep -q "usage" "$work/out"' table --help
}

# table: lists of N, digits and g (issue 5). check_mixed_table FILE: a table of chains N = 3 and
# 5 at digits 16 and 20 (N = 5 runs transfer: digits 16 only) and g = 1, 2, with the mixed-N
# layout.
check_mixed_table() {
  py - "$1" <<'PY'
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
assert lines[0] == "# schema: 1", lines[0]
from schema1 import read_csv, header as schema1_header, real
_, header, rows = read_csv(sys.argv[1])  # (no ragged rows)
assert header == schema1_header("table", 5), header
assert [(r["N"], r["digits"], r["g"]) for r in rows] == [
    ("3", "16", "1"), ("3", "16", "2"), ("3", "20", "1"), ("3", "20", "2"),
    ("5", "16", "1"), ("5", "16", "2")], [(r["N"], r["digits"], r["g"]) for r in rows]
for r in rows:
    n = int(r["N"])
    assert r["method"] == ("torus-trapezoid" if n == 3 else "transfer") and r["converged"] == "true", r
    for stem in ("m", "l", "beta_K", "beta_K_error", "K", "K_error", "cos_phi", "cos_phi_error",
                 "var_K", "var_K_error", "beta2_var_K", "beta2_var_K_error", "diagonal_approx",
                 "beta_Kc", "beta_Kc_error"):
        names = [stem.replace("_error", f"{i}_error") if stem.endswith("_error") else f"{stem}{i}"
                 for i in range(1, 6)]
        cells = [r[name] for name in names]
        assert all(cells[:n]) and not any(cells[n:]), (stem, cells)
    # beta<K_i> as printed at the row's digits (every digit of the double, or --digits digits in
    # MPFR); equipartition sum = N/2.
    real(r["beta_K1"], int(r["digits"]), cell=True)
    total = sum(D(r[f"beta_K{i}"]) for i in range(1, n + 1))
    bound = sum(D(r[f"beta_K{i}_error"]) for i in range(1, n + 1))
    assert abs(total - D(n) / 2) <= bound, (total, bound)
# The 20-digit rows agree with the 16-digit rows within the 16-digit error bars.
for lo, hi in ((rows[0], rows[2]), (rows[1], rows[3])):
    for i in range(1, 4):
        assert abs(D(lo[f"beta_K{i}"]) - D(hi[f"beta_K{i}"])) <= D(lo[f"beta_K{i}_error"]) + D(hi[f"beta_K{i}_error"]), i
        assert D(hi[f"beta_K{i}_error"]) < D("1e-18"), hi[f"beta_K{i}_error"]
PY
}
case:table.lists() {
mixed_table=(table --chain 3,5 --beta 0.5 --g 1,2 --digits 16,20)
good "table lists of N, digits, g"   'check_mixed_table "$work/out"' "${mixed_table[@]}"
good "table mixed N to file"         '[ ! -s "$work/out" ] && check_mixed_table "$work/mixed.csv" && [ -z "$(ls "$work" | grep tmp)" ]' \
  "${mixed_table[@]}" --output "$work/mixed.csv"
good "table mixed N with 1 thread" \
  'OMP_NUM_THREADS=1 "$pendavg" "${mixed_table[@]}" | grep -v generated >"$work/t1" &&
   grep -v generated "$work/out" | cmp -s - "$work/t1"' "${mixed_table[@]}"
}

# beta<K_i>, <cos phi_i>, <K1>/<K2> and beta^2 Var K_i depend on beta and g only through beta g
# (fixed masses and lengths): the row beta = 2, g = 1 equals the row beta = 1, g = 2 to
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
        va, vb = D(a[f"beta2_var_K{i}"]), D(b[f"beta2_var_K{i}"])
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
            assert abs(D(r[f"beta_K{i}"]) - D(hi[f"beta_K{i}"])) <= D(r[f"beta_K{i}_error"]), (key, i)
PY
}
check_chain_beta_g() { # FILE: chain N = 3 by the torus, beta = 2, g = 1 vs beta = 1, g = 2
  "$python" - "$1" <<'PY'
import csv, sys
rows = list(csv.DictReader(l for l in open(sys.argv[1]) if not l.startswith("#")))
at = {(r["g"], r["beta"]): r for r in rows}
a, b = at[("1", "2")], at[("2", "1")]
for i in (1, 2, 3):
    err = float(a[f"beta_K{i}_error"]) + float(b[f"beta_K{i}_error"])
    assert abs(float(a[f"beta_K{i}"]) - float(b[f"beta_K{i}"])) <= err, i
    assert abs(float(a[f"cos_phi{i}"]) - float(b[f"cos_phi{i}"])) <= 1e-12, i
PY
}
case:table.beta_g() {
good "table beta g scaling"          'check_beta_g "$work/out"' \
  table --beta 1,2 --g 0,1,2 --digits 16,30 --mu1 0.3 --l1 1.5 --l2 0.7
good "table chain beta g scaling"    'check_chain_beta_g "$work/out"' \
  table --chain 3 --beta 1,2 --g 1,2
good "table g range innermost" \
  '[ "$(cols "$work/out" beta g | tr "\n" " ")" = "1,0 1,0.5 1,1 2,0 2,0.5 2,1 " ]' \
  table --beta 1,2 --g lin:0:1:3
good "table single N, no empty cells" \
  '! grep -v "^#" "$work/out" | grep -q ",," && ! grep -q "cells beyond" "$work/out" &&
   [ "$(data "$work/out" | head -1 | tr "," "\n" | grep -cx "beta_K[0-9]*")" -eq 3 ]' \
  table --chain 3 --beta 1
}
case:table.qmc_transfer() {
# qmc options are recorded and used: the table's row is the row of `average` with the same
# options (qmc's numbers do not depend on the thread count).
good "table qmc options" \
  'grep -q "^# qmc (N = 5): 2048 points x 8 shifts, seed 42" "$work/out" &&
   [ "$(cols "$work/out" beta_K1 beta_K2 beta_K3 beta_K4 beta_K5 method evaluations)" = \
     "$("$pendavg" average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --beta 1 --method qmc --samples 2048 --shifts 8 --seed 42 --format csv | cols - beta_K1 beta_K2 beta_K3 beta_K4 beta_K5),qmc,16384" ]' \
  table --chain 5 --method qmc --beta 1 --samples 2048 --shifts 8 --seed 42
good "table qmc seed changes values" \
  '[ "$(cols "$work/out" beta_K1)" != \
     "$("$pendavg" table --chain 5 --method qmc --beta 1 --samples 1024 --shifts 4 --seed 2 | cols - beta_K1)" ]' \
  table --chain 5 --method qmc --beta 1 --samples 1024 --shifts 4 --seed 1
# transfer: the tolerance is recorded and used (the row is the row of `average` with the same
# tolerance), and chains beyond qmc's 256 particles run.
good "table transfer tolerance" \
  'grep -q "transfer (tolerance 1e-06, double only) for N > 4" "$work/out" &&
   [ "$(cols "$work/out" beta_K1 beta_K2 beta_K3 beta_K4 beta_K5)" = \
     "$("$pendavg" average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --beta 1 --tol 1e-6 --format csv | cols - beta_K1 beta_K2 beta_K3 beta_K4 beta_K5)" ]' \
  table --chain 5 --beta 1 --tol 1e-6
good "table chain 300 (transfer)" \
  '[ "$(grep -v "^#" "$work/out" | sed 1d | tr "," "\n" | grep -c "^transfer$")" -eq 1 ]' \
  table --chain 300 --beta 1 --tol 1e-4
}

# bad_table NAME ARGS...: bad input with --output: exit 2, one line, and no file left behind.
bad_table() {
  local name=$1
  shift
  bad "$name" table "$@" --output "$work/never.csv"
  expect "$name: no file left" '[ -z "$(ls "$work" | grep never)" ]'
}
case:table.list_refusals() {
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
expect "table g sweep bad point: no file left" '[ ! -e "$work/bad.csv" ] && [ -z "$(ls "$work" | grep "bad.csv")" ]'
}

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
case:simulate.output() {
good "simulate nve json"    'check_simulate_json microcanonical 2' \
  simulate --masses 1,1 --lengths 1,1 --theta 90deg --time 300 --format json
good "simulate langevin"    'check_simulate_json canonical 2' \
  simulate --masses 1,1 --lengths 1,1 --theta 0 --time 300 --thermostat langevin --beta 0.5 --seed 3 --format json
good "simulate csv"         'check_simulate_csv_row 3' \
  simulate --masses 1,2,1 --lengths 1,1,0.5 --phi 0.5,-1,2 --phidot 0,1,0 --time 20 --exact no
run simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --trajectory "$work/traj.csv" --every 100 --exact no
if [ "$rc" -eq 0 ] && [ "$(grep -c . "$work/traj.csv")" -eq 14 ] && head -1 "$work/traj.csv" | grep -qx '# schema: 1' \
   && sed -n 3p "$work/traj.csv" | grep -q '^t,E,phi1,phi2,phidot1,phidot2$' \
   && [ -z "$(ls "$work" | grep 'traj.csv.tmp')" ]; then pass
else fail "simulate trajectory file" "exit 0, 14 lines: '# schema: 1', the column line t,E,phi1,phi2,phidot1,phidot2, the rows; no temporary" "exit $rc, $(grep -c . "$work/traj.csv" 2>&1) lines, columns $(sed -n 3p "$work/traj.csv" 2>&1)"; fi
# --output FILE: written atomically, nothing on stdout
run simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --exact no --format json --output "$work/simulate.json"
if [ "$rc" -eq 0 ] && [ ! -s "$work/out" ] && "$python" -c "import json, sys; d = json.load(open(sys.argv[1])); assert d['schema'] == 1 and d['command'] == 'simulate' and len(d['K']) == 2" "$work/simulate.json" \
   && [ -z "$(ls "$work" | grep 'simulate.json.tmp')" ]; then pass
else fail "simulate --output" "exit 0, nothing on stdout, the JSON in the file, no temporary" "exit $rc"; fi
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
}
case:simulate.refusals() {
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
}
case:signals.simulate() {
# SIGINT ends a run cleanly: exit 0, the averages so far, "interrupted": true.
"$pendavg" simulate --masses 1,1,1,1 --lengths 1,1,1,1 --theta 90deg --time 1e6 --exact no --format json >"$work/out" 2>"$work/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 0 ] && "$python" -c "import json,sys; d=json.load(open(sys.argv[1])); assert d['interrupted'] and 0 < d['steps'] < 10**9 and len(d['K']) == 4" "$work/out" \
   && grep -q "interrupted" "$work/err"; then pass
else fail "simulate SIGINT" "exit 0, JSON with interrupted true and 0 < steps < 1e9, 'interrupted' on stderr" "exit $rc (the check's message, if any, above)"; fi
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
" "$work/out"; then pass
else fail "simulate SIGINT before the blocks fill" "exit 0, null errors with a reason, no nan" "exit $rc (the check's message, if any, above)"; fi
}
case:signals.series() {
# SIGINT during the series' Bessel table: exit 130, one line, nothing on stdout.
"$pendavg" series --masses 1,100 --lengths 1,1 --beta 1 >"$work/out" 2>"$work/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 130 ] && [ ! -s "$work/out" ] && grep -q '^pendavg: interrupted: ' "$work/err"; then pass
else fail "series SIGINT" "exit 130, nothing on stdout, 'pendavg: interrupted: ' on stderr" "exit $rc"; fi
}
case:series.refusals() {
bad "series beyond the term cap" series --masses 1,1e3 --lengths 1,1 --beta 1
# A light first particle: the refusal names mu2 = 1 - mu1 (not "1") and the a priori term
# count (~ln(tol mu1^2 / 2) / ln mu2 = 7.9e13 for mu1 = 1e-12; it stopped at 2^40 + 1).
bad "series, mu1 = 1e-12: refused" series --masses 1e-12,1 --lengths 1,1 --beta 1
expect "series, mu1 = 1e-12: the message names mu2 and the term count" \
  'grep -Eq "mu2 = 1 - 1e-12 converges like mu2\^n: about [1-9][0-9]{13} terms" "$work/err"'
}
case:signals.average() {
# SIGINT during a long torus run: the last finished level, "interrupted": true, errors covering.
"$pendavg" average --masses 1,1,1,1 --lengths 1,1,1,1 --beta 1e3 --digits 30 --format json >"$work/out" 2>"$work/err" &
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
assert abs(float(d['beta_K'][0]) - exact) <= float(d['beta_K_error'][0]), d
" "$work/out"; then pass
else fail "average SIGINT" "exit 0, interrupted and not converged, beta_K1 within its error of 0.4991310458913583" "exit $rc (the check's message, if any, above)"; fi
}
# Issue 11: one big qmc point, a long transfer run and a long microcanonical run stop within
# seconds of SIGINT (polled between lattice chunks, between links, every 256 nodes): exit 0 with
# what they finished ("interrupted": true, not converged), or 130 and one line when nothing
# finished. A liveness bound with a wide margin (the runs take minutes), not a timing.
interrupt_within() { # NAME SECONDS_BEFORE_SIGNAL ARGS... (env limit_tenths: the bound, 150)
  local name=$1 delay=$2 waited=0 limit=${limit_tenths:-150}
  shift 2
  "$pendavg" "$@" --format json >"$work/out" 2>"$work/err" &
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
    fail "$name" "ended within $((limit / 10)) s of SIGINT" "still running"
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
    fail "$name" "exit 130 and one line, or exit 0 with interrupted true and not converged" "exit $rc (the check's message, if any, above)"
  fi
}
ones() { printf '1%.0s,' $(seq 2 "$1"); printf '1'; }
case:signals.qmc_text() {
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
if [ "$rc" -eq 0 ] && [ "$(count_scalar "$work/out" converged false)" -eq 1 ] &&
   [ "$(count_scalar "$work/out" interrupted true)" -eq 1 ]; then
  pass
else
  fail "average --format text, interrupted: marked" "exit 0, 'converged = false' and 'interrupted = true' once each" \
    "exit $rc, $(count_scalar "$work/out" converged false) and $(count_scalar "$work/out" interrupted true)"
fi
}
case:signals.qmc() {
interrupt_within "qmc N = 64 at 2^20 points: SIGINT" 2 \
  average --masses "$(ones 64)" --lengths "$(ones 64)" --beta 1 --method qmc --samples 1048576
}
case:signals.transfer() {
interrupt_within "transfer N = 4096: SIGINT" 2 \
  average --masses "$(ones 4096)" --lengths "$(ones 4096)" --beta 1 --tol 1e-12
}
case:signals.microcanonical() {
interrupt_within "microcanonical N = 4 at 20 digits: SIGINT" 2 \
  average --masses 1,1,1,1 --lengths 1,1,1,1 --energy 0 --digits 20
interrupt_within "microcanonical qmc N = 64: SIGINT" 2 \
  average --masses "$(ones 64)" --lengths "$(ones 64)" --energy 0 --samples 65536 --shifts 1024
}
case:signals.torus() {
# A torus level at N = 10 takes seconds (its first: 8^9 nodes; at N = 8 and 9 the work cap now
# ends the run after a first level of ~1-2 s, before the signal) and its outermost slices ~1/16
# of it: the stop request is polled before every innermost row of nodes (it took 4-5 s, the end
# of the slice; now ~20 ms).
for rule in torus-trapezoid torus-gauss; do
  limit_tenths=20 interrupt_within "$rule N = 10, SIGINT inside a level of seconds" 2 \
    average --masses "$(ones 10)" --lengths "$(ones 10)" --beta 1 --method "$rule" --tol 1e-12
done
}
case:input.double_range() {
# The microcanonical engine's double range is checked before any work, with advice that works.
bad "micro energy 1e308"       average --masses 1,1 --lengths 1,1 --energy 1e308
bad "micro excitation 1e300"   average --masses 1 --lengths 1 --excitation 1e300
bad "micro mass ratio 1e300"   average --masses 1,1,1e300 --lengths 1,1,1 --energy 0
bad "micro subnormal excitation" average --masses 1,1 --lengths 1,1 --excitation 1e-310
printf 'energy,m1,m2,l1,l2\n0,1,1,1,1\n1e308,1,1,1,1\n' >"$work/micro_far.csv"
bad "micro cases energy 1e308" average --cases "$work/micro_far.csv"
good "micro energy 1e300 in MPFR" '"$python" -c "import json,sys; o=json.load(open(sys.argv[1])); assert abs(float(o[\"K\"][0]) / 1e300 - 0.3431834814709248549) < 1e-15" "$work/out"' \
  average --masses 1,1 --lengths 1,1 --energy 1e300 --digits 20 --format json
# The transfer operator's double range (total over lightest mass <= 1e150), before any work.
bad "transfer mass ratio 1e200" average --masses 1e-100,1e100,1,1e-100,1e100 --lengths 1,1,1,1,1 --beta 1
# Refused before any integration: an unstable time step, a flung chain, no accessible states.
bad "simulate dt 10"           simulate --masses 1,1 --lengths 1,1 --phi 1,0 --phidot 0,0 --dt 10 --time 100
bad "simulate phidot 1e10"     simulate --masses 1,1 --lengths 1,1 --phi 0,0 --phidot 1e10,0 --time 1
bad "simulate at rest, bottom" simulate --masses 1,1 --lengths 1,1 --theta 0 --time 3000000
}

case:signals.table() {
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
   && grep -q "interrupted" "$work/err"; then pass
else fail "table SIGINT" "exit 0, '# interrupted: K of 60 points computed', fewer than 60 rows, no temporary, 'interrupted' on stderr" "exit $rc"; fi
}

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
case:poincare.output() {
good "poincare csv"            'check_poincare 40' poincare --masses 1,1 --lengths 1,1 --energy -2.5 --orbits 4 --points 10
run poincare --masses 1,1 --lengths 1,1 --energy -2.5 --orbits 2 --points 5 --output "$work/section.csv"
if [ "$rc" -eq 0 ] && [ ! -s "$work/out" ] && [ "$(grep -c '^[0-9]' "$work/section.csv")" -eq 10 ] \
   && head -1 "$work/section.csv" | grep -qx '# schema: 1'; then pass
else fail "poincare --output" "exit 0, nothing on stdout, 10 rows after '# schema: 1' in the file" "exit $rc"; fi
good "poincare json"           '"$python" -c "
import json, sys
d = json.load(open(sys.argv[1]))
assert d[\"schema\"] == 1 and d[\"command\"] == \"poincare\" and d[\"orbits\"] == 2 and d[\"points_per_orbit\"] == 3
assert len(d[\"points\"]) == 6 and all(set(p) == {\"orbit\", \"phi2\", \"p2\", \"time\"} for p in d[\"points\"])
" "$work/out"' poincare --masses 1,1 --lengths 1,1 --energy -2.5 --orbits 2 --points 3 --format json
}
case:poincare.refusals() {
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
}
case:input.advice() {
# The advice fits the command: scales that overflow say so (not "use --dt 0"), and a command
# without --digits does not advise it.
for extreme in "--energy 1e308" "--g 1e308 --energy 1"; do
  run poincare --masses 1,1 --lengths 1,1 $extreme --orbits 2 --points 5
  # the energy scale overflows, or g leaves the dynamics' range (1e-50..1e50): both say why
  expect "poincare $extreme: the overflow named" \
    '[ "$rc" -eq 2 ] && grep -qE "(overflow double|outside 1e-50..1e50).*; choose units nearer 1" "$work/err"'
done
run poincare --masses 1,1 --lengths 1,1 --energy 1e400
expect "poincare --energy 1e400: no --digits advice" '[ "$rc" -eq 2 ] && grep -q "out of the range of double$" "$work/err"'
run simulate --masses 1,1 --lengths 1,1 --theta 0.1 --time 1e400
expect "simulate --time 1e400: no --digits advice" '[ "$rc" -eq 2 ] && grep -q "out of the range of double$" "$work/err"'
run average --masses 1,1 --lengths 1,1 --beta 1e400
expect "average --beta 1e400: the --digits advice" '[ "$rc" -eq 2 ] && grep -q "(use --digits > 16)$" "$work/err"'
}

# ---------------------------------------------------------------- microcanonical (issue 15)
check_micro_json() { # N DIGITS [K1 reference: |K1 - reference| <= K1's error]
  py - "$1" "$2" "${3:-}" "$work/out" <<'PY'
import math, sys
from decimal import Decimal, getcontext
from schema1 import load, real, D, micro_json, other_state
getcontext().prec = 60
n, digits, prefix = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
o = load(sys.argv[4])  # (one JSON line, no bare NaN)
state = "energy" if list(o)[4] == "energy" else "excitation"
assert list(o) == micro_json(state), list(o)
assert o["N"] == n and o["digits"] == digits and o["ensemble"] == "microcanonical", o
assert o["converged"] is True and o["K_error_kind"] in ("estimate", "statistical"), o
for k in ("K", "K_error", "cos_phi", "cos_phi_error", "var_K", "var_K_error"):
    assert isinstance(o[k], list) and len(o[k]) == n, k
    assert all(math.isfinite(D(v)) for v in o[k]), (k, o[k])
for k in ("K", "cos_phi", "var_K"):
    for v in o[k]:
        real(v, digits)  # every digit of the double, or --digits digits
for k in ("Kc", "K_total", "density_of_states", other_state(state)):
    real(o[k], digits)
for value, error in zip(o["K"], o["K_error"]):
    assert 0 < D(error) < Decimal("1e-8") * D(value) or o["K_error_kind"] == "statistical", (value, error)
total = D(o["K_total"])
assert abs(sum(map(D, o["K"])) - total) <= Decimal("1e-12") * total
assert abs(D(o["Kc"]) * n - total) <= Decimal("1e-12") * total
if prefix:  # the printed value and its printed error
    deviation = abs(D(o["K"][0]) - Decimal(prefix))
    assert deviation <= D(o["K_error"][0]), (o["K"][0], o["K_error"][0], prefix)
    assert deviation <= Decimal(10) ** (1 - digits) * Decimal(prefix), (o["K"][0], prefix)
PY
}
# Near the bottom of the unit double pendulum (issue 15). References: the 40-digit mpmath
# quadrature of the definition, `python3 tests/bench/near_minimum_ladder.py --reference 1,1 1,1 1 D`:
# at the double E = -2.99999999 (D = 9.99999993922529029...e-9, exactly) <K_1>_E =
# 2.4999999684000729769e-9 (the issue's audit: 2.49999996840007298e-09; the old engine was off by
# 3e-9 relative); at D = 1e-8 (the double in double runs, the decimal in MPFR runs; they differ
# by 2e-17 relative) <K_1>_E = 2.49999998359375020479329115840663e-9.
case:microcanonical.average() {
good "micro --energy near the minimum" 'check_micro_json 2 16 2.4999999684000729769e-9' \
  average --masses 1,1 --lengths 1,1 --energy -2.99999999 --format json
good "micro --excitation"      'check_micro_json 2 16 2.49999998359375020479329115840663e-9' \
  average --masses 1,1 --lengths 1,1 --excitation 1e-8 --format json
good "micro --excitation digits 30" 'check_micro_json 2 30 2.49999998359375020479329115840663e-9' \
  average --masses 1,1 --lengths 1,1 --excitation 1e-8 --digits 30 --format json
good "micro N = 3 unit, E = 0" 'check_micro_json 3 16 && cp "$work/out" "$work/micro3.json"' \
  average --masses 1,1,1 --lengths 1,1,1 --energy 0 --format json
# the torus-trapezoid rule (a different quadrature of the same integrals) against the integral rule
good "micro N = 3 torus-trapezoid agrees" 'py -c "
import sys
from schema1 import load
t, i = load(sys.argv[1]), load(sys.argv[2])
assert t[\"method\"] == \"torus-trapezoid\" and i[\"method\"] == \"integral\", (t, i)
for key in (\"K\", \"cos_phi\", \"var_K\"):
    for a, ea, b, eb in zip(t[key], t[key + \"_error\"], i[key], i[key + \"_error\"]):
        assert abs(float(a) - float(b)) <= float(ea) + float(eb) and float(ea) < 1e-4 * abs(float(a)), (key, a, ea, b, eb)
" "$work/out" "$work/micro3.json"' average --masses 1,1,1 --lengths 1,1,1 --energy 0 --method torus-trapezoid --tol 1e-5 --format json
good "micro N = 5 qmc"         'check_micro_json 5 16' \
  average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --samples 1024 --shifts 8 --format json
good "micro csv"               'check_average_csv 2 energy' \
  average --masses 1,1 --lengths 1,1 --energy 0.5 --format csv
good "micro text"              '[ "$(count_scalar "$work/out" ensemble microcanonical)" -eq 1 ] && grep -Eq "^i +K +K_error +cos_phi +cos_phi_error +var_K +var_K_error$" "$work/out"' \
  average --masses 1,1 --lengths 1,1 --energy 0.5 --format text
}
case:microcanonical.refusals() {
bad "micro energy below the minimum" average --masses 1,1 --lengths 1,1 --energy -4
expect "micro energy below the minimum: the valid range" 'grep -q "minimum energy E_min = -3" "$work/err"'
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
}

case:microcanonical.cases() {
micro_cases_header=$(canonical_header cases 2 energy)
good "cases energy column" \
  '[ "$(data "$work/out" | wc -l)" -eq 4 ] && [ "$(data "$work/out" | head -1)" = "$micro_cases_header" ] &&
   py -c "import sys; from schema1 import *; assert has_prefix(read_csv(sys.argv[1])[2][1][\"K1\"], \"2.4999999684000e-9\")" "$work/out"' \
  average --cases "$work/energy.csv"
# the mpmath reference above, to 20 digits: 2.4999999835937502048e-9
good "cases excitation column, digits 20" \
  '[ "$(data "$work/out" | wc -l)" -eq 2 ] && [ "$(data "$work/out" | head -1)" = "$(canonical_header cases 2 excitation)" ] &&
   cols "$work/out" K1 | grep -q "^2.4999999835937502"' \
  average --cases "$work/excitation.csv" --digits 20
printf 'beta,energy,g,m1,m2,l1,l2\n1,1,1,1,1,1,1\n' >"$work/beta_energy.csv"
bad "cases beta and energy"    average --cases "$work/beta_energy.csv"
printf 'energy,g,m1,m2,l1,l2\n0,1,1,1,1,1\n-4,1,1,1,1,1\n' >"$work/energy_low.csv"
bad "cases energy below min"   average --cases "$work/energy_low.csv"
expect "cases energy below min: stderr names line 3" 'grep -q "line 3" "$work/err"'
# microcanonical rows run through the same sweep engine: --timing as for beta rows
run average --cases "$work/energy.csv"
cp "$work/out" "$work/energy_out.csv"
run average --cases "$work/energy.csv" --timing
expect "cases energy --timing: stdout unchanged, one stderr summary line" \
  '[ "$rc" -eq 0 ] && cmp -s "$work/out" "$work/energy_out.csv" && [ "$(wc -l <"$work/err")" -eq 1 ] &&
   grep -Eq "^pendavg: timing: rows=3 median_us=" "$work/err"'
bad "cases energy and --energy" average --cases "$work/energy.csv" --energy 1
}

check_micro_table() { # ROWS STATE
  py - "$work/out" "$1" "$2" <<'PY'
import csv, sys
from schema1 import read_csv, header as schema1_header
comments, header, rows = read_csv(sys.argv[1])
assert comments[0] == "# schema: 1", comments
assert len(rows) == int(sys.argv[2]), len(rows)
state = sys.argv[3]
assert header == schema1_header("table", max(int(r["N"]) for r in rows), state), header
for r in rows:
    assert r["converged"] == "true", r
    n = int(r["N"])
    total = sum(float(r["K%d" % (i + 1)]) for i in range(n))
    assert abs(float(r["Kc"]) * n - total) <= 1e-12 * total, r
    for i in range(n):
        assert float(r["K%d_error" % (i + 1)]) > 0, r
PY
}
case:microcanonical.table() {
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
}


case:average.qmc_underflow() {
# qmc weights cannot underflow (issue 15: this run printed NaN with "converged": true); its
# values within their bars of the tensor torus rule's
good "torus beta 100 (reference)" 'cp "$work/out" "$work/torus100.json"' \
  average --masses 1,1,1 --lengths 1,1,1 --beta 100 --method torus-trapezoid --format json
good "qmc beta 100 seed 16 finite" 'py -c "
import sys, math
from schema1 import load, D
o, t = load(sys.argv[1]), load(sys.argv[2])
for k in (\"beta_K\", \"beta_K_error\", \"cos_phi\", \"cos_phi_error\", \"var_K\", \"var_K_error\"):
    assert all(math.isfinite(D(v)) for v in o[k]), (k, o[k])
assert o[\"converged\"] is True and o[\"method\"] == \"qmc\", o
for key in (\"beta_K\", \"cos_phi\", \"var_K\"):
    error = key + \"_error\"
    for a, ea, b, eb in zip(o[key], o[error], t[key], t[error]):
        assert abs(D(a) - D(b)) <= D(ea) + D(eb), (key, a, ea, b, eb)
" "$work/out" "$work/torus100.json"' average --masses 1,1,1 --lengths 1,1,1 --beta 100 --method qmc --seed 16 --format json
}
# ---------------------------------------------------------------- issue 10: every error in every output
# The keys and columns added after the original ones: present, finite (JSON never holds a bare
# nan/inf: json.loads below refuses NaN and Infinity), errors positive, kinds valid, and equal to
# what `average` prints for the same point where both print it.
strict_python() { PYTHONPATH="$work" "$python" "$@"; }

check_limit_added() { # N DIGITS RUN_KEYS (the keys of high_temperature.run, "null" for none)
  py - "$work/out" "$1" "$2" "$3" <<'PY'
from schema1 import load, real, D, KINDS, LIMIT_JSON, CANONICAL_JSON
import math, sys
from decimal import Decimal
d = load(sys.argv[1]); n = int(sys.argv[2]); digits = int(sys.argv[3])
assert list(d) == LIMIT_JSON, list(d)
assert d["N"] == n and d["digits"] == digits and len(d["m"]) == len(d["l"]) == n, d
assert isinstance(d["seconds"], Decimal) and 0 <= d["seconds"] < 600, d["seconds"]
for part in ("high_temperature", "low_temperature"):
    o = d[part]
    assert list(o) == CANONICAL_JSON, list(o)
    assert o["converged"] is True and o["interrupted"] is False, o
    # a limit has no <K_i> and no Var K_i (beta^2 Var K_i only)
    for q in ("K", "var_K"):
        assert o[q] == o[q + "_error"] == [None] * n and o[q + "_error_kind"] is None, (q, o)
    # beta<K_i^c> = 1/2 exactly: as printed, within its error (0 where the print is exact) of 1/2
    assert [real(x, digits) for x in o["beta_Kc"]] == [Decimal("0.5")] * n, o["beta_Kc"]
    assert len(o["beta_Kc_error"]) == n and all(
        abs(D(x) - Decimal("0.5")) <= D(e) < Decimal("1e-14")
        for x, e in zip(o["beta_Kc"], o["beta_Kc_error"])), o
    for q in ("beta_K", "ratio", "cos_phi", "beta2_var_K", "beta_Kc"):
        assert o[q + "_error_kind"] in KINDS, (q, o)
    assert o["beta_Kc_error_kind"] == "bound", o
    # the residual |sum_i beta<K_i> - N/2| against the printed values (within their errors and
    # the residual's own 3 digits)
    residual = D(o["equipartition_residual"])
    assert residual >= 0, residual
    total = sum(D(x) for x in o["beta_K"])
    bars = sum(D(x) for x in o["beta_K_error"])
    assert abs(abs(total - Decimal(n) / 2) - residual) <= bars + residual / 100, (total, residual, bars)
run = d["high_temperature"]["run"]
if sys.argv[4] == "null":
    assert run is None, run
else:
    assert sorted(run) == sorted(sys.argv[4].split(",")) and all(v > 0 for v in run.values()), run
assert d["low_temperature"]["run"] is None
PY
}
case:limit.every_error() {
good "limit json: converged, run, residual, beta_Kc, seconds (N = 2)" 'check_limit_added 2 16 null' \
  limit --masses 0.5,0.5 --format json
good "limit json: the torus run (N = 3)" 'check_limit_added 3 16 points_per_dim,levels,grid_points' \
  limit --masses 1,2,0.5 --lengths 1,0.5,2 --format json
good "limit json: the transfer run (N = 7)" 'check_limit_added 7 16 angle_nodes,pivot_nodes,levels' \
  limit --masses 1,1,1,1,1,1,1 --format json
good "limit json: digits 30" 'check_limit_added 2 30 null' limit --masses 0.2,0.8 --lengths 1,2 --digits 30 --format json
}

# limit --format csv: average's columns (the same writer), the limit in front and no beta; its
# values are the JSON's, as printed there.
check_limit_csv() { # N MASSES LENGTHS DIGITS
  "$pendavg" limit --masses "$2" --lengths "$3" --digits "$4" --format json >"$work/limit.json" &&
  "$pendavg" average --masses "$2" --lengths "$3" --beta 1 --digits "$4" --format csv >"$work/average.csv" &&
  py - "$work/out" "$work/limit.json" "$work/average.csv" "$1" "$4" <<'PY'
from schema1 import load, read_csv, columns_of, text, per, KINDS
import math, sys
from decimal import Decimal
comments, header, rows = read_csv(sys.argv[1])  # (no ragged rows)
assert comments == ["# schema: 1", "# pendavg limit"], comments
d = load(sys.argv[2]); n = int(sys.argv[4])
average_header = read_csv(sys.argv[3])[1]
assert header == ["limit"] + [c for c in average_header if c != "beta"], header
assert [r["limit"] for r in rows] == ["high_temperature", "low_temperature"], rows
# beta<K_i> = 1/2 (beta -> inf), <cos phi_i> = 0 (beta -> 0) and 1 (beta -> inf) and
# beta<K_i^c> = 1/2 are exact: only there an error may be 0
exact = {("high_temperature", "cos_phi"): 0, ("low_temperature", "cos_phi"): 1,
         ("low_temperature", "beta_K"): Decimal("0.5"), ("high_temperature", "beta_Kc"): Decimal("0.5"),
         ("low_temperature", "beta_Kc"): Decimal("0.5")}
for r in rows:
    o = d[r["limit"]]
    expected = dict(columns_of(d), **columns_of(o), limit=r["limit"])
    for column in header:
        if column != "seconds":
            assert r[column] == text(expected[column]), (column, r[column], expected[column])
    assert r["N"] == str(n) and r["digits"] == sys.argv[5] and r["converged"] == "true", r
    assert not any(r[k] for k in per("K", n) + per("var_K", n) + ["K_error_kind", "var_K_error_kind"]), r
    assert not any(r[k + "_error"] for k in per("K", n) + per("var_K", n)), r
    assert r["beta_Kc_error_kind"] == "bound" and {r["beta_K_error_kind"], r["cos_phi_error_kind"],
                                                  r["beta2_var_K_error_kind"]} <= KINDS, r
    assert math.isfinite(float(r["seconds"])) and float(r["seconds"]) >= 0
    for stem in ("beta_K", "cos_phi", "beta2_var_K", "beta_Kc"):
        for i in range(1, n + 1):
            value, error = Decimal(r[f"{stem}{i}"]), Decimal(r[f"{stem}{i}_error"])
            # positive, or 0 beside a value known exactly
            assert math.isfinite(error) and (error > 0 or value == exact.get((r["limit"], stem))), \
                (stem, i, r[f"{stem}{i}"], r[f"{stem}{i}_error"])
    for k in per("beta_K", n) + per("cos_phi", n) + per("beta2_var_K", n) + per("diagonal_approx", n):
        assert math.isfinite(float(r[k])), (k, r[k])
PY
}
case:limit.csv() {
good "limit --format csv (N = 2)"            'check_limit_csv 2 0.5,0.5 1,1 16' limit --masses 0.5,0.5 --lengths 1,1 --format csv
good "limit --format csv (N = 3, torus)"     'check_limit_csv 3 1,2,0.5 1,0.5,2 16' limit --masses 1,2,0.5 --lengths 1,0.5,2 --format csv
good "limit --format csv (N = 2, digits 30)" 'check_limit_csv 2 0.2,0.8 1,2 30' limit --masses 0.2,0.8 --lengths 1,2 --digits 30 --format csv
good "limit --format csv (N = 1)"            'check_limit_csv 1 2 3 16' limit --masses 2 --lengths 3 --format csv
# text: per limit, its name, its errors' kinds, its work and its residual
good "limit text: errors, work, residual per limit" \
  '[ "$(grep -c "^limit = \(high\|low\)_temperature$" "$work/out")" -eq 2 ] &&
   [ "$(grep -c "^error kinds: beta_K bound, " "$work/out")" -eq 2 ] && [ "$(count_scalar "$work/out" evaluations "[0-9]+")" -eq 2 ] &&
   [ "$(count_scalar "$work/out" work_unit "[a-z]+")" -eq 2 ] && [ "$(count_scalar "$work/out" converged true)" -eq 2 ] &&
   [ "$(count_scalar "$work/out" equipartition_residual "[0-9.e+-]+")" -eq 2 ] && [ "$(text_rows "$work/out")" -eq 4 ]' \
  limit --masses 0.5,0.5 --format text
}

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
case:simulate.every_error() {
good "simulate json: K_total, potential, energy_trend, samples (NVE)" 'check_simulate_added microcanonical' \
  simulate --masses 1,1 --lengths 1,1 --theta 90deg --time 300 --format json
"$pendavg" average --masses 1,1 --lengths 1,1 --beta 0.5 --format json >"$work/canonical.json" 2>/dev/null
good "simulate json: exact_var_K and kinds (Langevin)" 'check_simulate_added canonical "$work/canonical.json"' \
  simulate --masses 1,1 --lengths 1,1 --theta 0 --time 300 --thermostat langevin --beta 0.5 --seed 3 --format json
"$pendavg" average --masses 1,2,1 --lengths 1,1,0.5 --beta 2 --format json >"$work/canonical3.json" 2>/dev/null
good "simulate json: exact_var_K (Langevin, N = 3)" 'check_simulate_added canonical "$work/canonical3.json"' \
  simulate --masses 1,2,1 --lengths 1,1,0.5 --theta 0 --time 200 --thermostat langevin --beta 2 --seed 5 --format json
}

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
case:simulate.csv() {
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
good "simulate json: K_total and potential over replicas" check_replicas_added "${replicas3[@]}" --format json
}

# table and --cases rows: every column equals `average --format csv`'s for the same point (the
# same library call; the inputs as given); a series row's beta_K error is a bound, its cos_phi and
# var_K errors estimates.
check_rows_as_average() { # FILE KIND (table | cases): every row against `average --format csv`
  py - "$1" "$2" "$pendavg" <<'PY'
import math, subprocess, sys
from decimal import Decimal
from schema1 import read_csv, header, KINDS
kind, pendavg = sys.argv[2], sys.argv[3]
comments, head, rows = read_csv(sys.argv[1])  # (no ragged rows)
assert rows and comments[0] == "# schema: 1", comments
n_max = sum(1 for k in head if k.startswith("m") and k[1:].isdigit())
assert head == header(kind, n_max), head
for r in rows:
    n = int(r["N"]) if kind == "table" else n_max
    masses = ",".join(r[f"m{i}"] for i in range(1, n + 1))
    lengths = ",".join(r[f"l{i}"] for i in range(1, n + 1))
    args = [pendavg, "average", "--masses", masses, "--lengths", lengths, "--beta", r["beta"],
            "--g", r["g"], "--format", "csv"]
    if kind == "table":
        args += ["--digits", r["digits"]]
    if r["method"] == "series":
        args += ["--method", "series"]
    _, a_head, (a,) = read_csv(None, subprocess.run(args, capture_output=True, text=True, check=True).stdout)
    assert a_head == header("average", n), a_head
    # (a shorter chain's row of a mixed-N table: the cells beyond its N empty)
    names = [k for k in head if k != "seconds"]
    assert [r[k] for k in names] == [a.get(k, "") for k in names], [(k, r[k], a.get(k)) for k in names if r[k] != a.get(k, "")]
    for q in ("beta_K", "K", "ratio", "cos_phi", "var_K", "beta2_var_K", "beta_Kc"):
        assert r[q + "_error_kind"] in KINDS, (q, r)
    assert r["beta_Kc_error_kind"] == "bound" and r["work_unit"] in ("terms", "nodes", "samples"), r
    assert math.isfinite(float(r["equipartition_residual"])) and float(r["equipartition_residual"]) >= 0
    assert r["converged"] == "true" and r["interrupted"] == "false", r
    for i in range(1, n + 1):
        # beta<K_i^c> = 1/2 exactly: within its error (0 where the print is exact) of 1/2
        value, error = Decimal(r[f"beta_Kc{i}"]), Decimal(r[f"beta_Kc{i}_error"])
        assert value == Decimal("0.5") and abs(value - Decimal("0.5")) <= error < Decimal("1e-14"), r
    if r["method"] == "series":
        assert (r["beta_K_error_kind"], r["cos_phi_error_kind"], r["var_K_error_kind"]) == ("bound", "estimate", "estimate"), r
PY
}
case:table.rows_as_average() {
good "table: error kinds, work_unit, residual, beta_Kc (series rows)" 'check_rows_as_average "$work/out" table' \
  table --beta 0.5,2 --mu1 0.3 --l2 0.7 --method series
good "table: the same for chains N = 3, 5 (torus, transfer)" 'check_rows_as_average "$work/out" table' \
  table --chain 3,5 --beta 1 --g 1,2
good "table: the same at digits 30" 'check_rows_as_average "$work/out" table' \
  table --beta 1 --mu1 0.3 --digits 30
}
case:cases.rows_as_average() {
good "cases: error kinds, work_unit, residual, beta_Kc" 'check_rows_as_average "$work/out" cases' \
  average --cases "$work/cases.csv"
good "cases: the same for N = 3" 'check_rows_as_average "$work/out" cases' \
  average --cases "$work/cases3.csv"
good "cases: the same for series rows" 'check_rows_as_average "$work/out" cases' \
  average --cases "$work/cases.csv" --method series
}

# microcanonical rows: every column (K_total, density_of_states, each with its error and kind,
# work_unit, ...) equal to `average --energy/--excitation --format csv`'s.
check_micro_added() { # FILE KIND (table | cases) STATE
  py - "$1" "$2" "$3" "$pendavg" <<'PY'
import math, subprocess, sys
from schema1 import read_csv, header
kind, state, pendavg = sys.argv[2], sys.argv[3], sys.argv[4]
comments, head, rows = read_csv(sys.argv[1])  # (no ragged rows)
assert rows and comments[0] == "# schema: 1", comments
n_max = sum(1 for k in head if k.startswith("m") and k[1:].isdigit())
assert head == header(kind, n_max, state), head
for r in rows:
    n = int(r["N"]) if kind == "table" else n_max
    args = [pendavg, "average", "--masses", ",".join(r[f"m{i}"] for i in range(1, n + 1)),
            "--lengths", ",".join(r[f"l{i}"] for i in range(1, n + 1)), f"--{state}", r[state],
            "--g", r["g"], "--format", "csv"]
    if kind == "table":
        args += ["--digits", r["digits"]]
    if r["method"] == "qmc":
        args += ["--samples", "1024", "--shifts", "8"]
    _, a_head, (a,) = read_csv(None, subprocess.run(args, capture_output=True, text=True, check=True).stdout)
    assert a_head == header("average", n, state), a_head
    # (a shorter chain's row of a mixed-N table: the cells beyond its N empty)
    names = [k for k in head if k != "seconds"]
    assert [r[k] for k in names] == [a.get(k, "") for k in names], [(k, r[k], a.get(k)) for k in names if r[k] != a.get(k, "")]
    for k in ("K_total", "K_total_error", "density_of_states", "density_of_states_error"):
        assert math.isfinite(float(r[k])) and float(r[k]) > 0, (k, r[k])
    total = sum(float(r[f"K{i}"]) for i in range(1, n + 1))
    bars = sum(float(r[f"K{i}_error"]) for i in range(1, n + 1)) + float(r["K_total_error"])
    assert abs(total - float(r["K_total"])) <= bars, (total, r["K_total"], bars)
    assert r["work_unit"] == ("samples" if r["method"] == "qmc" else "nodes"), r
PY
}
case:microcanonical.rows_as_average() {
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
}

# --certified (N = 2): every printed error a bound that covers the printed value; the JSON's
# kinds are all "bound" and the printed value lies within its printed error of a 60-digit run.
check_certified() { # FILE DIGITS REFERENCE-FILE
  py - "$1" "$2" "$3" <<'PY'
import sys
from decimal import Decimal, getcontext
from schema1 import load, real, D
getcontext().prec = 80
run, digits, ref = load(sys.argv[1]), int(sys.argv[2]), load(sys.argv[3])
assert run["method"] == "certified-integral" and run["beta_K_error_kind"] == "bound", run
assert run["converged"] is True, run
kinds = {k: v for k, v in run.items() if k.endswith("_error_kind")}
assert len(kinds) == 7 and all(k == "bound" for k in kinds.values()), kinds
for key in ("beta_K", "K", "cos_phi", "var_K", "beta2_var_K"):
    err = key + "_error"
    for v, e, r in zip(run[key], run[err], ref[key]):
        real(v, digits)
        assert abs(D(v) - D(r)) <= D(e), (key, v, e, r)
        assert D(e) <= Decimal(10) ** (2 - digits) * abs(D(v)) + Decimal("1e-300"), (key, v, e)
assert abs(D(run["ratio"]) - D(ref["ratio"])) <= D(run["ratio_error"])
PY
}
case:average.certified() {
if "$pendavg" --version | grep -q '^certified enclosures (--certified): Arb'; then
  run average --masses 1,3 --lengths 1,2 --beta 7 --g 2 --certified --digits 60 --format json
  cp "$work/out" "$work/certified_ref.json"
  # A double's shortest round-trip text is not the double's value as a decimal (up to half a
  # unit of its last digit away): a printed bound must cover the printed value, not only the
  # double (this point's beta_K[1] once printed a bound that covered the double alone).
  good "average --certified: bounds (double)" 'check_certified "$work/out" 16 "$work/certified_ref.json"' \
    average --masses 1,3 --lengths 1,2 --beta 7 --g 2 --certified --format json
  good "average --certified --digits 30: bounds" 'check_certified "$work/out" 30 "$work/certified_ref.json"' \
    average --masses 1,3 --lengths 1,2 --beta 7 --g 2 --certified --digits 30 --format json
  good "limit --certified: beta -> 0 in balls" 'grep -q "\"certified-integral\"" "$work/out"' \
    limit --masses 1,3 --certified --format json
  printf 'beta,g,m1,m2,l1,l2\n7,2,1,3,1,2\n' >"$work/certified.csv"
  good "average --cases --certified: kind bound" 'grep -q ",certified-integral," "$work/out" && ! grep -q estimate "$work/out"' \
    average --cases "$work/certified.csv" --certified
  bad "average --certified N = 3" average --masses 1,1,1 --lengths 1,1,1 --beta 1 --certified
  bad "average --certified --method series" average --masses 1,1 --lengths 1,1 --beta 1 --certified --method series
  bad "average --certified --energy" average --masses 1,1 --lengths 1,1 --energy 1 --certified
else
  bad "average --certified without Arb" average --masses 1,1 --lengths 1,1 --beta 1 --certified
fi
}

case:help.usage() {
good "average --help: microcanonical and MPFR" 'grep -q "excitation D" "$work/out" && grep -q "runs in MPFR" "$work/out"' average --help

for command in average limit series simulate poincare; do
  good "$command --help"     'grep -q "usage" "$work/out"' "$command" --help
done
good "--help"                'grep -q "usage" "$work/out"' --help
good "help"                  'grep -q "usage" "$work/out"' help
good "help average"          'grep -q "usage" "$work/out"' help average
good "--version"             'head -n 1 "$work/out" | grep -Eqx "pendavg [0-9]+\.[0-9]+\.[0-9]+"' --version
}


cases_main "$@"
