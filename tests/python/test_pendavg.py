# SPDX-License-Identifier: GPL-3.0-or-later
"""The Python module against the CLI (the same library calls: the same bits and the same strings)
and against direct C++ library calls (tests/python/reference_values.cpp: every number bit for
bit), arrays against scalar calls, error kinds, bad input, Ctrl-C in simulate, thread safety, and
the docstrings.

Run by ctest (label default) with PYTHONPATH=build/python, PENDAVG_CLI=build/pendavg,
PENDAVG_REFERENCE=build/tests/pendavg_reference_values and PENDAVG_TEST_STRICT=1 (nothing may be
skipped: a missing matplotlib or mpmath fails the test). By hand, with Debian's python3:
    PYTHONPATH=build/python /usr/bin/python3 -m pytest -q tests/python
"""
import concurrent.futures
import csv
import importlib
import inspect
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

import pendavg

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CLI = os.environ.get("PENDAVG_CLI", os.path.join(ROOT, "build", "pendavg"))
REFERENCE = os.environ.get("PENDAVG_REFERENCE",
                           os.path.join(ROOT, "build", "tests", "pendavg_reference_values"))
STRICT = os.environ.get("PENDAVG_TEST_STRICT") == "1"  # set by ctest: skip nothing


def optional_module(name):
    """Imports `name`; a missing module skips the test when run by hand, and fails it under ctest
    (PENDAVG_TEST_STRICT=1: run.sh installs python3-mpmath and python3-matplotlib for the tests)."""
    if STRICT:
        return importlib.import_module(name)
    return pytest.importorskip(name)


def text(x):
    """What the module reads a number as (floats: repr), for the CLI's command line."""
    return x if isinstance(x, str) else repr(x) if isinstance(x, float) else str(x)


def cli(*args):
    done = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
    return done


def cli_json(*args):
    done = cli(*args)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def cli_text_json(*args):
    """The CLI's JSON with every number kept as the text it printed (a double run prints numbers,
    an MPFR run decimal strings; either way the text is what .decimal must hold)."""
    done = cli(*args)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout, parse_float=str, parse_int=str)


def cli_average(masses, lengths, beta, g=1.0, digits=16, **options):
    args = ["average", "--masses", ",".join(map(text, masses)), "--lengths",
            ",".join(map(text, lengths)), "--beta", text(beta), "--g", text(g), "--digits", digits]
    for name, value in options.items():
        args += [f"--{name}", text(value)]
    return cli_text_json(*args, "--format", "json")


def assert_same_as_cli(r, d):
    """Every field of r is the CLI's (its JSON d, numbers as printed: cli_text_json): numbers
    digit for digit (.decimal, None for null), counts, flags and names equal; in a double run the
    floats are the printed numbers themselves (shortest round-trip text) and the errors at most
    the printed ones (3 digits rounded up, covering the value's printed text: at most one unit in
    the value's last place more). Every field of the result's table is in d."""
    for name, kind, per_particle, _, _ in type(r).fields():
        if name not in d:
            assert getattr(r, name) is None, name  # a limit's beta: not an input there
            continue
        value, printed = getattr(r, name), d[name]
        if kind in ("real", "error"):
            assert r.decimal[name] == printed, name
            if r.digits > 16 or value is None:
                continue
            flat = np.atleast_1d(np.asarray(value, dtype=float))
            texts = printed if per_particle else [printed]
            of = name.removesuffix("_error")  # X_error is the error of X (the schema's rule)
            values = np.atleast_1d(np.asarray(getattr(r, of) if of != name and
                                              getattr(r, of) is not None else 0.0, dtype=float))
            for x, text, v in zip(flat.tolist(), texts, np.broadcast_to(values, flat.shape)):
                if text is None:
                    assert np.isnan(x), name
                elif kind == "real":
                    assert x == float(text), (name, x, text)
                else:
                    assert x <= float(text) <= 1.01 * (x + np.spacing(abs(v))), (name, x, text)
        elif kind == "count":
            assert value == int(printed), name
        else:
            assert value == printed, name


# ---------------------------------------------------------------- agreement with the CLI

@pytest.mark.parametrize("masses, lengths, beta, options", [
    ([1.0], [1.0], 2.0, {}),                                   # N = 1: torus-trapezoid
    ([0.5, 0.5], [1.0, 1.0], 1.0, {}),                          # N = 2: integral
    ([0.9, 0.1], [1.0, 2.0], 3.0, {"method": "series"}),
    ([1.0, 2.0, 0.5], [1.0, 0.5, 2.0], 0.7, {}),                # N = 3: torus-trapezoid
    ([1.0, 1.0, 1.0], [1.0, 1.0, 1.0], 1.0, {"method": "torus-gauss", "tol": 1e-10}),
    ([1.0] * 8, [1.0] * 8, 1.0, {"method": "qmc", "samples": 4096, "seed": 3}),  # N = 8: qmc
    ([1.0] * 8, [1.0] * 8, 1.0, {}),                            # N = 8: transfer
    ([1.0, 0.5, 2.0, 1.0, 3.0], [1.0, 2.0, 0.5, 1.0, 1.0], 3.0, {"tol": 1e-6}),  # N = 5: transfer
    ([1.0] * 3, [1.0] * 3, 1e9, {}),                            # N = 3, low-temperature extrapolation
])
def test_double_agrees_with_cli(masses, lengths, beta, options):
    r = pendavg.average(masses, lengths, beta, **options)
    assert_same_as_cli(r, cli_average(masses, lengths, beta, **options))


TINY = 1e-12
HARD_N2 = [  # tests/validation/test_cross_check.cpp named_hard_cases: m1, m2, l1, l2, g, beta
    (TINY, 1.0 - TINY, 1, 1, 1, 1), (1.0 - TINY, TINY, 1, 1, 1, 1), (0.5, 0.5, 1, 1, 1, 1e8),
    (0.5, 0.5, 1, 1, 1, 1e-8), (0.5, 0.5, 1, 1e-4, 1, 1), (0.5, 0.5, 1, 1e4, 1, 1),
    (0.5, 0.5, 1, 1, 0, 1), (TINY, 1.0 - TINY, 1, 1, 1, 1e8), (TINY, 1.0 - TINY, 1, 1, 1, 1e-8),
    (1.0 - TINY, TINY, 1, 1, 1, 1e8), (0.5, 0.5, 1, 1e4, 1, 1e8), (0.5, 0.5, 1, 1e-4, 1, 1e8),
    (TINY, 1.0 - TINY, 1, 1e-4, 1, 1e8), (0.05, 0.95, 1, 1, 1, 100)]


@pytest.mark.parametrize("case", HARD_N2)
def test_hard_double_pendulum_cases_agree_with_cli(case):
    m1, m2, l1, l2, g, beta = case
    r = pendavg.average([m1, m2], [l1, l2], beta, g)
    assert_same_as_cli(r, cli_average([m1, m2], [l1, l2], beta, g))


