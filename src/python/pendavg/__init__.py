# SPDX-License-Identifier: GPL-3.0-or-later
"""pendavg -- exact thermal averages of the kinetic energy in planar multiple pendulums.

A chain of N point masses m_1..m_N on massless rigid links of lengths l_1..l_N hangs from a fixed
pivot in uniform gravity g (Konishi & Yanagita, "Multiple pendulum and nonuniform distribution of
average kinetic energy"). In the canonical ensemble at inverse temperature beta the particles do
not share the kinetic energy equally: beta<K_i> depends on i, on the masses and lengths and on
beta g m l. pendavg computes beta<K_i>, <K_1>/<K_2>, <cos phi_i> and Var K_i exactly, to any number
of digits, each with an error that says what it promises (a rigorous bound, a refinement
estimate, or a statistical bar), the method used and the work done.

    >>> import pendavg
    >>> r = pendavg.average([0.5, 0.5], [1, 1], beta=1.0)      # double pendulum, beta = 1
    >>> r.beta_K, r.beta_K_error, r.beta_K_error_kind            # numpy arrays, 'estimate'
    >>> pendavg.average([0.5, 0.5], [1, 1], np.logspace(-3, 3, 61)).beta_K.shape   # (61, 2)
    >>> pendavg.average([0.5, 0.5], [1, 1], "1", digits=50).decimal["beta_K"]     # 50 digits

Functions: average (any N, one point or a numpy-broadcast grid on all cores), sweep (the double
pendulum over a grid of beta, mu1, l1, l2, g), limit (beta -> 0 and beta -> infinity), series
(the paper's series term by term), microcanonical (fixed energy), simulate (time averages along
a trajectory), poincare (the double pendulum's Poincare section).

Numbers. Every number argument may be a float, an int, a str holding a decimal ('0.1',
'1e-300'), a decimal.Decimal or an mpmath.mpf. It is read as the `pendavg` command reads the same
text: a float as its repr (the shortest decimal that gives it back, i.e. what you typed, so 0.1
means 1/10 also at 50 digits), a str exactly as written, an int exactly, an mpf by its exact
binary value (for |x| beyond about 1e-8600..1e20000 its text is rounded so that it reads back
as the same binary number whenever the working precision holds its bits; a binary exponent
outside MPFR's range is refused). No conversion builds a huge integer: every one is quick. With
digits = 16 (the default) everything runs in double and the results are the C++ library's doubles,
bit for bit; with digits = 17..1000 it runs in MPFR at digits + 12 guard digits, and the results
also come as the CLI's decimal strings (`.decimal`) and as mpmath.mpf values (`.mpf`).

Results. The result objects are generated from the output schema's field tables (the CLI's
JSON keys; Averages.fields() lists them): a value X comes with X_error (its absolute error) and
X_error_kind ('bound', 'estimate' or 'statistical'), the inputs N, digits, beta, g, m, l with
them. pendavg 0.2's names that schema 1 renamed (error, var_K_beta2, ...) still answer, with a
DeprecationWarning naming the new one.

Errors. Bad input raises ValueError with the CLI's one-line message, which names the argument
as this package names it (e.g. "beta: '0.0' must be > 0"; a long number text is shortened in
it); an argument of the
wrong type (None, a complex, a non-str method, a non-callable progress) raises TypeError naming
it. A result with a NaN or an infinity is refused (ValueError) rather than returned. Calls
release the GIL and are thread-safe at any mix of digits; array calls run on all cores. Ctrl-C
stops an array call (KeyboardInterrupt) and ends simulate/poincare early with the averages so
far (interrupted = True).

Notebooks. Every result converts: .to_dict(), .to_dataframe() (pandas) and, for Averages,
.to_xarray() (xarray); pandas and xarray are optional. sweep() results carry their axes:
.dims (the swept arguments, in order) and .coords (their values).

Decimal strings (.decimal) do not depend on the locale: the radix character is always '.'.
"""
import sys as _sys
import time as _time
import warnings as _warnings
from collections import namedtuple as _namedtuple

import numpy as _np

from . import _pendavg as _core
from ._pendavg import Averages, MicrocanonicalResult, SimulationResult

__version__ = _core.__version__
__all__ = ["average", "sweep", "limit", "series", "microcanonical", "simulate", "poincare",
           "Averages", "Limits", "SeriesResult", "MicrocanonicalResult", "SimulationResult",
           "PoincareSection", "dynamics_instruction_set"]

dynamics_instruction_set = _core.dynamics_instruction_set


# ---------------------------------------------------------------- canonical averages

def _flag(value, name):
    """A True/False argument: bool or numpy.bool_ only (not 0/1, None or strings)."""
    if isinstance(value, (bool, _np.bool_)):
        return bool(value)
    raise TypeError(f"{name} must be True or False, not {type(value).__name__}")


def _fields_doc(fields):
    """The fields of a result as docstring lines: '    - name: meaning', wrapped."""
    import textwrap
    lines = []
    for name, kind, per_particle, meaning, _ in fields:
        text = f"- {name}{' (per particle)' if per_particle else ''}: {meaning}"
        lines += textwrap.wrap(text, 96, initial_indent="    ", subsequent_indent="        ")
    return "\n".join(lines) + "\n"


