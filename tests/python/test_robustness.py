# SPDX-License-Identifier: GPL-3.0-or-later
"""The Python module fails closed: every bad argument of every public function is a ValueError or
a TypeError whose one-line message names the argument (never a RuntimeError, a hang or a silent
NaN); decimal strings do not follow the locale; mpmath.mpf inputs of any exponent are read
quickly and as the CLI reads the same number.

Run as tests/CMakeLists.txt runs tests/python (PENDAVG_TEST_STRICT=1: nothing is skipped).
"""
import inspect
import locale
import math
import os
import subprocess
import sys
import time
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

import pendavg

from test_pendavg import STRICT, cli, cli_json, optional_module

# ---------------------------------------------------------------- bad arguments, every function

# A valid, quick call of every public function; each test below replaces one argument.
GOOD = {
    "average": dict(masses=[0.5, 0.5], lengths=[1, 1], beta=1.0),
    "sweep": dict(beta=[0.5, 1.0]),
    "limit": dict(masses=[0.5, 0.5], lengths=[1, 1]),
    "series": dict(masses=[0.5, 0.5], lengths=[1, 1], beta=1.0, terms=3),
    "microcanonical": dict(masses=[1, 1], lengths=[1, 1], energy=0.5),
    "simulate": dict(masses=[1, 1], lengths=[1, 1], theta=0.5, time=0.01, exact=False),
    "poincare": dict(masses=[1, 1], lengths=[1, 1], energy=-2, orbits=1, points=1),
}

MEGABYTE = "1" * 1_000_000
NEVER = [float("nan"), float("inf"), -float("inf"), "abc", object(), 1 + 1j, b"1", MEGABYTE,
         {"a": 1}, "\ud800", "1\x002", "1\n2"]

# Per argument: values that are valid there (skipped), and values that are bad only there.
VALID_THERE = {
    "g": [0], "theta": [-1, 0], "phi": [-1, 0], "phidot": [-1, 0], "energy": [-1, 0],
    "terms": [0], "seed": [0], "burn_in": [0],
}
# Arguments that only some methods or modes take: a value there is refused as "not used"
# (also a ValueError naming it), which the sweep accepts as a refusal of the bad value.
NUMBER_LIKE = {"masses", "lengths", "beta", "g", "digits", "tol", "samples", "shifts", "seed",
               "terms", "energy", "excitation", "theta", "phi", "phidot", "time", "dt",
               "burn_in", "friction", "every", "orbits", "points", "mu1", "l1", "l2"}
POSITIVE = {"masses", "lengths", "beta", "digits", "tol", "samples", "shifts", "time", "dt",
            "friction", "every", "orbits", "points", "mu1", "l1", "l2", "excitation"}
INTEGER = {"digits", "samples", "shifts", "terms", "every", "orbits", "points", "seed"}


def bad_values(function, name):
    values = list(NEVER)
    default = inspect.signature(getattr(pendavg, function)).parameters[name].default
    if default is not None:  # None is "not given" where it is the default
        values.append(None)
    if name in NUMBER_LIKE:
        values += [[], np.zeros(0)] if name in ("masses", "lengths") else []
        if name in POSITIVE:
            values += [-1, 0, "-1e-5000"]
        if name in INTEGER:
            values += [10 ** 30, 2.5, -(10 ** 30)]
        else:
            values += [10 ** 5000 if name != "mu1" else 2]  # beyond double's range
        if name == "mu1":
            values += [1, "1e-5000"]  # m2 = 1 - mu1 would need 5000 digits
    else:  # method, integrator, thermostat, exact, progress: names or callables
        values += [5, 2.5]
    return [v for v in values if not any(v is w or (type(v) is type(w) and v == w)
                                         for w in VALID_THERE.get(name, []))]


# The functions whose messages name the package's arguments (beta: ...); simulate and poincare
# still word theirs as the CLI does (--beta: ...).
PYTHON_NAMES = {"average", "sweep", "limit", "series", "microcanonical"}