@pytest.mark.parametrize("masses, lengths, beta, digits", [
    (["0.5", "0.5"], ["1", "1"], "1", 30),
    ([TINY, 1.0 - TINY], [1, 1e-4], 1e8, 40),      # floats: read as their repr, as typed
    (["0.05", "0.95"], ["1", "1"], "100", 60),
    ([1, 1, 1], [1, 1, 1], "0.5", 20),              # N = 3 torus in MPFR
])
def test_mpfr_agrees_with_cli(masses, lengths, beta, digits):
    r = pendavg.average(masses, lengths, beta, digits=digits)
    assert_same_as_cli(r, cli_average(masses, lengths, beta, digits=digits))
    # mpf: the exact MPFR value, which the printed string rounds
    mpmath = optional_module("mpmath")
    with mpmath.workdps(digits + 20):
        for value, printed in zip(r.mpf["beta_K"], r.decimal["beta_K"]):
            assert abs(value - mpmath.mpf(printed)) <= abs(value) * mpmath.mpf(10) ** (1 - digits)


def certified_build():
    return "certified enclosures (--certified): Arb" in cli("--version").stdout


@pytest.mark.parametrize("masses, lengths, beta, digits", [
    ([0.5, 0.5], [1.0, 2.0], 3.0, 16),
    (["0.05", "0.95"], ["1", "1"], "100", 30),
])
def test_certified_agrees_with_cli(masses, lengths, beta, digits):
    if not certified_build():
        with pytest.raises(ValueError, match="certified"):
            pendavg.average(masses, lengths, beta, digits=digits, certified=True)
        return
    r = pendavg.average(masses, lengths, beta, digits=digits, certified=True)
    args = ["average", "--masses", ",".join(map(text, masses)), "--lengths",
            ",".join(map(text, lengths)), "--beta", text(beta), "--digits", digits, "--certified",
            "--g", text(1.0)]  # the module's default g, as its text (an MPFR run prints it)
    assert_same_as_cli(r, cli_text_json(*args, "--format", "json"))
    assert r.method == "certified-integral" and r.beta_K_error_kind == "bound" and r.converged
    assert {getattr(r, f[0]) for f in r.fields() if f[0].endswith("_error_kind")} == {"bound"}
    lim = pendavg.limit(masses, digits=digits, certified=True)
    assert lim.high_temperature.method == "certified-integral"


def test_limit_agrees_with_cli():
    for masses, digits in (([0.5, 0.5], 16), (["0.05", "0.95"], 20), ([1, 1, 1], 16)):
        lim = pendavg.limit(masses, digits=digits)
        d = cli_text_json("limit", "--masses", ",".join(map(text, masses)), "--digits", digits,
                          "--g", text(1.0), "--format", "json")  # the module's default g, as text
        head = {k: v for k, v in d.items() if not isinstance(v, dict)}  # the chain's inputs
        for r, key in ((lim.high_temperature, "high_temperature"),
                       (lim.low_temperature, "low_temperature")):
            assert_same_as_cli(r, {**head, **d[key]})
            assert r.K is None and r.K_error is None and r.var_K is None and r.beta is None


def test_series_agrees_with_cli():
    """pendavg.series is `pendavg series --format json` field for field: the call's (its inputs,
    terms, certified, beta_K1_error_kind) and each term's (n, R_n, term, numerator, denominator,
    beta_K1 and its bound beta_K1_error, None while none exists), at 20 digits (decimal strings)
    and at 16 (doubles, each bound enlarged by its value's rounding)."""
    call_fields, term_fields = pendavg.SeriesResult.fields()
    for digits in (20, 16):
        s = pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=digits)
        d = cli_text_json("series", "--masses", "0.8,0.2", "--lengths", "1,1", "--beta", "2",
                          "--g", text(1.0), "--digits", digits, "--format", "json")
        for name, kind, per_particle, _, _ in call_fields:
            if kind in ("real", "error"):
                assert s.decimal[name] == d[name], name
            elif kind == "count":
                assert getattr(s, name) == int(d[name]), name
            else:
                assert getattr(s, name) == d[name], name
        assert s.terms == len(s.n) == len(d["rows"]) and s.beta_K1_error_kind == "bound"
        for name, kind, _, _, _ in term_fields:
            printed = [row[name] for row in d["rows"]]
            if kind == "count":
                assert getattr(s, name).tolist() == [int(x) for x in printed], name
                continue
            assert s.decimal[name] == printed, name
            values = getattr(s, name)
            for x, text_ in zip(values.tolist(), printed):
                if text_ is None:
                    assert np.isnan(x), name  # no bound yet
                elif digits == 16 and kind == "real":
                    assert x == float(text_), name  # the double itself
                elif digits == 16:
                    assert x <= float(text_) <= 1.01 * x, name  # 3 digits, rounded up
        mpmath = optional_module("mpmath")
        with mpmath.workdps(digits + 20):  # .mpf: the exact values the strings round
            for value, printed in zip(s.mpf["beta_K1"], s.decimal["beta_K1"]):
                assert abs(value - mpmath.mpf(printed)) <= abs(value) * mpmath.mpf(10) ** (1 - min(digits, 16))


def test_sweep_agrees_with_table():
    r = pendavg.sweep(beta=[0.1, 1, 10], mu1=[0.05, 0.5], l2=[0.5, 2])
    assert r.beta_K.shape == (3, 2, 2, 2) and r.ratio.shape == (3, 2, 2)
    out = cli("table", "--beta", "0.1,1,10", "--mu1", "0.05,0.5", "--l2", "0.5,2").stdout
    rows = [line.split(",") for line in out.splitlines() if not line.startswith("#")]
    header, rows = rows[0], rows[1:]
    col = {name: k for k, name in enumerate(header)}
    # table nests mu1, l1, l2, g, beta (beta fastest); the sweep's axes are (beta, mu1, l2)
    for row in rows:
        b = [0.1, 1, 10].index(float(row[col["beta"]]))
        m = ["0.05", "0.5"].index(row[col["m1"]])
        l = ["0.5", "2"].index(row[col["l2"]])
        for i in range(2):
            assert r.decimal["beta_K"][b, m, l, i] == row[col[f"beta_K{i + 1}"]]
            assert r.decimal["beta_K_error"][b, m, l, i] == row[col[f"beta_K{i + 1}_error"]]
            assert r.decimal["m"][b, m, l, i] == row[col[f"m{i + 1}"]]
        assert r.decimal["ratio"][b, m, l] == row[col["ratio"]]


# ---------------------------------------------------------------- the field tables

# What a result object has besides its fields: the call's shape and wall time, the CLI's strings
# and the exact values, a grid's axes, the conversions and the field list (the same for every
# call; the canonical averages also have the method's run diagnostics, a simulation its
# trajectory).
RESULT_EXTRAS = {"shape", "seconds", "decimal", "mpf", "dims", "coords", "fields", "to_dict",
                 "as_dict", "to_dataframe", "to_xarray", "_exact_values"}


def table_order(*tables):
    """Every field name of the output schema's tables `tables` (by io::all_tables' names), each
    once, in the tables' order."""
    known = pendavg._pendavg.tables()
    return list(dict.fromkeys(field[0] for table in tables for field in known[table]))


def table_names(*tables):
    return set(table_order(*tables))


def deprecated_aliases(names, cls="Averages"):
    """The migration table's renames of pendavg 0.2's attributes of class `cls` whose new name is
    in names."""
    return {old: new for old, new, _, python, _ in pendavg._pendavg.renames()
            if python == cls and new in names and old not in names}


def public_attributes(cls):
    return {n for n in dir(cls) if not (n.startswith("__") and n.endswith("__"))}