def average(masses, lengths, beta, g=1.0, digits=16, method="auto", tol=None, samples=None,
            shifts=None, seed=None, progress=None, certified=False):
    """Canonical (thermal) averages of an N-link pendulum at inverse temperature beta.

    The chain: point masses m_i on massless rigid links l_i, the first hanging from a fixed
    pivot, in uniform gravity g; angles phi_i from the downward vertical; canonical ensemble
    exp(-beta H). Returns an Averages (index 0 of a per-particle field is the paper's particle 1)
    with the fields of `pendavg average --format json`:

<fields>
    and: seconds (the library call's wall time), run (the torus grid, the qmc run or the transfer
    operator's final resolution), decimal (the CLI's strings, `digits` digits), mpf (mpmath.mpf
    values: the exact binary values of the MPFR results), dims and coords (a grid's axis names
    and values: pendavg.sweep's swept arguments; a broadcast call's axis0, axis1, ... with
    positions). The methods: 'integral' (N = 2: the exact 1-D reduced integral), 'series' (the
    paper's series), 'torus-trapezoid', 'torus-gauss', 'qmc', 'transfer' (the transfer operator
    along the chain, N >= 5), 'low-temperature-extrapolation' (any N, very stiff joints). Error
    kinds: 'bound' (rigorous), 'estimate' (from quadrature refinement, checked against
    independent methods), 'statistical' (QMC: 99.9% Student-t bars). <K_i> and Var K_i of a double
    run are beta<K_i>/beta and beta^2 Var K_i/beta^2 divided in long double and rounded, their
    errors covering that rounding (a double run needs beta in 1.5e-154..1.3e154 for them; MPFR
    has no such limit).
    Conversions: to_dict(), to_dataframe() (pandas: a row per particle and grid point) and
    to_xarray() (xarray: dims + ('particle',)).

    Arguments:
      masses   the N masses m_i > 0 (a list, tuple or 1-D array; a single number is N = 1).
      lengths  the N link lengths l_i > 0.
      beta     inverse temperature 1/(k_B T) > 0, in units where m, l and g are as given (the
               natural scale is beta g m l).
      g        gravitational acceleration >= 0 (default 1); g = 0 is the free chain.
      digits   significant digits requested: 16 (default) runs in double; 17..1000 in MPFR.
      method   'auto' (default: 'integral' for N = 2, 'torus-trapezoid' for N = 1, 3, 4,
               'transfer' for N >= 5), 'integral' or 'series' (N = 2 only), 'torus-trapezoid'
               or 'torus-gauss' (any N, cost n^(N-1)), 'transfer' (any N <= 16384, double
               only), 'qmc' (any N <= 256, double only; the independent check).
      tol      torus methods in double: relative tolerance (default 1e-13; with digits > 16 it
               is 10^-digits and may not be given); transfer: relative tolerance (default
               1e-10).
      samples  qmc: lattice points per shift, a power of two in 1024..1048576 (default 65536).
      shifts   qmc: random shifts, 4..1024 (default 16).
      seed     qmc: seed of the shifts (default 1).
      progress None (silent), True (a line on stderr every 2 s, as the CLI) or a callable
               f(fraction) called from this thread: for one point the fraction of the current
               torus level (torus methods), for a grid the fraction of points done.
      certified  N = 2 (method 'auto' or 'integral'): certified enclosures (as `pendavg average
               --certified`): every error a proven bound (error kinds 'bound', method
               'certified-integral') for the inputs as converted (a float exactly; other
               numbers rounded to the working precision). Needs a build with Arb.
    An option the chosen method does not use is refused (ValueError), so a typo cannot silently
    change nothing. Ctrl-C: a torus run stops after its current level and returns the last
    finished one (interrupted = True; KeyboardInterrupt if none finished); a grid stops starting
    points and raises KeyboardInterrupt.

    Broadcasting. beta, g and every single mass or length may be a numpy array (or list); they
    are broadcast together (numpy rules) to a shape S, every point of S is computed on all cores
    with the GIL released, and per-particle fields come back with shape S + (N,), per-point
    fields (ratio, method, evaluations, ...) with shape S. Element k equals the scalar call with
    the k-th values, bit for bit. E.g. a (beta, l2) grid:
        pendavg.average([0.5, 0.5], [1, l2[None, :]], beta[:, None])   # shape (len(beta), len(l2), 2)
    (pendavg.sweep does the same from 1-D axes). A bad point raises ValueError naming its index.
    """
    callback = _progress_callback(progress, "average")
    certified = _flag(certified, "certified")
    result = _core.average_point(masses, lengths, beta, g, digits, method, tol, samples, shifts,
                                 seed, certified, callback)
    if result is not None:
        if result.interrupted:
            print("[average] interrupted: the last finished torus level is reported",
                  file=_sys.stderr, flush=True)
        return result
    m, l = _entries(masses), _entries(lengths)
    if len(m) != len(l):
        raise ValueError(f"{len(m)} masses but {len(l)} lengths")
    names = ["beta", "g"] + [f"masses[{i}]" for i in range(len(m))] + \
            [f"lengths[{i}]" for i in range(len(l))]
    columns = [_as_array(x, name) for x, name in zip([beta, g, *m, *l], names)]
    try:
        shape = _np.broadcast_shapes(*(c.shape for c in columns))
    except ValueError:
        shapes = ", ".join(f"{name} {c.shape}" for name, c in zip(names, columns) if c.ndim)
        raise ValueError(f"average: the array arguments do not broadcast together ({shapes})") \
            from None
    flat = [_np.ascontiguousarray(_np.broadcast_to(c, shape)).reshape(-1) for c in columns]
    return _core.average_grid(list(shape), len(m), flat, digits, method, tol, samples, shifts, seed,
                              certified, callback)