def names_the_argument(message, name, function):
    if function in PYTHON_NAMES:  # the argument's own name, no option of the CLI
        return name in message and "--" not in message
    return any(s in message for s in (name, "--" + name.replace("_", "-")))


def in_range_there(function, value):
    """series runs in MPFR, where 1.1e999999 and 1e5000 are numbers."""
    return function == "series" and (value is MEGABYTE or isinstance(value, int) and
                                     value > 10 ** 100)


CASES = [(function, name, value)
         for function in GOOD
         for name in inspect.signature(getattr(pendavg, function)).parameters
         for value in bad_values(function, name) if not in_range_there(function, value)]


def case_id(case):
    function, name, value = case
    if isinstance(value, int) and value.bit_length() > 1000:
        shown = "huge-int"
    else:
        shown = repr(value) if len(repr(value)) < 20 else type(value).__name__
    return f"{function}-{name}-{shown}"


@pytest.mark.parametrize("function, name, value", CASES, ids=[case_id(c) for c in CASES])
def test_every_bad_argument_is_a_value_or_type_error_naming_it(function, name, value):
    arguments = dict(GOOD[function])
    arguments[name] = value
    if function == "microcanonical" and name == "excitation":
        del arguments["energy"]
    if function == "simulate" and name in ("phi", "phidot"):
        del arguments["theta"]
        arguments.setdefault("phi", [0.5, 0.5])
        arguments[name] = value
    if function == "simulate" and name in ("beta", "friction"):
        arguments["thermostat"] = "langevin"
        arguments.setdefault("beta", 1)
        arguments[name] = value
    start = time.monotonic()
    with pytest.raises((ValueError, TypeError)) as caught:
        getattr(pendavg, function)(**arguments)
    assert time.monotonic() - start < 10
    message = str(caught.value)
    assert type(caught.value) in (ValueError, TypeError), type(caught.value)
    assert "\n" not in message and len(message) < 400, message[:500]
    assert names_the_argument(message, name, function), message


def test_huge_digits_is_a_value_error_not_a_runtime_error():
    """digits = 10**30 was a RuntimeError (pybind11's failed cast)."""
    for function in ("average", "limit", "series", "microcanonical"):
        with pytest.raises(ValueError, match=r"^digits: '1000000000000000000000000000000' is "
                                             r"not an integer in 16\.\.1000$"):
            getattr(pendavg, function)(**GOOD[function], digits=10 ** 30)


def test_a_megabyte_number_is_not_echoed_whole():
    with pytest.raises(ValueError) as caught:
        pendavg.average([0.5, 0.5], [1, 1], "1" * 1_000_000)  # beyond double's range
    message = str(caught.value)
    assert message.startswith("beta: '1111") and "(1000000 characters)" in message
    assert len(message) < 200
    with pytest.raises(ValueError, match=r"^masses: malformed number '1x{39}\.\.\.x{16}' "
                                         r"\(1000001 characters\) \(expected"):
        pendavg.average(["1" + "x" * 1_000_000, 1], [1, 1], 1)


def test_texts_that_cannot_be_read_are_one_line_value_errors():
    """A lone surrogate was a RuntimeError (pybind11's failed cast); a NUL cut the message short
    (it ended the C string); a newline made it two lines."""
    with pytest.raises(ValueError, match=r"^beta: the text is not valid Unicode"):
        pendavg.average([0.5, 0.5], [1, 1], "\ud800")
    with pytest.raises(ValueError, match=r"^method: the text is not valid Unicode"):
        pendavg.average([0.5, 0.5], [1, 1], 1, method="\ud800")
    with pytest.raises(ValueError, match=r"^g: the text holds a NUL character$"):
        pendavg.average([0.5, 0.5], [1, 1], 1, g="1\x002")
    with pytest.raises(ValueError, match=r"^beta: malformed number '1\\x0a2' \(expected a finite "
                                         r"decimal number\)$"):
        pendavg.average([0.5, 0.5], [1, 1], "1\n2")