def test_result_attributes_are_the_field_tables():
    """A result class's attributes are its field tables' names (no more, no fewer), the migration
    table's deprecated aliases and the documented extras; its fields() list is those tables."""
    tables_of = {
        pendavg.Averages: ["canonical inputs", "chain inputs (limit)", "canonical averages"],
        pendavg.MicrocanonicalResult: [
            "microcanonical inputs (--energy)", "microcanonical inputs (--excitation)",
            "microcanonical averages (after --energy)",
            "microcanonical averages (after --excitation)"],
        pendavg.SimulationResult: ["simulation inputs", "simulation"]}
    averages = table_order(*tables_of[pendavg.Averages])
    micro = table_order(*tables_of[pendavg.MicrocanonicalResult])
    simulation = table_order(*tables_of[pendavg.SimulationResult])
    for cls, order, extras in ((pendavg.Averages, averages, RESULT_EXTRAS | {"run"}),
                               (pendavg.MicrocanonicalResult, micro, RESULT_EXTRAS),
                               (pendavg.SimulationResult, simulation,
                                RESULT_EXTRAS | {"trajectory"})):
        names = set(order)
        aliases = deprecated_aliases(names, cls.__name__)
        assert public_attributes(cls) == names | set(aliases) | extras, cls.__name__
        assert [f[0] for f in cls.fields()] == order
        tables = [pendavg._pendavg.tables()[t] for t in tables_of[cls]]
        known = {}
        for field in (f for t in tables for f in t):
            known.setdefault(field[0], field)  # (a name's first table describes it)
        for name, kind, per_particle, meaning, _ in cls.fields():  # the tables' own description
            assert (name, kind, per_particle, meaning) == known[name], name
            assert getattr(cls, name).__doc__ == meaning, name
    simulation_aliases = deprecated_aliases(set(simulation), "SimulationResult")
    assert deprecated_aliases(set(averages)) == {"error": "beta_K_error", "var_K_beta2": "beta2_var_K",
                                            "var_K_beta2_error": "beta2_var_K_error",
                                            "error_kind": "beta_K_error_kind"}
    assert deprecated_aliases(set(micro)) == {}
    assert simulation_aliases == {"error_kind": "K_error_kind",
                                  "exact_error_kind": "exact_K_error_kind"}
    s = pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=20)
    call, terms = pendavg.SeriesResult.fields()
    assert set(s.__dict__) == {f[0] for f in call + terms} | {"decimal", "exact"}
    assert {f[0] for f in call} == table_names("canonical inputs",
                                               "series run (after the canonical inputs)")
    assert {f[0] for f in terms} == table_names("series row")
    p = pendavg.poincare([1, 1], [1, 1], -2, orbits=1, points=2)
    call, crossings, starts = pendavg.PoincareSection.fields()
    assert set(p.__dict__) == {f[0] for f in call + crossings + starts} | {"seconds", "decimal"}
    assert [f[0] for f in call] == table_order("poincare section")
    assert [f[0] for f in crossings] == table_order("section point")
    assert [f[0] for f in starts] == table_order(
        "orbit start (Python's PoincareSection; the CLI prints the crossings)")


def test_run_diagnostics_are_the_run_tables():
    """Averages.run is a dict of one run table (the torus grid, the qmc run, the transfer
    operator's resolution), its values of the fields' kinds, and equal to the CLI's `run`."""
    tables = {name.split(" (")[0]: fields for name, fields in pendavg._pendavg.tables().items()}
    python_type = {"real": float, "count": int}
    calls = {"torus run": ([1] * 3, [1] * 3, {}), "qmc run": ([1] * 3, [1] * 3, {"method": "qmc",
                                                                              "samples": 1024}),
             "transfer run": ([1] * 5, [1] * 5, {})}
    for table, (masses, lengths, options) in calls.items():
        r = pendavg.average(masses, lengths, 1.0, **options)
        assert list(r.run) == [f[0] for f in tables[table]], table
        for name, kind, _, _ in tables[table]:
            assert type(r.run[name]) is python_type[kind], (table, name)
        args = ["average", "--masses", ",".join(map(str, masses)), "--lengths",
                ",".join(map(str, lengths)), "--beta", 1, "--format", "json"]
        for option, value in options.items():
            args += [f"--{option}", value]
        assert cli_json(*args)["run"] == r.run, table
    assert pendavg.average([0.5, 0.5], [1, 1], 1.0).run is None  # the integral: no run table
    grid = pendavg.average([1] * 3, [1] * 3, [1.0, 2.0])
    assert grid.run.shape == (2,) and all(set(run) == set(grid.run[0]) for run in grid.run)


def test_result_values_follow_the_field_kinds():
    """Per field kind and shape: per-particle fields are arrays (..., N), per-point fields floats
    (arrays of the grid's shape), counts ints, flags bools, texts str (str arrays); the call's
    counts (N, digits) are one int also for a grid."""
    one = pendavg.average([1, 2, 0.5], [1, 0.5, 2], 0.7)
    grid = pendavg.average([1, 2, 0.5], [1, 0.5, 2], [[0.7, 1.0]])
    python_type = {"real": float, "error": float, "count": int, "flag": bool, "text": str}
    numpy_kind = {"real": "f", "error": "f", "count": "i", "flag": "b", "text": "U"}
    for name, kind, per_particle, _, is_input in pendavg.Averages.fields():
        a, b = getattr(one, name), getattr(grid, name)
        if is_input and kind == "count":
            assert type(a) is int and a == b, name
        elif per_particle:
            assert a.shape == (3,) and b.shape == (1, 2, 3) and a.dtype.kind == numpy_kind[kind]
        else:
            assert type(a) is python_type[kind], name
            assert b.shape == (1, 2) and b.dtype.kind == numpy_kind[kind], name


def test_deprecated_aliases_warn_and_answer_the_new_field():
    results = (pendavg.average([0.5, 0.5], [1, 2], 1.0),
               pendavg.simulate([1, 1], [1, 1], theta=1, time=0.5))
    for r in results:
        name = type(r).__name__
        aliases = deprecated_aliases({f[0] for f in r.fields()}, name)
        assert aliases, name
        for old, new in aliases.items():
            with pytest.warns(DeprecationWarning,
                              match=rf"{name}\.{old} is deprecated .* use \.{new}$"):
                value = getattr(r, old)
            np.testing.assert_array_equal(value, getattr(r, new))
            assert old not in r.to_dict() and new in r.to_dict()


# ---------------------------------------------------------------- the C++ library's own bits

def reference(lines):
    """The library's results of reference_values.cpp's calls `lines` (direct C++ calls, every
    number printed exactly: %a, mpfr's %Ra), one dict per line."""
    if not os.path.exists(REFERENCE):
        if STRICT:
            pytest.fail(f"{REFERENCE} is missing (target pendavg_reference_values)")
        pytest.skip(f"{REFERENCE} not built (cmake --build build --target pendavg_reference_values)")
    done = subprocess.run([REFERENCE], input="\n".join(lines) + "\n", capture_output=True,
                          text=True, check=True)
    out = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(out) == len(lines)
    for line, result in zip(lines, out):
        assert "error" not in result, (line, result)
    return out


def reference_line(kind, masses, lengths, arguments):
    """reference_values.cpp's line for the Python call kind(masses, lengths, **arguments)."""
    given = {"g": 1.0, "digits": 16, **arguments}
    tokens = [kind, "masses=" + ",".join(map(text, masses)),
              "lengths=" + ",".join(map(text, lengths))]
    tokens += [f"{name}={text(value)}" for name, value in given.items() if name != "method" or value != "auto"]
    return " ".join(tokens)