def sweep(beta, mu1=0.5, l1=1, l2=1, g=1.0, digits=16, method="auto", progress=None):
    """The double pendulum over every combination of the given values (as `pendavg table`).

    Masses m1 = mu1 and m2 = 1 - mu1 (total mass M = 1; 1 - mu1 is formed in exact decimal from
    the decimal of mu1, as `pendavg table --mu1` forms it, so 0.05 gives m2 = 0.95 exactly as
    typed), lengths l1, l2, gravity g, inverse temperature beta. Each argument is a number or a
    1-D array of values; the result is pendavg.average's Averages with one axis per array
    argument, in the order (beta, mu1, l1, l2, g), then the particle axis:

        r = pendavg.sweep(beta=np.logspace(-3, 3, 61), l2=np.logspace(-1, 1, 61))
        r.ratio.shape     # (61, 61): <K1>/<K2> over (beta, l2)
        r.beta_K.shape    # (61, 61, 2)

    Arguments:
      beta      inverse temperature(s) > 0: a number or a 1-D array.
      mu1       m1 / M, in (0, 1) (default 0.5): a number or a 1-D array; m2 = 1 - mu1.
      l1        length(s) of the first link > 0 (default 1).
      l2        length(s) of the second link > 0 (default 1).
      g         gravitational acceleration(s) >= 0 (default 1).
      digits    significant digits: 16 (default, double) or 17..1000 (MPFR), as for
                pendavg.average.
      method    'auto' (default: 'integral'), 'integral' or 'series', as for pendavg.average.
      progress  None, True or a callable f(fraction of points done), as for pendavg.average.
    The result also carries its axes: r.dims, the swept arguments in axis order (e.g. ('beta',
    'l2')), and r.coords, {name: the values swept (float64, or object if not floats)};
    r.to_dataframe() and r.to_xarray() label their rows and axes with them.
    """
    names = ["beta", "mu1", "l1", "l2", "g"]
    axes = [beta, mu1, l1, l2, g]
    domains = {"beta": "positive", "mu1": "positive", "l1": "positive", "l2": "positive",
               "g": "nonnegative"}
    arrays = [i for i, a in enumerate(axes) if _is_array(a)]
    shaped, coords = [], {}
    for i, a in enumerate(axes):
        if i not in arrays:
            shaped.append(a)
            continue
        # lists keep their Python numbers (str, int, Decimal, mpf: each read as typed)
        a = _np.asarray(a, dtype=object) if isinstance(a, (list, tuple, range)) else \
            _as_array(a, names[i])
        if a.ndim != 1:
            raise ValueError(f"sweep: {names[i]} must be a number or a 1-D array")
        coords[names[i]] = _coordinate(a)
        view = [1] * len(arrays)
        view[arrays.index(i)] = a.shape[0]
        shaped.append(a.reshape(view))
    # every value checked under its own name (a bad l1 is "l1: ...", not "lengths: ...")
    for name, axis in zip(names, axes):
        for value in (axis if _is_array(axis) else [axis]):
            _core.check_number(value, name, domains[name], digits)
    # m2 = 1 - mu1 in exact decimal, as `pendavg table` forms it (checked: 0 < mu1 < 1, at most
    # 4000 digits after the point)
    mu = shaped[1]
    if _is_array(mu):
        m1 = _np.vectorize(_mass_text, otypes=[object])(mu) if mu.size else mu.astype(object)
        m2 = _np.vectorize(lambda m: _core.one_minus_decimal(m, "mu1"), otypes=[object])(m1) \
            if mu.size else mu.astype(object)
    else:
        m1 = _mass_text(mu)
        m2 = _core.one_minus_decimal(m1, "mu1")
    result = average([m1, m2], [shaped[2], shaped[3]], shaped[0], shaped[4], digits=digits,
                     method=method, progress=progress)
    result._dims, result._coords = tuple(coords), coords
    return result


class Limits(_namedtuple("Limits", ["high_temperature", "low_temperature"])):
    """The beta -> 0 and beta -> infinity limits of a chain (pendavg.limit): two Averages
    without a beta (beta, and the fields divided by it, are None)."""

    __slots__ = ()

    def to_dict(self):
        """{'high_temperature': dict, 'low_temperature': dict} (Averages.to_dict)."""
        return {name: getattr(self, name).to_dict() for name in self._fields}

    def to_dataframe(self):
        """Both limits as one pandas DataFrame, indexed by (limit, particle). Needs pandas."""
        pandas = _optional("pandas", "to_dataframe")
        return pandas.concat({name: getattr(self, name).to_dataframe() for name in self._fields},
                             names=["limit"])