def test_a_long_text_is_shortened_between_characters():
    with pytest.raises(ValueError, match=r"^beta: malformed number 'é{20}\.\.\.é{8}' \(100 "
                                         r"characters\)"):
        pendavg.average([0.5, 0.5], [1, 1], "é" * 100)  # 2 bytes each: 40 + 16 bytes shown


@pytest.mark.parametrize("call, args", [
    (lambda: pendavg.poincare([1, 1], [1, 1], "1e999"),
     "poincare --masses 1,1 --lengths 1,1 --energy 1e999"),
    (lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=1, dt="1e-999"),
     "simulate --masses 1,1 --lengths 1,1 --theta 1 --time 1 --dt 1e-999"),
], ids=["poincare", "simulate"])
def test_double_only_functions_do_not_advise_digits(call, args):
    """simulate and poincare take no digits: a number beyond double's range is refused with the
    CLI's message for them, without its '(use --digits > 16)'."""
    done = cli(*args.split())
    assert done.returncode == 2 and "use --digits" not in done.stderr
    with pytest.raises(ValueError) as caught:
        call()
    assert "pendavg: error: " + str(caught.value) == done.stderr.strip()


def test_odd_number_types():
    """Fractions and numpy scalars are numbers; a bool, a complex or a numpy array where a
    single number belongs is a TypeError naming the argument."""
    by_float = pendavg.average([0.5, 0.5], [1, 1], 0.25)
    for beta in (Fraction(1, 4), np.float32(0.25), np.float64(0.25), np.array(0.25),
                 Decimal("0.25")):
        np.testing.assert_array_equal(pendavg.average([0.5, 0.5], [1, 1], beta).beta_K,
                                      by_float.beta_K)
    for beta in (True, 1j, np.complex128(1)):
        with pytest.raises(TypeError, match="^beta: expected a"):
            pendavg.average([0.5, 0.5], [1, 1], beta)
    with pytest.raises(ValueError, match=r"^beta: not a rectangular array"):
        pendavg.average([0.5, 0.5], [1, 1], [[1, 2], [3]])
    with pytest.raises(ValueError, match=r"do not broadcast together \(beta \(2,\), g \(3,\)\)"):
        pendavg.average([0.5, 0.5], [1, 1], [1, 2], g=[1, 2, 3])
    with pytest.raises(TypeError, match="^progress: expected None, True or a callable"):
        pendavg.average([0.5, 0.5], [1, 1], 1, progress="yes")


# ---------------------------------------------------------------- results are finite

def test_a_non_finite_result_is_refused_not_returned():
    """The low-temperature limit of this chain had var_K_beta2 = nan (returned silently)."""
    try:
        lim = pendavg.limit([1e-300, 1e20], [1, 0.5])
    except ValueError as refused:
        # refused before the work by the domain module (src/domain.hpp), or after it by the
        # result check: either way one line, never a NaN
        assert ("not finite" in str(refused) or "below double's normal range" in str(refused)) \
            and "\n" not in str(refused)
        return
    for r in lim:  # the library now evaluates it: then every number is finite
        for name, value in r.to_dict().items():
            if isinstance(value, (float, np.ndarray)) and np.asarray(value).dtype.kind == "f":
                assert np.all(np.isfinite(value)), name