def exact_fraction(printed):
    """The exact value of a number printed by %a (double) or mpfr's %Ra: 0xH.HHHp[+-]E."""
    sign = -1 if printed.startswith("-") else 1
    body = printed.lstrip("+-")
    if body in ("inf", "nan", "@Inf@", "@NaN@"):
        return printed
    mantissa, exponent = body[2:].split("p")
    whole, _, fraction = mantissa.partition(".")
    return sign * Fraction(int(whole + fraction, 16)) * Fraction(2) ** (int(exponent) - 4 * len(fraction))


def mpf_fraction(x):
    """An mpmath.mpf's exact value (its man * 2^exp), or its text for inf and nan."""
    mpmath = optional_module("mpmath")
    if not mpmath.isfinite(x):
        return ("-" if x < 0 else "") + ("inf" if mpmath.isinf(x) else "nan")
    sign, man, exponent, _ = x._mpf_  # (x.man_exp holds |man| only)
    return (-1) ** sign * Fraction(man) * Fraction(2) ** exponent


def assert_same_bits(python_value, printed, name):
    """Every double of python_value (a float or an array) has the bits of the printed one."""
    values = np.atleast_1d(np.asarray(python_value, dtype=float)).ravel().tolist()
    assert len(values) == len(printed), name
    for x, p in zip(values, printed):
        y = float.fromhex(p) if not isinstance(exact_fraction(p), str) else float(p)
        assert x.hex() == y.hex(), (name, x.hex(), p)


def assert_library_bits(result, library, given_state=None):
    """result (Averages or MicrocanonicalResult) holds exactly the library's numbers: in double
    the same doubles; with digits > 16 the same exact MPFR values (.mpf), the doubles they round
    to, and the CLI's decimal strings of them (.decimal)."""
    for name, printed in library["values"].items():
        if result.digits == 16:
            assert_same_bits(getattr(result, name), printed, name)
            continue
        exact = result.mpf[name]
        exact = list(exact) if isinstance(exact, (list, np.ndarray)) else [exact]
        assert [mpf_fraction(x) for x in exact] == [exact_fraction(p) for p in printed], name
        rounded = [float(f) for f in map(exact_fraction, printed)]
        assert_same_bits(getattr(result, name), [x.hex() for x in rounded], name)
    if isinstance(result, pendavg.Averages) and "ratio" not in library["values"]:
        assert result.ratio is None  # N = 1
    if isinstance(result, pendavg.MicrocanonicalResult) and "proposal_beta" not in library["values"]:
        assert result.proposal_beta is None and result.effective_sample_fraction is None  # not qmc
    for name, strings in library.get("decimal", {}).items():
        if name == given_state:  # printed as given, as the CLI prints it
            continue
        assert list(np.atleast_1d(result.decimal[name])) == strings, name
    assert result.method == library["method"]
    kind = "beta_K_error_kind" if isinstance(result, pendavg.Averages) else "K_error_kind"
    assert getattr(result, kind) == library["error_kind"]
    assert getattr(result, "ensemble", None) == library.get("ensemble")
    assert result.evaluations == library["evaluations"]
    assert result.converged == library["converged"]


BIT_CASES = [  # (function, masses, lengths, arguments): every method, double and MPFR
    ("average", [1.0], [1.0], {"beta": 2.0}),                                        # torus-trapezoid
    ("average", [0.5, 0.5], [1.0, 1.0], {"beta": 1.0}),                               # integral
    ("average", [TINY, 1.0 - TINY], [1, 1e-4], {"beta": 1e8}),                        # integral, hard
    ("average", [0.3, 0.7], [1.0, 2.0], {"beta": 0.1, "g": 0.0}),                     # integral, g = 0
    ("average", [0.9, 0.1], [1.0, 2.0], {"beta": 3.0, "method": "series"}),
    ("average", [1.0, 2.0, 0.5], [1.0, 0.5, 2.0], {"beta": 0.7}),                     # torus-trapezoid
    ("average", [1.0] * 3, [1.0] * 3, {"beta": 1.0, "method": "torus-gauss", "tol": 1e-10}),
    ("average", [1.0] * 8, [1.0] * 8, {"beta": 1.0, "method": "qmc", "samples": 4096, "seed": 3}),
    ("average", [1.0] * 8, [1.0] * 8, {"beta": 1.0}),                                 # transfer
    ("average", [1.0, 0.5, 2.0, 1.0, 3.0], [1.0, 2.0, 0.5, 1.0, 1.0], {"beta": 3.0, "tol": 1e-6}),
    ("average", [1.0] * 3, [1.0] * 3, {"beta": 1e9}),                # low-temperature extrapolation
    ("average", ["0.5", "0.5"], ["1", "1"], {"beta": "1", "digits": 30}),             # MPFR integral
    ("average", ["0.8", "0.2"], ["1", "1.5"], {"beta": "2", "digits": 25, "method": "series"}),
    ("average", [1, 1, 1], [1, 1, 1], {"beta": "0.5", "digits": 20}),                 # MPFR torus
    ("average", [1], [1], {"beta": "3", "digits": 40}),                              # MPFR N = 1
    ("limit", [0.5, 0.5], [1.0, 1.0], {}),
    ("limit", [1.0, 2.0, 0.5], [1.0, 0.5, 2.0], {}),                                 # torus at g = 0
    ("limit", ["0.05", "0.95"], ["1", "2"], {"digits": 20}),
    ("microcanonical", [1.0, 1.0], [1.0, 1.0], {"energy": 0.0}),                       # integral
    ("microcanonical", [1.0, 0.3], [1.3, 0.6], {"excitation": 1e-8, "g": 9.81}),
    ("microcanonical", [1.0, 1.0], [1.0, 1.0], {"energy": -1.0, "method": "torus-trapezoid"}),
    ("microcanonical", [1.0, 2.0, 0.5], [1.0, 0.5, 2.0], {"energy": 1.0}),             # N = 3 integral
    ("microcanonical", [1.0] * 5, [1.0] * 5, {"energy": 0.0, "samples": 1024, "seed": 2}),  # qmc
    ("microcanonical", ["1", "1"], ["1", "1"], {"energy": "0", "digits": 30}),         # MPFR integral
    ("microcanonical", ["1", "0.3"], ["1.3", "0.6"], {"excitation": "1e-8", "g": "9.81", "digits": 25}),
    ("microcanonical", ["1", "1"], ["1", "1"], {"energy": "-1", "digits": 20, "method": "torus-trapezoid"}),
]


@pytest.fixture(scope="module")
def library_results():
    return reference([reference_line(*case) for case in BIT_CASES])


def python_call(kind, masses, lengths, arguments):
    if kind == "average":
        rest = dict(arguments)
        return pendavg.average(masses, lengths, rest.pop("beta"), **rest)
    if kind == "limit":
        return pendavg.limit(masses, lengths, **arguments)
    return pendavg.microcanonical(masses, lengths, **arguments)


@pytest.mark.parametrize("k", range(len(BIT_CASES)),
                         ids=[reference_line(*case) for case in BIT_CASES])
def test_python_bits_equal_the_library(library_results, k):
    kind, masses, lengths, arguments = BIT_CASES[k]
    result, library = python_call(kind, masses, lengths, arguments), library_results[k]
    if kind == "limit":
        assert_library_bits(result.high_temperature, library["high_temperature"])
        assert_library_bits(result.low_temperature, library["low_temperature"])
    else:
        state = next((s for s in ("energy", "excitation") if s in arguments), None)
        assert_library_bits(result, library, state)