def limit(masses, lengths=None, g=1.0, digits=16, progress=None, certified=False):
    """The high- and low-temperature limits of beta<K_i>, <K1>/<K2>, beta^2 Var K_i, <cos phi_i>.

    beta -> 0: for N = 2 the paper's closed form beta<K_1> = (mu_1/2) K(k)/E(k), k^2 = mu_2 =
    m_2/M (eq. aveK1-beta0; error kind 'bound'); for any N the torus average of the same chain at
    g = 0 (trapezoid for N <= 5, transfer beyond, double only). <cos phi_i> -> 0. Independent of g.
    beta -> infinity: beta<K_i> -> 1/2 for every particle (equipartition of the harmonic chain),
    <cos phi_i> -> 1, beta^2 Var K_i -> tr(X_i(0)^2)/2, in closed form.

    Arguments:
      masses    the N masses m_i > 0, as for pendavg.average.
      lengths   the N link lengths l_i > 0 (default None: all 1).
      g         gravitational acceleration >= 0 (default 1), checked as `pendavg limit --g`
                checks it (beta -> 0 does not depend on it).
      digits    significant digits: 16 (default, double) or 17..1000 (MPFR; N >= 6 is double
                only, the transfer operator).
      progress  None, True (a line on stderr every 2 s) or a callable f(fraction) of the torus
                level of the beta -> 0 limit (N >= 3), as for pendavg.average.
      certified N = 2: the beta -> 0 limit in ball arithmetic, every error a proven bound (as
                `pendavg limit --certified`; the beta -> infinity limit is exact).
    Ctrl-C stops the torus run of N >= 3 after a finished level. Returns
    Limits(high_temperature, low_temperature), two Averages without beta (as `pendavg limit`:
    the fields divided by beta are None).
    """
    callback = _progress_callback(progress, "limit")
    high, low = _core.limit(masses, lengths, g, digits, _flag(certified, "certified"), callback)
    if high.interrupted:
        print("[limit] interrupted: the last finished torus level is reported", file=_sys.stderr,
              flush=True)
    return Limits(high, low)


# ---------------------------------------------------------------- series, microcanonical

class _Record:
    """A result that is a list of rows of one table after its call's fields (pendavg.series'
    terms, pendavg.poincare's crossings): every field an attribute, the call's as single values,
    the rows' as arrays (fields() lists them: the call's, then the rows')."""

    _index = None  # to_dataframe's index: a row field, or the name of the rows' positions

    def __init__(self, fields):
        self.__dict__.update(fields)

    def as_dict(self):
        """The fields as a dict."""
        return dict(self.__dict__)

    def to_dict(self):
        """The fields as a dict (numbers, numpy arrays, strings; as_dict)."""
        return self.as_dict()

    def to_dataframe(self):
        """The rows as a pandas DataFrame: a column per row field, then every single value of
        the call repeated on each row; indexed by a series' n, a section's crossing (0, 1, ...).
        Needs pandas."""
        pandas = _optional("pandas", "to_dataframe")
        call, rows = self.fields()[:2]
        columns = {f[0]: getattr(self, f[0]) for f in rows}
        count = len(columns[rows[0][0]])
        for name, _, per_particle, _, _ in call:
            if not per_particle:
                columns[name] = [getattr(self, name)] * count
        frame = pandas.DataFrame(columns)
        if self._index in columns:
            return frame.set_index(self._index)
        frame.index.name = self._index
        return frame

    def __repr__(self):
        shown = ", ".join(f"{k}={_short(v)}" for k, v in self.__dict__.items()
                          if not k.startswith("_") and k not in ("decimal", "exact"))
        return f"pendavg.{type(self).__name__}({shown})"


class SeriesResult(_Record):
    """The paper's series for beta<K_1> term by term (pendavg.series), from the output schema's
    series tables (SeriesResult.fields(): the call's, then its terms').

    The call's fields (single values; m and l per particle):
<call fields>
    The terms' fields (arrays, one entry per term n = 0, 1, ...):
<term fields>
    decimal: the CLI's strings of each term field (`pendavg series --format json`), exact and
    mpf: the exact MPFR values.
    """

    _index = "n"

    @staticmethod
    def fields():
        """(the call's fields, the terms' fields) as (name, kind, per_particle, meaning, input)
        tuples."""
        return _core.series_fields()

    @property
    def mpf(self):
        """Every term field as a list of mpmath.mpf (the exact MPFR values)."""
        return {name: [_to_mpf(x) for x in values] for name, values in self.exact.items()}


SeriesResult.__doc__ = SeriesResult.__doc__.replace(
    "<call fields>\n", _fields_doc(_core.series_fields()[0])).replace(
    "<term fields>\n", _fields_doc(_core.series_fields()[1]))