@pytest.mark.parametrize("call", [
    lambda: pendavg.average([0.5, 0.5], [1, 1], [0.5, 1, 2], digits=20),
    lambda: pendavg.average([1, 2, 0.5], [1, 0.5, 2], 0.7),
    lambda: pendavg.limit(["0.05", "0.95"], digits=20),
    lambda: pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=20),
    lambda: pendavg.microcanonical([1, 0.3], [1.3, 0.6], excitation="1e-8", digits=20),
    lambda: pendavg.simulate([1, 1], [1, 1], theta=1, time=0.5, exact=True),
], ids=["average-grid-mpfr", "average-n3", "limit", "series", "microcanonical", "simulate"])
def test_results_hold_finite_numbers_only(call):
    result = call()
    for r in (result if isinstance(result, tuple) else (result,)):
        for name, value in r.to_dict().items():
            if name in ("K_error", "Kc_error", "cos_phi_error", "K_autocorrelation_time",
                        "K_deviation_sigmas") and getattr(r, "error_reason", None):
                continue  # too short a run: NaN error bars, said by error_reason
            array = np.asarray(value) if isinstance(value, (float, np.ndarray)) else None
            if array is not None and array.dtype.kind == "f":
                assert np.all(np.isfinite(array)), name


@pytest.mark.parametrize("dt", [20, 0.3, 0.05])
def test_a_coarse_trajectory_is_finite_or_refused(dt):
    """Time steps up to and beyond the integrator's stability limit: the run either stays
    finite or is refused with one line, never returns NaN averages."""
    try:
        r = pendavg.simulate([1, 1], [1, 1], theta=3, time=200, dt=dt, exact=False)
    except ValueError as refused:
        assert "\n" not in str(refused) and ("dt" in str(refused) or "not finite" in str(refused))
        return
    assert np.all(np.isfinite(r.K)) and math.isfinite(r.energy_drift)


# ---------------------------------------------------------------- the locale

def usable_locale(name):
    old = locale.setlocale(locale.LC_NUMERIC)
    try:
        locale.setlocale(locale.LC_NUMERIC, name)
        return locale.localeconv()["decimal_point"] == ","
    except locale.Error:
        return False
    finally:
        locale.setlocale(locale.LC_NUMERIC, old)


def comma_locale():
    """A locale whose decimal point is ',' (under ctest made with Debian's localedef if the
    machine has none: system-wide, or else in a temporary directory named by LOCPATH)."""
    for name in ("de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", "de_DE", "nl_NL.UTF-8"):
        if usable_locale(name):
            return name
    if not STRICT:
        pytest.skip("no comma-decimal locale on this machine")
    made = subprocess.run(["localedef", "-i", "de_DE", "-f", "UTF-8", "de_DE.UTF-8"],
                          capture_output=True)
    if made.returncode != 0 or not usable_locale("de_DE.UTF-8"):  # not root: a private one
        import tempfile
        directory = tempfile.mkdtemp(prefix="pendavg-locale-")
        subprocess.run(["localedef", "-i", "de_DE", "-f", "UTF-8",
                        os.path.join(directory, "de_DE.UTF-8")], capture_output=True)
        os.environ["LOCPATH"] = directory  # glibc's setlocale reads it on every call
    if not usable_locale("de_DE.UTF-8"):
        pytest.fail("no comma-decimal locale, and localedef could not make de_DE.UTF-8")
    return "de_DE.UTF-8"