def test_methods_of_the_bit_cases():
    """BIT_CASES covers every method and microcanonical rule, in double and in MPFR."""
    seen = set()
    for kind, masses, lengths, arguments in BIT_CASES:
        r = python_call(kind, masses, lengths, arguments)
        for one in (r if kind == "limit" else [r]):
            ensemble = getattr(one, "ensemble", None)
            seen.add((f"{ensemble}/{one.method}" if ensemble else one.method, one.digits > 16))
    assert {("integral", False), ("series", False), ("torus-trapezoid", False),
            ("torus-gauss", False), ("qmc", False), ("transfer", False),
            ("low-temperature-extrapolation", False), ("limit-beta0", False),
            ("limit-beta-infinity", False), ("integral", True), ("series", True),
            ("torus-trapezoid", True), ("limit-beta0", True),
            ("microcanonical/integral", False), ("microcanonical/torus-trapezoid", False),
            ("microcanonical/qmc", False), ("microcanonical/integral", True),
            ("microcanonical/torus-trapezoid", True)} <= seen, seen


@pytest.mark.parametrize("masses, lengths, beta, options", [
    ([0.3, 0.7], [1.0, 2.0], np.logspace(-3, 3, 9), {}),
    ([1.0] * 3, [1.0] * 3, np.array([0.5, 2.0]), {"tol": 1e-10}),
    ([1.0] * 6, [1.0] * 6, np.array([0.5, 2.0]), {"tol": 1e-8}),
    (["0.4", "0.6"], ["1", "1"], ["0.1", "1", "10"], {"digits": 30}),
])
def test_grid_bits_equal_the_library(masses, lengths, beta, options):
    """Each point of an array call (one thread per point, a workspace per worker) is the
    library's scalar call, bit for bit."""
    grid = pendavg.average(masses, lengths, beta, **options)
    library = reference([reference_line("average", masses, lengths, {"beta": b, **options})
                         for b in beta])
    for b, point in enumerate(library):
        for name, printed in point["values"].items():
            if grid.digits == 16:
                assert_same_bits(getattr(grid, name)[b], printed, name)
            else:
                exact = np.atleast_1d(grid.mpf[name][b]).tolist()
                assert [mpf_fraction(x) for x in exact] == [exact_fraction(p) for p in printed]
        for name, strings in point.get("decimal", {}).items():
            assert list(np.atleast_1d(grid.decimal[name][b])) == strings, name
        assert grid.method[b] == point["method"] and grid.evaluations[b] == point["evaluations"]


# ---------------------------------------------------------------- arrays against scalar calls

def same_point(grid, index, point):
    """Every field of the grid's point `index` is the scalar call's (the call's counts N and
    digits are one value for the whole grid), and so is every decimal string."""
    for name, kind, per_particle, _, is_input in pendavg.Averages.fields():
        at_grid, alone = getattr(grid, name), getattr(point, name)
        if is_input and kind == "count" or alone is None:
            assert at_grid == alone, name
            continue
        np.testing.assert_array_equal(np.asarray(at_grid)[index], alone, name)
    assert point.decimal.keys() == grid.decimal.keys()
    for key in point.decimal:
        assert list(np.atleast_1d(grid.decimal[key][index])) == \
            list(np.atleast_1d(point.decimal[key])), key


def test_array_calls_equal_scalar_calls_element_by_element():
    beta = np.logspace(-3, 3, 7)
    l2 = np.array([0.1, 1.0, 10.0])
    grid = pendavg.average([0.3, 0.7], [1.0, l2[None, :]], beta[:, None])
    assert grid.shape == (7, 3) and grid.beta_K.shape == (7, 3, 2)
    for b in range(7):
        for k in range(3):
            same_point(grid, (b, k), pendavg.average([0.3, 0.7], [1.0, l2[k]], beta[b]))
    one_axis = pendavg.average([0.5, 0.5], [1, 1], beta)
    assert one_axis.beta_K.shape == (7, 2)
    for b in range(7):
        same_point(one_axis, b, pendavg.average([0.5, 0.5], [1, 1], beta[b]))


def test_array_calls_any_n_and_mpfr():
    beta = [0.5, 2.0]
    grid = pendavg.average([1, 1, 1], [1, 1, 1], beta, tol=1e-10)
    for b in range(2):
        same_point(grid, b, pendavg.average([1, 1, 1], [1, 1, 1], beta[b], tol=1e-10))
    grid = pendavg.average(["0.4", "0.6"], [1, 1], ["0.1", "1", "10"], digits=30)
    for b, beta_text in enumerate(["0.1", "1", "10"]):
        point = pendavg.average(["0.4", "0.6"], [1, 1], beta_text, digits=30)
        same_point(grid, b, point)
        assert [m[b] for m in [grid.mpf["beta_K"][:, 0]]] == [point.mpf["beta_K"][0]]


def test_broadcast_errors_name_the_point():
    with pytest.raises(ValueError, match=r"^index \(2,\): beta: '-1.0' must be > 0$"):
        pendavg.average([0.5, 0.5], [1, 1], np.array([1.0, 2.0, -1.0]))
    with pytest.raises(ValueError, match="2 masses but 1 lengths"):
        pendavg.average([0.5, 0.5], [1], np.array([1.0, 2.0]))


# ---------------------------------------------------------------- error kinds

def test_error_kinds():
    assert pendavg.average([0.5, 0.5], [1, 1], 1).beta_K_error_kind == "estimate"
    series = pendavg.average([0.9, 0.1], [1, 1], 1, method="series")
    assert series.beta_K_error_kind == "bound" and series.ratio_error_kind == "bound"
    assert series.cos_phi_error_kind == "estimate"  # the series' <cos phi_i>: a quadrature
    qmc = pendavg.average([1] * 5, [1] * 5, 1, method="qmc", samples=1024)
    assert qmc.method == "qmc" and qmc.beta_K_error_kind == "statistical"
    assert qmc.run["points"] == 1024 and qmc.run["shifts"] == 16
    transfer = pendavg.average([1] * 5, [1] * 5, 1)
    assert transfer.method == "transfer" and transfer.beta_K_error_kind == "estimate"
    assert transfer.run["angle_nodes"] >= 16 and transfer.run["pivot_nodes"] >= 3
    assert transfer.run["levels"] >= 2
    torus = pendavg.average([1] * 3, [1] * 3, 1)
    assert torus.beta_K_error_kind == "estimate" and torus.run["points_per_dim"] > 0
    assert pendavg.limit([0.5, 0.5]).high_temperature.beta_K_error_kind == "bound"
    assert pendavg.limit([0.5, 0.5]).low_temperature.beta_K_error_kind == "bound"
    for r in (series, qmc, transfer, torus):
        assert np.all(r.beta_K_error > 0) and np.all(r.beta_Kc == 0.5)


# ---------------------------------------------------------------- bad input