def series(masses, lengths, beta, g=1.0, digits=16, terms=0, progress=None):
    """The paper's series for beta<K_1> of the double pendulum, term by term (eq. ave-K1-result).

    beta<K_1> = (mu_1/2) sum_n c_n mu_2^n R_n / (R_0 - sum_{n>=1} d_n mu_2^n R_n) with the
    modified-Bessel moments R_n(a1, a2), a1 = beta M g l1, a2 = beta m2 g l2. After n terms both
    tails are bounded by c_{n+1} R_{n+1} mu_2^{n+1} / (1 - mu_2): every row carries a rigorous bound.
    Convergence is geometric in mu_2 = m_2/M, so a light first particle (small mu_1) needs many
    terms: prefer pendavg.average there.

    Arguments:
      masses    the two masses m_1, m_2 > 0 (N = 2 only).
      lengths   the two link lengths l_1, l_2 > 0.
      beta      inverse temperature > 0.
      g         gravitational acceleration >= 0 (default 1).
      digits    the requested digits, 16..1000 (the sums always run in MPFR, at digits + 12).
      terms     how many terms (0, the default: until the bound certifies the digits; refused
                before any work when that needs over 6000 terms).
      progress  None, True (a line on stderr every 2 s) or a callable f(fraction) of the
                Bessel table done, as for pendavg.average.
    Ctrl-C raises KeyboardInterrupt (no row exists before the table is complete). Returns a
    SeriesResult with the rows as arrays.
    """
    callback = _progress_callback(progress, "series")
    return SeriesResult(_core.series(masses, lengths, beta, g, digits, terms, callback))


def microcanonical(masses, lengths, energy=None, g=1.0, digits=16, method="auto", tol=None,
                   samples=None, shifts=None, seed=None, excitation=None):
    """Exact microcanonical averages <K_i>_E, <K_i^(c)>_E, <cos phi_i>_E, Var K_i at fixed energy.

    The values NVE time averages (pendavg.simulate without thermostat) must reproduce when the
    motion is ergodic. Energies use the paper's U = -sum_j g S_j l_j cos phi_j (S_j the mass at
    and below link j), so the hanging chain at rest has E_min = -sum_j g S_j l_j; E > E_min.
    Per angle configuration the momenta are uniform on the shell H = E; the angle integrals
    run over the reduced torus. The same call as `pendavg average --energy E
    | --excitation D [--digits D]`, with the CLI's checks, messages and strings.

    Arguments:
      masses      the N masses m_i > 0, as for pendavg.average.
      lengths     the N link lengths l_i > 0.
      energy      the energy E > E_min. Give one of energy and excitation: near the bottom of
                  the well an E in double carries only ~1e-16 |E_min| / D relative accuracy in
                  D, an excitation all of it.
      g           gravitational acceleration >= 0 (default 1).
      digits      significant digits requested: 16 (default) runs in double; 17..1000 in MPFR
                  at digits + 12 guard digits with tolerance 10^-digits, for the integral rule
                  (N <= 4) and torus-trapezoid (N <= 2); qmc is double only.
      method      'auto' (integral for N <= 4, qmc beyond), 'integral' (nested tanh-sinh, cut
                  at every singular point), 'torus-trapezoid' (a check; algebraic
                  convergence), 'qmc' (statistical bars, the 99.9% Student-t quantile of the
                  standard error over the shifts).
      tol         integral and torus-trapezoid in double: relative target (default 1e-13 for
                  N <= 2, 1e-11 for N = 3, 1e-9 beyond); with digits > 16 it is 10^-digits
                  and may not be given.
      samples     qmc: lattice points per shift, a power of two in 1024..65536 (default 16384).
      shifts      qmc: random shifts, 4..1024 (default 16).
      seed        qmc: seed of the shifts (default 1).
      excitation  the excitation D = E - E_min > 0, instead of energy (formed without
                  cancellation: the way to state a state near the bottom of the well).
    An option the chosen rule does not use is refused (ValueError, the CLI's message).
    Progress and Ctrl-C: this function reports no progress and cannot be stopped midway (it
    does not pass the library a RunControl yet); it runs with the GIL released, and a
    Ctrl-C raises KeyboardInterrupt when it returns.
    Returns a MicrocanonicalResult with the fields of `pendavg average --energy E --format json`:

<fields>
    and seconds, decimal (the CLI's strings) and mpf (exact mpmath values; both also in double).
    """
    return _core.microcanonical(masses, lengths, energy, g, digits, method, tol, samples, shifts,
                                seed, excitation)


# ---------------------------------------------------------------- dynamics

class PoincareSection(_Record):
    """The double pendulum's Poincare section phi_1 = 0, phidot_1 > 0 (pendavg.poincare), from
    the output schema's tables (PoincareSection.fields(): the section's, its crossings', its
    orbits' starts').

    The section's fields (single values; m and l per particle):
<call fields>
    The crossings' fields (arrays, one entry per crossing, grouped by orbit, in time order):
<crossing fields>
    The orbits' starts (arrays, one entry per orbit):
<start fields>
    seconds: the run's wall time; decimal: the CLI's strings of every number.
    """

    _index = "crossing"

    @staticmethod
    def fields():
        """(the section's fields, the crossings' fields, the orbit starts' fields) as (name,
        kind, per_particle, meaning, input) tuples."""
        return _core.poincare_fields()


PoincareSection.__doc__ = PoincareSection.__doc__.replace(
    "<call fields>\n", _fields_doc(_core.poincare_fields()[0])).replace(
    "<crossing fields>\n", _fields_doc(_core.poincare_fields()[1])).replace(
    "<start fields>\n", _fields_doc(_core.poincare_fields()[2]))