def test_decimal_strings_do_not_follow_the_locale():
    """Under a locale with a decimal comma (LC_NUMERIC), the MPFR strings were '3,43...e-01' and
    the library's messages said '~5,56'."""
    name = comma_locale()
    calls = [
        lambda: pendavg.average(["0.5", "0.5"], [1, 1], "1", digits=20).decimal,
        lambda: pendavg.average([0.5, 0.5], [1, 1], 1).decimal,
        lambda: pendavg.average([0.5, 0.5], [1, 1], [1, 2], digits=25).decimal,
        lambda: pendavg.limit(["0.05", "0.95"], digits=20).high_temperature.decimal,
        lambda: pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=20).decimal,
        lambda: pendavg.microcanonical([1, 1], [1, 1], "0", digits=20).decimal,
    ]
    refusals = [  # the library's messages quote numbers too ("~5.56", "-3.000000")
        lambda: pendavg.simulate([1, 1], [1, 1], theta=3, time=200, dt=20, exact=False),
        lambda: pendavg.poincare([1, 1], [1, 1], -3.5),
    ]

    def message(call):
        with pytest.raises(ValueError) as caught:
            call()
        return str(caught.value)

    expected = [call() for call in calls]
    expected_messages = [message(call) for call in refusals]
    assert "~5.56" in expected_messages[0] and "= -3.000000" in expected_messages[1]
    old = locale.setlocale(locale.LC_NUMERIC)
    try:
        locale.setlocale(locale.LC_NUMERIC, name)
        assert locale.localeconv()["decimal_point"] == ","
        got = [call() for call in calls]
        assert [message(call) for call in refusals] == expected_messages
    finally:
        locale.setlocale(locale.LC_NUMERIC, old)

    def texts(d):
        for v in d.values():
            yield from (np.asarray(v, dtype=object).reshape(-1) if v is not None else [])

    for before, after in zip(expected, got):
        assert {k: np.asarray(v).tolist() for k, v in before.items()} == \
               {k: np.asarray(v).tolist() for k, v in after.items()}
        assert not any("," in t for t in texts(after) if t is not None)
    # the CLI itself, under the same locale (LC_ALL in its environment)
    env = dict(os.environ, LC_ALL=name)
    from test_pendavg import CLI
    out = subprocess.run([CLI, "average", "--masses", "0.5,0.5", "--lengths", "1,1", "--beta",
                          "1", "--digits", "20", "--format", "json"], env=env,
                         capture_output=True, text=True)
    assert out.returncode == 0
    import json, re
    for text in json.loads(out.stdout)["beta_K"]:
        assert re.fullmatch(r"\d\.\d{19}e[+-]\d\d", text), text


# ---------------------------------------------------------------- mpmath inputs

def results(decimal):
    """An Averages' decimal strings without its inputs' (an MPFR run prints those as written: a
    number given as an mpf and as its decimal text are the same number, written differently)."""
    inputs = {f[0] for f in pendavg.Averages.fields() if f[4]}
    return {k: v for k, v in decimal.items() if k not in inputs}


def test_mpf_with_a_huge_exponent_is_quick_and_read_as_the_cli_reads_it():
    """mpf('1e-100000000') hung (it built a 2e8-digit integer, deaf to Ctrl-C); mpf('1e-5000')
    failed on Python's 4300-digit limit although the CLI takes 1e-5000."""
    mpmath = optional_module("mpmath")
    for text, digits in (("1e-5000", 30), ("1e-100000000", 30), ("1e-5000", 17)):
        start = time.monotonic()
        r = pendavg.average([0.5, 0.5], [1, 1], mpmath.mpf(text), digits=digits)
        assert time.monotonic() - start < 5
        # the same value as the CLI's (the mpf is the 53-bit number nearest 10^-k, which rounds
        # to the CLI's 10^-k at these digits as well: both are the beta -> 0 limit to 30 digits)
        cli = cli_json("average", "--masses", "0.5,0.5", "--lengths", "1,1", "--beta", text,
                       "--digits", digits, "--format", "json")
        assert r.decimal["beta_K"] == cli["beta_K"]
    # exactness: below 10^-8500 the text is rounded, yet it reads back as the same binary number
    x = mpmath.mpf("1e-9000")
    exact = pendavg.average([0.5, 0.5], [1, 1], x, digits=40)
    text = mpmath.nstr(x, 60, min_fixed=1, max_fixed=0)  # 60 digits: x itself at 40 + 12
    assert results(exact.decimal) == results(  # K too (beta itself is printed as given)
        pendavg.average([0.5, 0.5], [1, 1], text, digits=40).decimal)
    # beyond MPFR's exponent range: refused with one line naming the argument, no hang
    huge = mpmath.mpf((0, 1, -(2 ** 40), 1))
    start = time.monotonic()
    with pytest.raises(ValueError, match=r"^beta: the number's binary exponent .* outside the "
                                         r"range of MPFR numbers"):
        pendavg.average([0.5, 0.5], [1, 1], huge, digits=30)
    assert time.monotonic() - start < 5
    # in double: the CLI's message for a number beyond double's range
    with pytest.raises(ValueError, match=r"^beta: '1000.*' \(11669 characters\) is out of the "
                                         r"range of double \(use digits > 16\)$"):
        pendavg.average([0.5, 0.5], [1, 1], mpmath.mpf("1e-5000"))