BAD = [  # (python call, the CLI's arguments): the same one-line message
    (lambda: pendavg.microcanonical([1, 1], [1, 1], 0, samples=1024), "average --masses 1,1 --lengths 1,1 --energy 0 --samples 1024"),
    (lambda: pendavg.microcanonical([1] * 5, [1] * 5, 0, tol=1e-5), "average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --tol 1e-5"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], 0, method="series"), "average --masses 1,1 --lengths 1,1 --energy 0 --method series"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], excitation=-1), "average --masses 1,1 --lengths 1,1 --excitation -1"),
    (lambda: pendavg.microcanonical([1] * 5, [1] * 5, 0, digits=30), "average --masses 1,1,1,1,1 --lengths 1,1,1,1,1 --energy 0 --digits 30"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], 0, method="qmc", digits=20), "average --masses 1,1 --lengths 1,1 --energy 0 --method qmc --digits 20"),
    (lambda: pendavg.microcanonical([1] * 3, [1] * 3, 0, method="torus-trapezoid", digits=20), "average --masses 1,1,1 --lengths 1,1,1 --energy 0 --method torus-trapezoid --digits 20"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], 0, tol=1e-20, digits=30), "average --masses 1,1 --lengths 1,1 --energy 0 --tol 1e-20 --digits 30"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], 0, digits=15), "average --masses 1,1 --lengths 1,1 --energy 0 --digits 15"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], "-3", digits=30), "average --masses 1,1 --lengths 1,1 --energy -3 --digits 30"),
    (lambda: pendavg.microcanonical([1, 1], [1, 1], excitation="0", digits=30), "average --masses 1,1 --lengths 1,1 --excitation 0 --digits 30"),
    (lambda: pendavg.microcanonical(["0", 1], [1, 1], 0, digits=30), "average --masses 0,1 --lengths 1,1 --energy 0 --digits 30"),
    (lambda: pendavg.microcanonical([1, 1], [1], 0, digits=30), "average --masses 1,1 --lengths 1 --energy 0 --digits 30"),
    (lambda: pendavg.average([0, 0.5], [1, 1], 1), "average --masses 0,0.5 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average([-1.0, 0.5], [1, 1], 1), "average --masses -1.0,0.5 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average([float("nan"), 0.5], [1, 1], 1), "average --masses nan,0.5 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average(["inf", 0.5], [1, 1], 1), "average --masses inf,0.5 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average(["1e400", 0.5], [1, 1], 1), "average --masses 1e400,0.5 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average(["0x1p3", 0.5], [1, 1], 1), "average --masses 0x1p3,0.5 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average([0.5, 0.5], [1, 0], 1), "average --masses 0.5,0.5 --lengths 1,0 --beta 1"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 0), "average --masses 0.5,0.5 --lengths 1,1 --beta 0"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], "nan", digits=30), "average --masses 0.5,0.5 --lengths 1,1 --beta nan --digits 30"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], ""), "average --masses 0.5,0.5 --lengths 1,1 --beta="),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 1, g=-1), "average --masses 0.5,0.5 --lengths 1,1 --beta 1 --g -1"),
    (lambda: pendavg.average([1, 1], [1], 1), "average --masses 1,1 --lengths 1 --beta 1"),
    (lambda: pendavg.average(["1.0x", 1], [1, 1], 1), "average --masses 1.0x,1 --lengths 1,1 --beta 1"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 1, digits=15), "average --masses 0.5,0.5 --lengths 1,1 --beta 1 --digits 15"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 1, digits=1001), "average --masses 0.5,0.5 --lengths 1,1 --beta 1 --digits 1001"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 1, digits=20.5), "average --masses 0.5,0.5 --lengths 1,1 --beta 1 --digits 20.5"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 1, method="simpson"), "average --masses 0.5,0.5 --lengths 1,1 --beta 1 --method simpson"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, method="series"), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method series"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, tol=0), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --tol 0"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, tol=1), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --tol 1"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, method="qmc", tol=1e-10), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method qmc --tol 1e-10"),
    (lambda: pendavg.average([0.5, 0.5], [1, 1], 1, tol=1e-10), "average --masses 0.5,0.5 --lengths 1,1 --beta 1 --tol 1e-10"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, tol=1e-10, digits=30), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --tol 1e-10 --digits 30"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, method="qmc", samples=1000), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method qmc --samples 1000"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, method="qmc", samples=4096.0), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method qmc --samples 4096.0"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, method="qmc", seed=-1), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --method qmc --seed=-1"),
    (lambda: pendavg.average([1] * 3, [1] * 3, 1, seed=2), "average --masses 1,1,1 --lengths 1,1,1 --beta 1 --seed 2"),
    (lambda: pendavg.average([1e-320, 1], [1, 1], 1), "average --masses 1e-320,1 --lengths 1,1 --beta 1"),
    (lambda: pendavg.limit([0, 1]), "limit --masses 0,1"),
    (lambda: pendavg.series([0.5, 0.5], [1, 1], 0, terms=3), "series --masses 0.5,0.5 --lengths 1,1 --beta 0 --terms 3"),
    (lambda: pendavg.series([0.5, 0.5], [1, 1], 1, terms=-1), "series --masses 0.5,0.5 --lengths 1,1 --beta 1 --terms=-1"),
    (lambda: pendavg.simulate([1, 1], [1, 1], time=1), "simulate --masses 1,1 --lengths 1,1 --time 1"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=0.0001), "simulate --masses 1,1 --lengths 1,1 --theta 1 --time 0.0001"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta="1x", time=1), "simulate --masses 1,1 --lengths 1,1 --theta 1x --time 1"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=1, integrator="euler"), "simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --integrator euler"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=1, beta=1), "simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --beta 1"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=1, thermostat="langevin"), "simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --thermostat langevin"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=1, seed=3), "simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --seed 3"),
    (lambda: pendavg.simulate([1, 1], [1, 1], phi=[1], time=1), "simulate --masses 1,1 --lengths 1,1 --phi 1 --time 1"),
    (lambda: pendavg.poincare([1, 1, 1], [1, 1, 1], -2), "poincare --masses 1,1,1 --lengths 1,1,1 --energy -2"),
    (lambda: pendavg.poincare([1, 1], [1, 1], -2, orbits=0), "poincare --masses 1,1 --lengths 1,1 --energy -2 --orbits 0"),
]


def python_spelling(message, args):
    """The CLI's message as the package words it: its options named as the package's arguments
    (--beta -> beta, --burn-in -> burn_in), and pendavg.microcanonical's without the CLI's
    command ("average: "). simulate and poincare keep the CLI's words (their own conversion is
    pending)."""
    command = args.split()[0]
    if command in ("simulate", "poincare"):
        return message
    if command == "average" and ("--energy" in args or "--excitation" in args):
        message = message.removeprefix("average: ")
    return re.sub(r"--([a-z][a-z-]*)", lambda m: m.group(1).replace("-", "_"), message)


@pytest.mark.parametrize("call, args", BAD, ids=[b[1] for b in BAD])
def test_bad_input_raises_the_cli_message(call, args):
    """The same one-line refusal as the CLI's, spelled with the package's argument names."""
    done = cli(*args.split())
    assert done.returncode == 2 and done.stdout == ""
    message = done.stderr.strip()
    assert message.startswith("pendavg: error: ")
    with pytest.raises(ValueError) as caught:
        call()
    assert str(caught.value) == python_spelling(message[len("pendavg: error: "):], args)
    if args.split()[0] not in ("simulate", "poincare"):
        assert "--" not in str(caught.value)


