# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/golden/show.py -- prints a result of the pendavg Python module for the golden cases
(golden.py runs a case's `python` line with `show` and `pendavg` imported): its repr, then every
field of to_dict() in order, arrays as lists of their full-precision values, then the decimal
strings of a result that has them (Averages.decimal: the CLI's digits)."""


def plain(value):
    """Arrays as lists (numpy prints arrays with 8 digits); everything else as it is."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value


def show(result):
    print(repr(result))
    if hasattr(result, "high_temperature"):  # Limits: a named tuple of two Averages
        for name in result._fields:
            print(f"[{name}]")
            show(getattr(result, name))
        return
    for key, value in result.to_dict().items():
        print(f"{key}: {plain(value)!r}")
    if hasattr(result, "decimal"):
        for key, value in result.decimal.items():
            print(f"decimal {key}: {value!r}")


def refusal(call):
    """What the module raises for bad input: the exception's type and message."""
    try:
        result = call()
    except Exception as error:  # noqa: BLE001 -- any exception is what is pinned
        print(f"{type(error).__name__}: {error}")
    else:
        print(f"no exception: {result!r}")