def test_number_texts_read_back_as_the_same_binary_number():
    """The text of an mpf or an int, read by mpmath's own parser (an independent reader) at the
    number's bit count, is the number itself: exactly (Fraction) while it is short, and after
    rounding at the number's precision beyond 1e-8600 / 1e20000."""
    mpmath = optional_module("mpmath")
    text_of = pendavg._pendavg.number_text
    cases = [mpmath.mpf(0.1), mpmath.mpf(-0.1), mpmath.mpf("1e-5000"), mpmath.mpf("3e300"),
             mpmath.mpf(2) ** -1074, mpmath.mpf(1) / 3]
    for x in cases:  # exact: the text is the binary value
        sign, man, exponent, bits = x._mpf_
        value = Fraction((-1) ** sign * man) * Fraction(2) ** exponent
        assert Fraction(Decimal(text_of(x, "x"))) == value, x
    with mpmath.workprec(300):
        cases = [mpmath.mpf("1e-100000000"), -mpmath.mpf("7e-9000"), mpmath.mpf("2.5e30000"),
                 mpmath.mpf(1) / 3 * mpmath.mpf(10) ** -50000]
    for x in cases:  # rounded text, same binary number
        bits = x._mpf_[3]
        start = time.monotonic()
        text = text_of(x, "x")
        assert time.monotonic() - start < 1 and len(text) < 2000
        with mpmath.workprec(bits):
            assert mpmath.mpf(text) == x, x
    for n in (10 ** 5000 + 7, -(2 ** 100), -(10 ** 19000) - 1):  # ints: exactly, past str()'s limit
        assert Fraction(Decimal(text_of(n, "x"))) == n


def test_mpf_exact_binary_value_at_every_digits():
    """An mpf is its binary value: mpf(0.1) is 0.1000000000000000055511151231257827..., at 17
    and at 1000 digits alike, and a sweep over mpf reads mu1 the same way."""
    mpmath = optional_module("mpmath")
    exact_tenth = "0.1000000000000000055511151231257827021181583404541015625"
    for digits in (17, 60, 1000):
        assert results(pendavg.average([0.5, 0.5], [1, 1], mpmath.mpf(0.1), digits=digits).decimal) \
            == results(pendavg.average([0.5, 0.5], [1, 1], exact_tenth, digits=digits).decimal)
    big = 10 ** 5000 + 1  # an int beyond str()'s 4300 digits, read exactly
    with pytest.raises(ValueError, match=r"^beta: '1000.*0001' \(5001 characters\) is out of "
                                         r"the range of double"):
        pendavg.average([0.5, 0.5], [1, 1], big)


def test_mpf_conversion_honours_ctrl_c():
    """A conversion is bounded (no multi-minute integer), so a Ctrl-C right after the call
    starts lands within seconds, in a subprocess that counts it."""
    optional_module("mpmath")
    code = ("import mpmath, pendavg, time, signal, threading, os\n"
            "threading.Timer(0.2, lambda: os.kill(os.getpid(), signal.SIGINT)).start()\n"
            "start = time.monotonic()\n"
            "try:\n"
            "    for _ in range(100000):\n"
            "        try:\n"
            "            pendavg.average([0.5, 0.5], [1, 1], mpmath.mpf('1e-100000000'))\n"
            "        except ValueError:\n"
            "            pass\n"
            "except KeyboardInterrupt:\n"
            "    print('interrupted', time.monotonic() - start)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stdout.startswith("interrupted"), done.stdout + done.stderr
    assert float(done.stdout.split()[1]) < 10