def test_number_types_are_read_exactly_with_their_sign():
    """An mpmath.mpf is read by its exact binary value, sign included (as the equal float or
    decimal string), in double and in MPFR; a negative one is refused as the CLI refuses it."""
    mpmath = optional_module("mpmath")
    from decimal import Decimal
    for digits in (16, 30):
        by_float = pendavg.microcanonical([1, 1], [1, 1], -1.25, digits=digits)
        for energy in (mpmath.mpf(-1.25), Decimal("-1.25"), "-1.25", -1.25):
            r = pendavg.microcanonical([1, 1], [1, 1], energy, digits=digits)
            assert r.energy == -1.25 and r.decimal["K"] == by_float.decimal["K"], energy
    tenth = pendavg.average([0.5, 0.5], [1, 1], mpmath.mpf(0.1), digits=30)
    assert tenth.decimal["beta_K"] == pendavg.average(
        [0.5, 0.5], [1, 1], "0.1000000000000000055511151231257827021181583404541015625",
        digits=30).decimal["beta_K"]
    swept = pendavg.sweep(beta=1, mu1=[mpmath.mpf(0.25), 0.25])
    np.testing.assert_array_equal(swept.beta_K[0], swept.beta_K[1])
    with pytest.raises(ValueError, match=r"^g: '-1' must be >= 0$"):
        pendavg.average([0.5, 0.5], [1, 1], 1, g=mpmath.mpf(-1))
    with pytest.raises(ValueError, match=r"^beta: '-5e-1' must be > 0$"):
        pendavg.average([0.5, 0.5], [1, 1], mpmath.mpf(-0.5), digits=20)


def test_nothing_crashes_on_odd_arguments():
    for call in (lambda: pendavg.average([], [], 1), lambda: pendavg.average([None], [1], 1),
                 lambda: pendavg.average([0.5, 0.5], [1, 1], [[1, 2], [3]]),
                 lambda: pendavg.average([0.5, 0.5], [1, 1], object()),
                 lambda: pendavg.average([0.5, 0.5], [1, 1], True)):
        with pytest.raises((ValueError, TypeError)):
            call()
    empty = pendavg.average([0.5, 0.5], [1, 1], np.zeros(0), digits=30)
    assert empty.shape == (0,) and empty.beta_K.shape == (0, 2) and empty.ratio.shape == (0,)
    assert empty.decimal["beta_K"].shape == (0, 2) and empty.mpf == {} and empty.method.shape == (0,)


# ---------------------------------------------------------------- dynamics

def test_simulate_agrees_with_cli():
    r = pendavg.simulate([1, 1], [1, 1], theta="90deg", time=20, every=1000)
    d = cli_json("simulate", "--masses", "1,1", "--lengths", "1,1", "--theta", "90deg", "--time", 20,
                 "--format", "json")
    # The CLI prints every value as the shortest text that reads back as the same double, and
    # every error with 3 digits, rounded up.
    for key in ("K", "Kc", "cos_phi", "K_deviation_sigmas", "exact_K", "exact_var_K"):
        assert list(getattr(r, key)) == d[key], key
    assert r.energy == d["energy"]
    assert r.exact_Kc == d["exact_Kc"] and r.exact_excitation == d["exact_excitation"]
    for key in ("K_error", "Kc_error", "exact_K_error", "exact_var_K_error"):
        for error, printed in zip(getattr(r, key), d[key]):
            assert error <= printed <= 1.01 * error, (key, error, printed)
    assert r.energy_error_max <= d["energy_error_max"] <= 1.01 * r.energy_error_max
    assert r.steps == d["steps"] and r.newton_solves == d["newton_solves"]
    assert r.exact_method == d["exact_method"] and not r.interrupted
    assert r.trajectory["phi"].shape == (21, 2) and r.trajectory["t"][-1] == pytest.approx(20)
    langevin = pendavg.simulate([1, 1], [1, 1], theta=0, time=10, thermostat="langevin", beta=2,
                                exact=False)
    d = cli_json("simulate", "--masses", "1,1", "--lengths", "1,1", "--theta", 0, "--time", 10,
                 "--thermostat", "langevin", "--beta", 2, "--exact", "no", "--format", "json")
    assert list(langevin.K) == d["K"] and d["exact_K"] == [None, None]
    assert langevin.exact_K is None and langevin.ensemble == "canonical"


def test_microcanonical_is_simulates_exact_reference():
    s = pendavg.simulate([1, 1], [1, 1], theta="90deg", time=1)  # E ~ 0
    m = pendavg.microcanonical([1, 1], [1, 1], excitation=s.exact_excitation)
    np.testing.assert_array_equal(m.K, s.exact_K)
    np.testing.assert_array_equal(m.var_K, s.exact_var_K)
    assert m.K_error_kind == "estimate" and m.converged
    by_energy = pendavg.microcanonical([1, 1], [1, 1], s.energy)  # E from the state: the same shell
    np.testing.assert_allclose(by_energy.K, s.exact_K, rtol=0, atol=2 * max(s.exact_K_error))


def test_microcanonical_agrees_with_cli():
    for state, value in (("energy", "-2.99999999"), ("excitation", "1e-8"), ("energy", "0")):
        m = pendavg.microcanonical([1, 0.3], [1.3, 0.6], g=9.81, **{state: value})
        d = cli_json("average", "--masses", "1,0.3", "--lengths", "1.3,0.6", "--g", "9.81",
                     f"--{state}", value, "--format", "json")
        for key in ("K", "cos_phi", "var_K"):
            assert getattr(m, key).tolist() == d[key], key  # the same doubles
        assert m.excitation == d["excitation"] and m.energy == d["energy"]
        assert m.method == d["method"] and m.ensemble == d["ensemble"] == "microcanonical"
        assert m.converged == d["converged"]
    with pytest.raises(ValueError, match="one of energy and excitation"):
        pendavg.microcanonical([1, 1], [1, 1], -1, excitation=1)
    with pytest.raises(ValueError, match="at or below the minimum energy"):
        pendavg.microcanonical([1, 1], [1, 1], -3)


@pytest.mark.parametrize("masses, lengths, state", [
    (["1", "1"], ["1", "1"], {"energy": "0", "digits": 30}),
    (["1", "0.3"], ["1.3", "0.6"], {"g": "9.81", "excitation": "1e-8", "digits": 25}),
    ([1, 0.3], [1.3, 0.6], {"g": 9.81, "energy": -2.99999999, "digits": 17}),   # floats as typed
    (["1", "1"], ["1", "1"], {"energy": "0", "digits": 20, "method": "torus-trapezoid"}),
    ([1.0, 1.0], [1.0, 1.0], {"energy": 0.5}),                                     # double
    ([1.0] * 5, [1.0] * 5, {"energy": 0.0, "samples": 1024}),                      # qmc, double
])
def test_microcanonical_digits_agree_with_cli(masses, lengths, state):
    """pendavg.microcanonical(..., digits=D) is `pendavg average --energy E --digits D`, field for
    field and digit for digit (.decimal), and .mpf holds the exact values the strings round."""
    m = pendavg.microcanonical(masses, lengths, **state)
    args = ["average", "--masses", ",".join(map(text, masses)), "--lengths",
            ",".join(map(text, lengths))]
    for name, value in {"g": 1.0, **state}.items():  # (the module's default g, as its text)
        args += [f"--{name}", text(value)]
    d = cli_text_json(*args, "--format", "json")
    assert_same_as_cli(m, d)
    assert (m.proposal_beta is None) == (m.method != "qmc")  # qmc's proposal only
    if m.digits == 16:
        return
    mpmath = optional_module("mpmath")
    exact = m.mpf
    with mpmath.workdps(m.digits + 20):
        for key in ("K", "cos_phi", "var_K"):
            for value, printed in zip(exact[key], m.decimal[key]):
                assert abs(value - mpmath.mpf(printed)) <= abs(value) * mpmath.mpf(10) ** (1 - m.digits)
    np.testing.assert_array_equal(m.K, [float(x) for x in exact["K"]])  # the doubles round them