def simulate(masses, lengths, g=1.0, *, theta=None, phi=None, phidot=None, time, dt=None,
             burn_in=None, integrator=None, thermostat=None, beta=None, friction=None, seed=None,
             exact=True, every=None, progress=None):
    """Integrate the chain and return time averages with error bars beside the exact values.

    Fixed energy (NVE, default): RATTLE in Cartesian coordinates (constraints |r_i| = l_i, O(N)
    Newton multipliers) inside a symmetric composition -- integrator 'yoshida6' (default, 6th
    order, 7 stages), 'yoshida4' (the paper's), 'suzuki4', 'kahan-li6', 'rattle2' -- compared
    with the exact microcanonical averages at the run's energy. thermostat='langevin': constrained
    BAOAB Langevin dynamics at inverse temperature beta (friction gamma, default 1; seed of the
    noise, default 1) compared with the exact canonical averages.

    Arguments:
      masses      the N masses m_i > 0.
      lengths     the N link lengths l_i > 0.
      g           gravitational acceleration >= 0 (default 1).
      theta       start at rest with every angle theta (radians, or a str like '90deg'); give
                  theta or phi.
      phi         start at the N angles phi_i from the downward vertical (radians).
      phidot      the N initial angular velocities with phi (default 0).
      time        the averaging time T (required, keyword only).
      dt          time step (default 1e-3).
      burn_in     extra time integrated before the averaging starts (default 0).
      integrator  the NVE composition: 'yoshida6' (default), 'yoshida4', 'suzuki4',
                  'kahan-li6', 'rattle2' (not with thermostat='langevin').
      thermostat  None (NVE, default) or 'langevin' (constrained BAOAB).
      beta        Langevin: inverse temperature > 0 (required with it, refused without).
      friction    Langevin: friction gamma > 0 (default 1).
      seed        Langevin: seed of the noise (default 1).
      exact       compute the exact values to compare with (default True; N >= 5 uses QMC: a
                  few seconds).
      every       also return the trajectory t, E, phi_i, phidot_i every `every` steps (numpy
                  arrays); None (default): no trajectory.
      progress    None (silent), True (a line on stderr every 2 s, as the CLI) or a callable
                  f(fraction) called from this thread about every 1% of the run.

    The exact values are computed first (a request they cannot serve is refused before any
    integration). Ctrl-C (KeyboardInterrupt) ends the run cleanly: the averages of the run so far
    are returned with interrupted = True. Same checks and messages as `pendavg simulate`; in
    double.
    Returns a SimulationResult with the fields of `pendavg simulate --format json`:

<fields>
    and seconds (the run's wall time), trajectory (None, or the arrays t, E, phi (T, N) and
    phidot (T, N) every `every` steps), decimal (the CLI's strings) and mpf (mpmath values).
    Conversions: to_dict(), to_dataframe() (pandas: a row per particle), to_xarray().
    """
    callback = _progress_callback(progress, "simulate")
    out = _core.simulate(masses, lengths, g, theta, phi, phidot, time, dt, burn_in, integrator,
                         thermostat, beta, friction, seed, exact, every, callback)
    if out.interrupted:
        print(f"[simulate] interrupted at t = {out.time:.6g}: averages of the run so far",
              file=_sys.stderr, flush=True)
    return out


def poincare(masses, lengths, energy, g=1.0, *, orbits=None, points=None, dt=None, progress=None):
    """The double pendulum's Poincare section phi_1 = 0, phidot_1 > 0 at energy E (paper Fig. 9).

    Orbits (default 8) start on the section at p_2 = 0 over the allowed phi_2 >= 0 and at
    phi_2 = 0 over the allowed p_2, and are integrated (RATTLE + Yoshida-4, dt default 1e-3)
    until each has crossed the section `points` times (default 500); each crossing is refined
    onto the section by a partial step. Energies in the paper's convention (E > -(M l1 + m2 l2) g).

    Arguments:
      masses    the two masses m_1, m_2 > 0 (N = 2 only).
      lengths   the two link lengths l_1, l_2 > 0.
      energy    the energy E of every orbit (E > -(M l1 + m2 l2) g).
      g         gravitational acceleration >= 0 (default 1).
      orbits    number of orbits (default 8).
      points    crossings of the section per orbit (default 500).
      dt        time step (default 1e-3).
      progress  None, True or a callable f(fraction), as for pendavg.simulate.
    Ctrl-C ends the run with the points so far (interrupted = True). Returns a PoincareSection.
    """
    callback = _progress_callback(progress, "poincare")
    out = PoincareSection(_core.poincare(masses, lengths, g, energy, orbits, points, dt, callback))
    if out.interrupted:
        print("[poincare] interrupted: points so far", file=_sys.stderr, flush=True)
    return out


class _TextProgress:
    """'[command]  42% (12 s)' on stderr at most every 2 s, starting after 2 s (as the CLI)."""

    def __init__(self, command):
        self.command, self.start, self.last = command, _time.monotonic(), 0.0

    def __call__(self, fraction):
        elapsed = _time.monotonic() - self.start
        if elapsed - self.last < 2:
            return
        self.last = elapsed
        print(f"[{self.command}] {100 * fraction:3.0f}% ({elapsed:.0f} s)", file=_sys.stderr,
              flush=True)


# ---------------------------------------------------------------- result classes from the tables
#
# Averages, MicrocanonicalResult and SimulationResult are made in C++ from the output schema's
# field tables: a property per field (cls.fields(): name, kind, per_particle, meaning, input);
# their base _TableResult has .decimal, .seconds, .shape. Everything below works from cls.fields() alone: no field is named
# here.

def _class_fields(result):
    """(name, kind, per_particle, meaning, input) of every field of result's class."""
    return type(result).fields()


def _call_wide(kind, is_input):
    """The call's inputs that are counts (N, digits): one value for a whole grid."""
    return is_input and kind == "count"


def _result_mpf(self):
    """The values and errors as mpmath.mpf: exact binary values (MPFR runs: at digits + 12
    guard digits, of which `digits` are asked for; errors as computed, before printing rounded
    them up; double runs: the doubles exactly). One point: a list per particle, else one mpf;
    a grid: numpy object arrays. Fields without a value (None) are left out. Needs mpmath."""
    import mpmath
    exact = self._exact_values()
    out = {}
    for name, kind, per_particle, _, _ in _class_fields(self):
        if kind not in ("real", "error"):
            continue
        if exact is not None:
            if name not in exact:
                continue
            items = [None if x is None else _to_mpf(x) for x in exact[name]]
        else:
            value = getattr(self, name)
            if value is None:
                continue
            items = [mpmath.mp.make_mpf(mpmath.libmp.from_float(float(x)))
                     for x in _np.asarray(value, dtype=float).reshape(-1)]
        if not any(x is not None for x in items):
            continue  # K and var_K of the limits, ratio of N = 1, an empty grid
        if self.shape == ():
            out[name] = items if per_particle else items[0]
        else:
            array = _np.empty(len(items), dtype=object)
            array[:] = items
            out[name] = array.reshape(self.shape + ((self.N,) if per_particle else ()))
    return out


def _result_repr(self):
    """The call's counts and, for one point, every value that is there (errors and their kinds
    left out: .to_dict() has them)."""
    name = type(self).__name__
    fields = _class_fields(self)
    call = ", ".join(f"{f[0]}={getattr(self, f[0])!r}" for f in fields if _call_wide(f[1], f[4]))
    if self.shape != ():
        return f"pendavg.{name}(shape={self.shape}, {call})"
    shown = []
    for field, kind, _, _, is_input in fields:
        if _call_wide(kind, is_input) or kind == "error" or field.endswith("_error_kind"):
            continue
        value = getattr(self, field)
        if value is not None:
            shown.append(f"{field}={_short(value)}")
    return f"pendavg.{name}({call}, {', '.join(shown)})"


def _result_as_dict(self):
    """Every field as a dict, in the output schema's order (the CLI's JSON keys; numbers as
    floats or numpy arrays, None for a field without a value), then seconds (and run, or
    trajectory); a grid adds shape, dims and coords."""
    out = {f[0]: getattr(self, f[0]) for f in _class_fields(self)}
    out["seconds"] = self.seconds
    for extra in ("run", "trajectory"):  # Averages' run diagnostics, a simulation's trajectory
        if hasattr(type(self), extra):
            out[extra] = getattr(self, extra)
    if self.shape != ():
        out["shape"], out["dims"], out["coords"] = self.shape, self.dims, self.coords
    return out


def _result_dims(self):
    """Names of the result's axes (before the particle axis): the swept arguments of
    pendavg.sweep, ('axis0', 'axis1', ...) for a broadcast pendavg.average, () for one point."""
    dims = self.__dict__.get("_dims")
    return dims if dims is not None else tuple(f"axis{k}" for k in range(len(self.shape)))


def _result_coords(self):
    """{dim: the values along that axis}: pendavg.sweep's swept values (float64 where they are
    numbers); positions 0, 1, ... along the axes of a broadcast pendavg.average; {} for one
    point."""
    coords = self.__dict__.get("_coords")
    if coords is not None:
        return dict(coords)
    return {dim: _np.arange(n) for dim, n in zip(self.dims, self.shape)}


def _result_columns(self):
    """(per-particle fields, per-point fields, the call's counts) that this result has (no
    None); seconds is per point. A swept argument's field is its coordinate, not a column."""
    particle, point, call = {}, {}, {}
    for name, kind, per_particle, _, is_input in _class_fields(self):
        value = getattr(self, name)
        if value is None or name in self.dims:
            continue
        if _call_wide(kind, is_input):
            call[name] = value
        elif per_particle:
            particle[name] = value
        else:
            point[name] = value
    point["seconds"] = self.seconds
    return particle, point, call


def _result_to_dataframe(self):
    """A pandas DataFrame with one row per particle (and grid point): index (particle,) for one
    point, (*dims, particle) for a grid, labelled with .coords; per-particle fields are columns,
    per-point fields (beta, ratio, method, ...) are repeated over the particles. Needs pandas."""
    pandas = _optional("pandas", "to_dataframe")
    particle, point, _ = _result_columns(self)
    n = self.N
    columns = {name: _np.asarray(v).reshape(-1) for name, v in particle.items()}
    for name, v in point.items():
        columns[name] = _np.repeat(_np.asarray(v).reshape(-1), n)
    particles = _np.arange(1, n + 1)
    if self.shape == ():
        index = pandas.Index(particles, name="particle")
    else:
        coords = self.coords
        index = pandas.MultiIndex.from_product([*(coords[d] for d in self.dims), particles],
                                               names=[*self.dims, "particle"])
    return pandas.DataFrame(columns, index=index)