def test_microcanonical_threads_mixing_digits_give_the_serial_bits():
    calls = [(energy, digits) for digits in (16, 20, 30) for energy in ("-1", "0.5")]

    def run(call):
        energy, digits = call
        r = pendavg.microcanonical(["1", "0.5"], ["1", "2"], energy, digits=digits)
        return r.decimal, r.K.tolist(), r._exact_values()

    serial = [run(call) for call in calls]
    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        assert list(pool.map(run, calls * 2)) == serial * 2


def test_poincare_agrees_with_cli():
    p = pendavg.poincare([1, 1], [1, 1], -2, orbits=2, points=5)
    out = cli("poincare", "--masses", "1,1", "--lengths", "1,1", "--energy", -2, "--orbits", 2,
              "--points", 5).stdout
    rows = list(csv.DictReader(l for l in out.splitlines() if l and not l.startswith("#")))
    assert len(rows) == len(p.phi2) == 10
    for k, row in enumerate(rows):  # the shortest text that reads back as the same double
        assert int(row["orbit"]) == p.orbit[k]
        assert float(row["phi2"]) == p.phi2[k] and float(row["p2"]) == p.p2[k]


def test_keyboard_interrupt_stops_simulate_with_the_averages_so_far():
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    fractions = []
    start = time.monotonic()
    timer.start()
    try:
        r = pendavg.simulate([1, 1, 1], [1, 1, 1], theta="90deg", time=1e6, exact=False,
                             progress=fractions.append)
    finally:
        timer.cancel()
    assert time.monotonic() - start < 10
    assert r.interrupted and 0 < r.time < 1e6 and r.steps > 0
    assert np.all(np.isfinite(r.K)) and np.all(r.K > 0)
    assert fractions and fractions == sorted(fractions) and fractions[-1] < 1


def test_keyboard_interrupt_stops_an_array_call():
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt):
            pendavg.average([0.5, 0.5], [1, 1], np.linspace(0.5, 2, 20000), digits=60)
    finally:
        timer.cancel()
    assert time.monotonic() - start < 10
    assert pendavg.average([0.5, 0.5], [1, 1], 1).beta_K[0] > 0  # still usable


def test_keyboard_interrupt_stops_a_torus_run_after_a_level():
    reference = pendavg.average([1] * 4, [1] * 4, 1.0)
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
    levels = []
    start = time.monotonic()
    timer.start()
    try:
        r = pendavg.average([1] * 4, [1] * 4, 1.0, digits=20, progress=levels.append)  # ~1 min
    except KeyboardInterrupt:  # stopped before the first level finished
        r = None
    finally:
        timer.cancel()
    assert time.monotonic() - start < 30 and levels
    if r is not None:  # the last finished level, with errors that still cover
        assert r.interrupted and not r.converged
        assert np.all(np.abs(r.beta_K - reference.beta_K) <= r.beta_K_error + reference.beta_K_error)


def test_progress_of_a_grid():
    fractions = []
    pendavg.average([0.5, 0.5], [1, 1], np.logspace(-2, 2, 50), digits=30, progress=fractions.append)
    assert fractions[-1] == 1.0 and fractions == sorted(fractions)


def test_progress_callback_errors_propagate():
    def fail(fraction):
        raise RuntimeError("stop here")
    with pytest.raises(RuntimeError, match="stop here"):
        pendavg.simulate([1, 1], [1, 1], theta=1, time=1e5, exact=False, progress=fail)


# ---------------------------------------------------------------- threads

def test_threads_mixing_digits_give_the_serial_bits():
    calls = [(["0.5", "0.5"], ["1", "1"], beta, digits)
             for digits in (16, 30, 60) for beta in ("0.3", "1", "7")]
    calls += [([1], [1], "1", 20), ([1, 1, 1], [1, 1, 1], "2", 16)]

    def run(call):
        masses, lengths, beta, digits = call
        r = pendavg.average(masses, lengths, beta, digits=digits)
        return r.decimal, r.beta_K.tolist()

    serial = [run(call) for call in calls]
    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        for _ in range(2):
            assert list(pool.map(run, calls * 2)) == serial * 2


def test_grid_calls_from_threads():
    beta = np.logspace(-1, 1, 16)
    reference = pendavg.average([0.5, 0.5], [1, 1], beta).beta_K
    with concurrent.futures.ThreadPoolExecutor(max_workers=3) as pool:
        for result in pool.map(lambda _: pendavg.average([0.5, 0.5], [1, 1], beta).beta_K, range(6)):
            np.testing.assert_array_equal(result, reference)


# ---------------------------------------------------------------- documentation

PUBLIC_FUNCTIONS = [name for name in pendavg.__all__ if inspect.isfunction(getattr(pendavg, name))]


def documented_arguments(doc):
    """The names the docstring's 'Arguments:' section explains, one entry per line (six spaces
    of indent, then the name)."""
    assert "\n    Arguments:\n" in doc
    section = doc.split("\n    Arguments:\n", 1)[1]
    return re.findall(r"^ {6}(\w+) ", section, re.M)


@pytest.mark.parametrize("name", PUBLIC_FUNCTIONS)
def test_help_explains_every_argument(name):
    """help(pendavg.<function>) explains each argument of the signature, by name, in its
    Arguments section, and explains no argument the function does not have."""
    function = getattr(pendavg, name)
    parameters = list(inspect.signature(function).parameters)
    assert documented_arguments(function.__doc__) == parameters


def test_every_public_function_is_documented():
    assert set(PUBLIC_FUNCTIONS) == {"average", "sweep", "limit", "series", "microcanonical",
                                     "simulate", "poincare"}
    assert pendavg.dynamics_instruction_set.__doc__.count("x86-64-v3") >= 1
    for name in pendavg.__all__:
        assert len(getattr(pendavg, name).__doc__.strip()) > 40, name


def test_quickstart_reproduces_fig5(tmp_path):
    optional_module("matplotlib")
    out = tmp_path / "fig5.png"
    subprocess.run([sys.executable, os.path.join(ROOT, "tables", "examples", "quickstart.py"),
                    str(out)], check=True, capture_output=True)
    assert out.stat().st_size > 10000
    # its curve is the paper's Fig. 5 as the main job tabulates it (tables/beta_sweep.csv)
    with open(os.path.join(ROOT, "tables", "beta_sweep.csv")) as fh:
        rows = [row for row in csv.DictReader(line for line in fh if not line.startswith("#"))
                if row["m1"] == "0.5" and row["l2"] == "1"]
    assert len(rows) == 61
    r = pendavg.average([0.5, 0.5], [1, 1], [row["beta"] for row in rows])
    for row, value, error in zip(rows, r.beta_K, r.beta_K_error):
        for i in range(2):
            assert abs(value[i] - float(row[f"beta_K{i + 1}"])) <= error[i] + float(row[f"beta_K{i + 1}_error"])