def _result_to_xarray(self):
    """An xarray.Dataset with dims (*dims, 'particle'), labelled with .coords and particle =
    1..N; per-point fields have the grid dims only; the call's counts (N, digits) are
    attributes. Needs xarray."""
    xarray = _optional("xarray", "to_xarray")
    particle, point, call = _result_columns(self)
    dims = self.dims
    data = {name: ((*dims, "particle"), _np.asarray(v)) for name, v in particle.items()}
    data.update({name: (dims, _np.asarray(v)) for name, v in point.items()})
    coords = {"particle": _np.arange(1, self.N + 1), **self.coords}
    return xarray.Dataset(data, coords=coords, attrs=call)


def _deprecated_alias(old, new):
    """A property `old` answering `new`'s value with a DeprecationWarning (schema 0's name)."""
    def get(self):
        _warnings.warn(f"{type(self).__name__}.{old} is deprecated (pendavg 0.2's name): use "
                       f".{new}", DeprecationWarning, stacklevel=2)
        return getattr(self, new)
    return property(get, doc=f"Deprecated: pendavg 0.2's name of {new} (the migration table).")


def _aliases(cls):
    """{old name: new name} of the migration table's renames of pendavg 0.2's attributes of
    cls (src/io/migration.cpp)."""
    names = {f[0] for f in cls.fields()}
    return {old: new for old, new, _, python, _ in _core.renames()
            if python == cls.__name__ and new in names and old not in names}


# What every result class has (their base, _TableResult), then each class's deprecated aliases.
_core._TableResult.dims = property(_result_dims)
_core._TableResult.coords = property(_result_coords)
_core._TableResult.to_dataframe = _result_to_dataframe
_core._TableResult.to_xarray = _result_to_xarray
_core._TableResult.mpf = property(_result_mpf)
_core._TableResult.as_dict = _result_as_dict
_core._TableResult.to_dict = _result_as_dict
_core._TableResult.__repr__ = _result_repr
for _cls in (Averages, MicrocanonicalResult, SimulationResult):
    for _old, _new in _aliases(_cls).items():
        setattr(_cls, _old, _deprecated_alias(_old, _new))
del _cls

average.__doc__ = average.__doc__.replace("<fields>\n", _fields_doc(Averages.fields()))
microcanonical.__doc__ = microcanonical.__doc__.replace("<fields>\n",
                                                        _fields_doc(MicrocanonicalResult.fields()))
simulate.__doc__ = simulate.__doc__.replace("<fields>\n", _fields_doc(SimulationResult.fields()))


# ---------------------------------------------------------------- helpers

def _optional(module, method):
    """Imports an optional module, or ImportError with one clear line."""
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"pendavg: {method}() needs {module}, which is not installed "
                          f"(pip install {module}, or Debian's python3-{module})") from None


def _progress_callback(progress, command):
    """progress as the C++ core takes it: None, a text reporter for True, or the callable."""
    if progress is None or progress is False:
        return None
    if progress is True:
        return _TextProgress(command)
    if not callable(progress):
        raise TypeError(f"progress: expected None, True or a callable f(fraction), got "
                        f"{type(progress).__name__}")
    return progress


def _coordinate(values):
    """Axis values for .coords: float64 when every value is a number, else as given."""
    try:
        return _np.asarray([float(_core.number_text(v, "coordinate")) for v in values.tolist()],
                           dtype=float)
    except (TypeError, ValueError, OverflowError):
        return values


def _is_array(x):
    return isinstance(x, (list, tuple, range)) or (isinstance(x, _np.ndarray) and x.ndim > 0)


def _entries(x):
    if isinstance(x, str) or not _is_array(x):
        return [x]
    return list(x)


def _as_array(x, name):
    """x as a numpy array (object dtype for str entries), or ValueError naming the argument."""
    try:
        if isinstance(x, (list, tuple, range)):
            if any(isinstance(v, str) for v in x):
                return _np.asarray(x, dtype=object)
            try:
                return _np.asarray(x)
            except OverflowError:  # ints beyond int64: kept as Python ints
                return _np.asarray(x, dtype=object)
        return _np.asarray(x, dtype=object) if isinstance(x, str) else _np.asarray(x)
    except (ValueError, TypeError) as error:
        raise ValueError(f"{name}: not a rectangular array of numbers ({error})") from None


def _mass_text(mu1):
    """The decimal mu1 is read as (see the module docstring), by the C++ reader's own rule."""
    return _core.number_text(mu1.item() if isinstance(mu1, _np.generic) else mu1, "mu1")


def _to_mpf(x):
    import mpmath
    if isinstance(x, tuple):
        return mpmath.mp.make_mpf(mpmath.libmp.from_man_exp(int(x[0], 16), x[1]))
    return mpmath.mpf(x)


def _short(v):
    if isinstance(v, _np.ndarray):
        if v.size > 6:
            return f"array(shape={v.shape})"
        return repr(v.tolist())
    return repr(v)
