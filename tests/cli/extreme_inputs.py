#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/cli/extreme_inputs.py -- the fail-closed contract of every `pendavg` command under
extreme inputs (issue 26 item 6): an adversarial generator plus fixed named reproducers.

Every run must either
  (a) exit 0 with every printed value and error finite (JSON, CSV and text parsed: no nan, inf
      or null where a number belongs; a quantity that cannot be exactly 0 -- beta<K_i>, Var K_i,
      <K_i>, beta^2 Var K_i, <K>_E, the density of states -- printed as 0 with error 0 is an
      underflow; a double run printing a subnormal value with an error below it claims digits a
      subnormal does not have), its --output file written and nothing else left behind, and,
      where cheap, each value within its error of an independent run (the same N = 2 command at
      --digits 30 for integral, series, limit and microcanonical; torus against transfer for
      N = 3..4; tolerance error_a + error_b + 4 ulps), or
  (b) exit 2 with exactly one line on stderr ("pendavg: ..."), nothing on stdout and no file
      left behind (no partial output, no temporaries); a refusal that takes more CPU time than
      --refusal-soft (0.1 s) is recorded as a soft finding, more than --refusal-hard (2 s) as a
      failure; a refusal's advice must be true ("request 17 or more digits": the same command at
      17 digits runs; "at 16 digits pendavg extrapolates": the same command at 16 digits runs;
      "use method transfer": the same command with that method runs);
and it must end within --timeout seconds of CPU time (else "unbounded-run"; work, not wall time:
the verdict does not depend on the machine's load; a run is killed after 3x that of wall time). Exit 1 (internal error), any
other status and a signal are failures.

Inputs: masses, lengths, g, beta, energies, angles, times, steps, perturbations and tolerances at
magnitudes 1e-323..1.8e308, beyond double (1e400, 1e-5000, 1e200000000, for MPFR), NaN/inf
spellings, products that overflow (beta g M l near 1e308 and near the 1e150 guard), mass ratios
up to 1e300 (often on the last link), N = 1..8 and a few large N for transfer and qmc; double and
--digits 17..60. The generator keeps accepted work cheap (small sample counts and step counts),
so a timeout means the program did not bound its own work.

Usage:
  extreme_inputs.py --pendavg BUILD/pendavg [--seed S|random] [--runs K] [--seconds T]
                    [--timeout 20] [--only fixed|random|NAME|INDEX] [--log FILE.jsonl] [-v]
Random case I of seed S is the same whatever ran before it (its own generator, seeded by S and
I): replay a failure with --seed S --only I (the report also prints each command line). Uses
the Python standard library only. Child processes run with OMP_NUM_THREADS=1 (one core).
Exit status: 0 when no failure was found, 1 otherwise (soft findings do not fail).
"""

import argparse
import decimal
import json
import os
import random
import re
import resource
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from decimal import Decimal

decimal.getcontext().prec = 60
decimal.getcontext().Emax = decimal.MAX_EMAX
decimal.getcontext().Emin = decimal.MIN_EMIN

DBL_MIN = Decimal("2.2250738585072014e-308")
DBL_EPS = Decimal(2) ** -52
SUBNORMAL_DEEP = Decimal("1.3e-321")  # below it a subnormal keeps fewer than 8 bits
NONFINITE = re.compile(r"^[+-]?(nan|inf|infinity)(\(.*\))?$", re.I)
NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")

# Quantities that cannot be exactly 0 and their error keys (JSON) / columns (CSV).
POSITIVE_JSON = {
    "beta_K": "beta_K_error", "K": "K_error", "var_K": "var_K_error",
    "beta2_var_K": "beta2_var_K_error",
    "Kc": "Kc_error", "K_total": "K_total_error", "density_of_states": "density_of_states_error",
    "exact_K": "exact_K_error", "exact_var_K": "exact_var_K_error", "exact_Kc": "exact_Kc_error",
}
POSITIVE_CSV = [  # (value column stem, error column stem); "#" is the particle index
    ("beta_K#", "beta_K#_error"), ("K#", "K#_error"), ("var_K#", "var_K#_error"),
    ("beta2_var_K#", "beta2_var_K#_error"), ("K_total", "K_total_error"),
    ("density_of_states", "density_of_states_error"), ("exact_K#", "exact_K#_error"),
    ("exact_var_K#", "exact_var_K#_error"),
]
# Time averages of a trajectory may be exactly 0 (a chain at rest); only exact values count.
DYNAMIC_KEYS = {"K", "Kc", "K_total", "var_K"}


class Case:
    """One command line with what to check about it."""

    def __init__(self, name, argv, files=None, outputs=(), expect=None, cross=None, note=""):
        self.name = name
        self.argv = [str(a) for a in argv]
        self.files = files or {}      # input files: name -> text (written to the input dir)
        self.outputs = list(outputs)  # files the command writes on success (relative to cwd)
        self.expect = expect          # "refuse": must be refused
        self.cross = cross            # (argv, kind): an independent run to compare values with
        self.note = note

    def option(self, name, default=None):
        a = self.argv
        for i in range(len(a) - 1, -1, -1):
            if a[i] == "--" + name and i + 1 < len(a):
                return a[i + 1]
        return default

    def command(self):
        return self.argv[0] if self.argv else ""


def with_option(argv, name, value):
    """argv with --name set to value (replaced if present, else appended)."""
    out = list(argv)
    for i in range(len(out) - 1):
        if out[i] == "--" + name:
            out[i + 1] = str(value)
            return out
    return out + ["--" + name, str(value)]


def without_option(argv, name):
    out, i = [], 0
    while i < len(argv):
        if argv[i] == "--" + name:
            i += 2
            continue
        out.append(argv[i])
        i += 1
    return out


# ---------------------------------------------------------------------------------- printing

def compact_list(value):
    """A long comma list as a $(python3 -c ...) expression (run-length encoded)."""
    items = value.split(",")
    if len(items) <= 12:
        return None
    runs = []
    for it in items:
        if runs and runs[-1][0] == it:
            runs[-1][1] += 1
        else:
            runs.append([it, 1])
    expr = "+".join("[%r]*%d" % (v, n) if n > 1 else "[%r]" % v for v, n in runs)
    return "\"$(python3 -c \"print(','.join(%s))\")\"" % expr


def shell_line(binary, case, workdir="DIR"):
    parts = [binary]
    for a in case.argv:
        c = compact_list(a) if "," in a else None
        parts.append(c if c else shlex.quote(a.replace("{in}", workdir)))
    line = " ".join(parts)
    if case.files:
        line += "   # " + "; ".join("%s/%s = %r" % (workdir, k, v) for k, v in case.files.items())
    return line


# --------------------------------------------------------------------------------- execution

class Result:
    pass


def execute(binary, case, timeout, scratch):
    work = tempfile.mkdtemp(prefix="xi-", dir=scratch)
    indir = os.path.join(work, "in")
    outdir = os.path.join(work, "out")
    os.mkdir(indir)
    os.mkdir(outdir)
    for name, text in case.files.items():
        with open(os.path.join(indir, name), "w") as f:
            f.write(text)
    argv = [a.replace("{in}", indir) for a in case.argv]
    env = dict(os.environ)
    env["OMP_NUM_THREADS"] = "1"
    env.pop("PENDAVG_MPI", None)
    r = Result()
    r.timed_out = False
    start = time.monotonic()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)  # cases run one at a time
    p = subprocess.Popen([binary] + argv, cwd=outdir, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, env=env,
                         start_new_session=True)
    try:
        out, err = p.communicate(timeout=3 * timeout)
    except subprocess.TimeoutExpired:
        r.timed_out = True
        try:
            os.killpg(p.pid, signal.SIGKILL)  # the group of the process this script started
        except ProcessLookupError:
            pass
        out, err = p.communicate()
    r.seconds = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    r.cpu_seconds = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    r.timed_out = r.timed_out or r.cpu_seconds > timeout
    r.rc = p.returncode
    r.stdout = out.decode("utf-8", "replace")
    r.stderr = err.decode("utf-8", "replace")
    r.files = {}
    r.leftover = []
    for root, _dirs, names in os.walk(outdir):
        for n in names:
            rel = os.path.relpath(os.path.join(root, n), outdir)
            if rel in case.outputs:
                with open(os.path.join(root, n), errors="replace") as f:
                    r.files[rel] = f.read()
            else:
                r.leftover.append(rel)
    shutil.rmtree(work, ignore_errors=True)
    return r


# ---------------------------------------------------------------------------------- checking

class Finding:
    def __init__(self, cls, detail, soft=False):
        self.cls = cls
        self.detail = detail
        self.soft = soft


def to_number(v):
    """Decimal for a JSON number or numeric string, None otherwise."""
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, Decimal)):
        return Decimal(v)
    if isinstance(v, float):
        return Decimal(repr(v))
    if isinstance(v, str) and NUMBER.match(v.strip()):
        return Decimal(v.strip())
    return None


def as_list(v):
    return v if isinstance(v, list) else [v]


class Checker:
    def __init__(self, case):
        self.case = case
        self.findings = []
        self.double = int(case.option("digits", "16") or 16) <= 16 if \
            (case.option("digits", "16") or "16").isdigit() else True
        self.dynamics = case.command() in ("simulate", "poincare")
        self.n = None

    def add(self, cls, detail, soft=False):
        self.findings.append(Finding(cls, detail, soft))

    # JSON --------------------------------------------------------------------------------
    def json_text(self, text):
        def bad_constant(name):
            raise ValueError("bare " + name)
        try:
            doc = json.loads(text, parse_float=Decimal, parse_constant=bad_constant)
        except ValueError as e:
            m = re.search(r"(?<![\w\"])(-?nan|-?inf\w*)", text, re.I)
            self.add("nonfinite-value" if m or "bare" in str(e) else "malformed-output",
                     "JSON does not parse (%s)%s" % (e, ": " + m.group(0) if m else ""))
            return None
        if isinstance(doc, dict):
            self.n = doc.get("N", doc.get("particles"))
        self.walk(doc, "$", None)
        return doc

    def walk(self, node, path, parent):
        if isinstance(node, dict):
            reasons = any(k.endswith("reason") and node[k] for k in node)
            for k, v in node.items():
                p = path + "." + k
                if v is None:
                    if not self.null_allowed(k, node, reasons):
                        self.add("null-value", "%s is null" % p)
                    continue
                if isinstance(v, list):
                    for i, x in enumerate(v):
                        if x is None and not self.null_allowed(k, node, reasons):
                            self.add("null-value", "%s[%d] is null" % (p, i))
                self.walk(v, p, node)
            self.zero_pairs(node, path)
        elif isinstance(node, list):
            for i, x in enumerate(node):
                self.walk(x, "%s[%d]" % (path, i), parent)
        elif isinstance(node, str):
            if NONFINITE.match(node.strip()) and not self.inf_allowed(path, node):
                self.add("nonfinite-value", "%s = %r" % (path, node))

    def null_allowed(self, key, node, reasons):
        if key in ("run", "ratio", "ratio_error", "ratio_error_kind") and (
                key == "run" or self.n == 1):
            return True
        if self.case.command() == "limit" and key in ("K", "K_error", "K_error_kind", "var_K",
                                                      "var_K_error", "var_K_error_kind"):
            return True  # a limit has beta<K_i> and beta^2 Var K_i, not <K_i> and Var K_i
        if key in ("proposal_beta", "effective_sample_fraction") and node.get("method") != "qmc":
            return True  # the microcanonical qmc's sampling, absent from its other methods
        if key.endswith("reason"):
            return True
        if key.startswith("exact_") and self.case.option("exact") == "no":
            return True  # --exact no: no exact values
        if self.dynamics and key in ("beta", "friction", "exact_excitation"):
            return True  # simulate: no bath without a thermostat, no shell with one
        if self.case.command() == "series" and key == "beta_K1_error":
            return True  # series: a row before any bound exists
        return reasons  # a null explained by a *_reason key in the same object

    def inf_allowed(self, path, value):
        # (series: a row without a bound yet prints null, not inf)
        return False

    def zero_pairs(self, node, path):
        for q, e in POSITIVE_JSON.items():
            if q not in node:
                continue
            if self.dynamics and q in DYNAMIC_KEYS and not self.langevin():
                continue
            vals = as_list(node[q])
            errs = as_list(node.get(e)) if e in node else [None] * len(vals)
            for i, v in enumerate(vals):
                x = to_number(v)
                err = to_number(errs[i]) if i < len(errs) else None
                self.check_value(x, err, "%s.%s[%d]" % (path, q, i))

    def check_value(self, x, err, where):
        if x is None:
            return
        if x == 0 and (err is None or err == 0):
            self.add("zero-with-zero-error",
                     "%s = 0 +- %s: an underflow (the quantity cannot be 0)" % (where, err))
        elif self.double and x != 0 and abs(x) < SUBNORMAL_DEEP and err is not None and \
                err < abs(x) * Decimal("1e-6"):
            # deep in the subnormals a double has few digits: the cross-checks decide
            self.add("subnormal-value", "%s = %s +- %s: a value deep in double's subnormals "
                     "(under 8 significant bits of its 53) with an error claiming 6+ digits"
                     % (where, x, err), soft=True)

    def langevin(self):
        return self.case.option("thermostat") == "langevin"

    # CSV ---------------------------------------------------------------------------------
    def csv_text(self, text, what):
        rows = []
        header = None
        for ln, line in enumerate(text.splitlines(), 1):
            if not line.strip():
                continue
            if line.startswith("#"):
                m = re.search(r"(?<![\w.])[-+]?(nan|inf|infinity)(?![\w])", line, re.I)
                if m:
                    self.add("nonfinite-value", "%s line %d: %r" % (what, ln, line[:160]))
                continue
            fields = line.split(",")
            if header is None:
                header = fields
                continue
            if len(fields) != len(header):
                self.add("malformed-output", "%s line %d: %d fields, header has %d"
                         % (what, ln, len(fields), len(header)))
                continue
            row = dict(zip(header, fields))
            for col, f in row.items():
                s = f.strip()
                if NONFINITE.match(s) or s.lower() == "null":
                    self.add("nonfinite-value", "%s line %d: %s = %r" % (what, ln, col, s))
            rows.append((ln, row))
        if header is None:
            self.add("malformed-output", "%s: no CSV header" % what)
            return header, rows
        for ln, row in rows:
            for vstem, estem in POSITIVE_CSV:
                for col in header:
                    idx = self.match_stem(col, vstem)
                    if idx is None:
                        continue
                    if self.dynamics and vstem in ("K#", "var_K#") and not self.langevin():
                        continue
                    ecol = estem.replace("#", idx)
                    x = to_number(row.get(col, ""))
                    err = to_number(row.get(ecol, "")) if ecol in row else None
                    self.check_value(x, err, "%s line %d %s" % (what, ln, col))
        return header, rows

    @staticmethod
    def match_stem(col, stem):
        if "#" not in stem:
            return "" if col == stem else None
        base = stem[:-1]
        if col.startswith(base) and col[len(base):].isdigit():
            return col[len(base):]
        return None

    # text --------------------------------------------------------------------------------
    def plain_text(self, text, what):
        for ln, line in enumerate(text.splitlines(), 1):
            scrub = line.replace("beta -> infinity", "").replace("beta -> inf", "").replace(
                "limit-beta-infinity", "")  # (the low-temperature limit's method)
            for m in re.finditer(r"(?<![\w.])[-+]?(nan|inf|infinity|null)(?![\w])", scrub, re.I):
                self.add("nonfinite-value", "%s line %d: %r" % (what, ln, line.strip()[:160]))
                break


def output_format(case):
    fmt = case.option("format")
    if fmt:
        return fmt
    cmd = case.command()
    if cmd in ("table", "poincare", "average", "limit", "simulate", "series") or case.option("cases"):
        return "csv"
    return "json"


def judge(case, r, args):
    """Findings about one run (not yet the advice or cross checks)."""
    c = Checker(case)
    if r.timed_out:
        c.add("unbounded-run", "no exit within %.0f s of CPU time (%.1f s used, %.1f s of wall "
              "time)" % (args.timeout, r.cpu_seconds, r.seconds))
        return c, None
    if r.rc < 0:
        c.add("crash", "killed by signal %s; stderr: %s" % (
            signal.Signals(-r.rc).name if -r.rc in signal.Signals._value2member_map_ else -r.rc,
            r.stderr.strip()[-300:]))
        return c, None
    err_lines = [ln for ln in r.stderr.splitlines()]
    if r.rc == 0:
        if case.expect == "refuse":
            c.add("accepted-must-refuse", "exit 0 (%s)" % case.note)
        doc = None
        fmt = output_format(case)
        for name in case.outputs:
            if name not in r.files:
                c.add("output-missing", "exit 0 but %s was not written" % name)
            else:
                c.csv_text(r.files[name], name)
        if r.leftover:
            c.add("stray-file", "left behind: %s" % ", ".join(r.leftover))
        if not case.outputs or r.stdout.strip():
            if fmt == "json":
                doc = c.json_text(r.stdout)
            elif fmt == "csv":
                c.csv_text(r.stdout, "stdout")
            else:
                c.plain_text(r.stdout, "stdout")
            if not r.stdout.strip() and not case.outputs:
                c.add("malformed-output", "exit 0 with nothing on stdout")
        return c, doc
    # exit 3: a sweep that finished with failed rows (README, sweeps): one stderr line, every
    # finished row kept in the output with a '# failed:' line in place of each failed one, and
    # no non-finite number in the rows that were kept.
    if r.rc == 3 and not case.outputs and r.stdout:
        # the same for a sweep written to stdout
        if len(err_lines) != 1 or not err_lines[0].startswith("pendavg: "):
            c.add("refusal-stderr-lines", "exit 3 with %d stderr lines" % len(err_lines))
        if "# failed:" not in r.stdout:
            c.add("malformed-output", "exit 3 but stdout has no '# failed:' line")
        rows = "\n".join(l for l in r.stdout.splitlines() if not l.startswith("#"))
        if rows.strip():
            c.csv_text(rows + "\n", "stdout")
        return c, None
    if r.rc == 3 and case.outputs:
        if len(err_lines) != 1 or not err_lines[0].startswith("pendavg: "):
            c.add("refusal-stderr-lines", "exit 3 with %d stderr lines" % len(err_lines))
        if r.stdout:
            c.add("refusal-stdout", "exit 3 with %d bytes on stdout" % len(r.stdout))
        if r.leftover:
            c.add("refusal-left-file", "exit 3 left: %s" % ", ".join(r.leftover))
        for name in case.outputs:
            text = r.files.get(name)
            if text is None:
                c.add("missing-output", "exit 3 without its output %s" % name)
                continue
            if "# failed:" not in text:
                c.add("malformed-output", "exit 3 but %s has no '# failed:' line" % name)
            rows = "\n".join(l for l in text.splitlines() if not l.startswith("#"))
            if rows.strip():
                c.csv_text(rows + "\n", name)
        return c, None
    # a refusal (or an error)
    msg = err_lines[-1] if err_lines else ""
    if r.rc == 1:
        c.add("internal-error", "exit 1: %s" % r.stderr.strip()[-300:])
    elif r.rc != 2:
        c.add("exit-status", "exit %d: %s" % (r.rc, r.stderr.strip()[-300:]))
    if r.stdout:
        c.add("refusal-stdout", "exit %d with %d bytes on stdout: %r"
              % (r.rc, len(r.stdout), r.stdout[:120]))
    if len(err_lines) != 1:
        c.add("refusal-stderr-lines", "exit %d with %d stderr lines: %r"
              % (r.rc, len(err_lines), [l[:100] for l in err_lines[:3]] + (
                  ["..."] if len(err_lines) > 3 else []) + ([msg[:200]] if len(err_lines) > 3
                                                          else [])))
    elif not msg.startswith("pendavg: "):
        c.add("refusal-stderr-lines", "stderr line does not start with 'pendavg: ': %r" % msg)
    if r.leftover:
        c.add("refusal-left-file", "exit %d left: %s" % (r.rc, ", ".join(r.leftover)))
    if r.files:
        c.add("refusal-left-file", "exit %d left its output: %s" % (r.rc, ", ".join(r.files)))
    if r.cpu_seconds > args.refusal_hard:
        c.add("slow-refusal", "exit %d after %.2f s of CPU time (> %.1f s): %s"
              % (r.rc, r.cpu_seconds, args.refusal_hard, msg[:200]))
    elif r.cpu_seconds > args.refusal_soft:
        c.add("slow-refusal-soft", "exit %d after %.2f s of CPU time (> %.2f s): %s"
              % (r.rc, r.cpu_seconds, args.refusal_soft, msg[:200]), soft=True)
    return c, None


def current_digits(case):
    d = case.option("digits", "16")
    try:
        return int(d)
    except ValueError:
        return None


def sweep_row(case, msg):
    """The row or point a sweep's message names (None outside sweeps)."""
    if case.command() != "table" and case.option("cases") is None:
        return None
    m = re.search(r"line (\d+)|point \(([^)]*)\)", msg)
    if not m:
        return "whole sweep"
    return m.group(1) or re.sub(r"digits = \d+, ", "", m.group(2))


def advice_case(case, r):
    """The run a refusal's advice asks for, or None."""
    if r.timed_out or r.rc != 2 or not r.stderr:
        return None, None
    msg = r.stderr.strip().splitlines()[-1]
    m = re.search(r"request (\d+) (or more )?digits", msg)
    if m and case.command() in ("average", "limit", "series", "table", "simulate"):
        want = int(m.group(1))
        have = current_digits(case)
        if case.command() == "simulate":
            return "false-advice", "simulate has no --digits, yet the refusal says: %s" % msg
        if have is not None and have >= want:
            return "false-advice", "already at --digits %d, the refusal says: %s" % (have, msg)
        if case.command() == "table" and case.option("chain") is None and False:
            return None, None
        argv = with_option(case.argv, "digits", want)
        if case.option("method") not in ("transfer",):
            argv = without_option(argv, "tol")  # --tol is a double run's tolerance
        return Case(case.name + "+advice", argv, files=case.files, outputs=case.outputs), msg
    m = re.search(r"use --dt ([0-9.eE+-]+) or smaller", msg)
    if m and case.command() in ("simulate", "poincare"):
        try:
            steps = float(case.option("time", "1")) / float(m.group(1))
        except (ValueError, ZeroDivisionError):
            steps = float("inf")
        if case.command() == "simulate" and not steps <= 2e5:
            return None, None  # the advice is checked only where following it is cheap
        return Case(case.name + "+advice", with_option(case.argv, "dt", m.group(1)),
                    files=case.files, outputs=case.outputs), msg
    m = re.search(r"use method (integral|transfer)", msg)
    if m and case.command() == "average" and "--cases" not in case.argv:
        return Case(case.name + "+advice", with_option(case.argv, "method", m.group(1)),
                    files=case.files, outputs=case.outputs), msg
    m = re.search(r"at (\d+) digits pendavg", msg)
    if m and case.command() in ("average", "limit"):
        return Case(case.name + "+advice", with_option(case.argv, "digits", m.group(1)),
                    files=case.files, outputs=case.outputs), msg
    return None, None


# --------------------------------------------------------------------------- cross checks

def pairs_average(doc):
    out = {}
    for q, e in (("beta_K", "beta_K_error"), ("cos_phi", "cos_phi_error"),
                 ("var_K", "var_K_error"), ("beta2_var_K", "beta2_var_K_error"),
                 ("ratio", "ratio_error"), ("K", "K_error"), ("Kc", "Kc_error"),
                 ("density_of_states", "density_of_states_error"),
                 ("K_total", "K_total_error")):
        if q in doc and e in doc:
            vs, es = as_list(doc[q]), as_list(doc[e])
            for i, v in enumerate(vs):
                out["%s[%d]" % (q, i)] = (to_number(v), to_number(es[i]) if i < len(es) else None)
    return out


def pairs_limit(doc):
    out = {}
    for lim in ("high_temperature", "low_temperature"):
        if isinstance(doc.get(lim), dict):
            for k, v in pairs_average(doc[lim]).items():  # (beta2_var_K among them)
                out[lim + "." + k] = v
    return out


def pairs_series(text):
    """The last row of a series CSV: beta<K1> and its bound (beta_K1, beta_K1_error)."""
    lines = [l for l in text.splitlines() if l.strip() and not l.startswith("#")]
    if len(lines) < 2:
        return {}
    row = dict(zip(lines[0].split(","), lines[-1].split(",")))
    return {"beta_K[0]": (to_number(row.get("beta_K1", "")), to_number(row.get("beta_K1_error", "")))}


def compare(a, b, label_a, label_b):
    """Mismatches between two dicts of (value, error)."""
    bad = []
    for k, (va, ea) in a.items():
        if k not in b:
            continue
        vb, eb = b[k]
        if va is None or vb is None or ea is None or eb is None:
            continue
        ulp = 4 * DBL_EPS * max(abs(va), abs(vb)) + Decimal("2e-323")
        if abs(va - vb) > ea + eb + ulp:
            bad.append("%s: %s %s +- %s vs %s %s +- %s (|diff| %.3g > %.3g)" % (
                k, label_a, va, ea, label_b, vb, eb, abs(va - vb), ea + eb + ulp))
    return bad


# ------------------------------------------------------------------------------ generators

NONFINITE_SPELLINGS = ["nan", "NaN", "-nan", "inf", "-inf", "Infinity", "+inf", "1e999",
                       "-1e999", "nan(0x1)", "INF"]
EDGE_HUGE = ["1.7976931348623157e308", "1.7976931348623157e+308", "1e308", "8.98846567431158e307",
             "6e307", "1.3407807929942596e154", "1e154", "1e150", "1.0000000000000002e150"]
EDGE_TINY = ["2.2250738585072014e-308", "2.225073858507201e-308", "4.9406564584124654e-324",
             "5e-324", "1e-310", "1e-320", "1e-300", "1e-150", "9.999999999999999e-151",
             "1.4916681462400413e-154"]
BEYOND = ["1e400", "1e-400", "1e-5000", "1e5000", "2e308", "1e-330", "1e200000000",
          "1e-200000000", "1e99999999999999999999", "1e-99999999999999999999"]


def fmt_mag(rng, exponent):
    m = rng.choice(["1", "2", "3.7", "5", "9.99", "1.234567890123", "7"])
    return "%se%d" % (m, exponent)


def positive(rng, mpfr=False, allow_bad=True, spread=300):
    """A positive parameter, biased toward the edges."""
    u = rng.random()
    if u < 0.45:
        return "%.4g" % (10 ** rng.uniform(-1, 1))
    if u < 0.68:
        return fmt_mag(rng, rng.randint(-spread, spread))
    if u < 0.76:
        return rng.choice(EDGE_TINY)
    if u < 0.84:
        return rng.choice(EDGE_HUGE)
    if u < 0.93 or not allow_bad:
        if mpfr or rng.random() < 0.5:
            return rng.choice(BEYOND)
        return rng.choice(EDGE_HUGE + EDGE_TINY)
    return rng.choice(NONFINITE_SPELLINGS + ["0", "-0", "-1", "0.0", "-1e-300"])


def mass_list(rng, n, mpfr=False):
    base = [("%.3g" % (10 ** rng.uniform(-0.5, 0.5))) for _ in range(n)]
    u = rng.random()
    if u < 0.35:  # one extreme mass, often the last
        i = n - 1 if rng.random() < 0.5 else rng.randrange(n)
        base[i] = fmt_mag(rng, rng.choice([-1, 1]) * rng.randint(100, 308))
    elif u < 0.45:  # alternating extremes
        e = rng.randint(100, 300)
        base = [fmt_mag(rng, e if i % 2 else -e) for i in range(n)]
    elif u < 0.65:
        base = [positive(rng, mpfr, allow_bad=rng.random() < 0.15) for _ in range(n)]
    return base


def overflow_split(rng, count):
    """`count` exponents summing to a target near the edges of double (or the 1e150 guard)."""
    target = rng.choice([rng.randint(296, 310), rng.randint(147, 153), rng.randint(-310, -296),
                         rng.randint(150, 160)])
    w = [rng.random() for _ in range(count)]
    s = sum(w)
    ex = [int(round(target * x / s)) for x in w]
    ex[-1] += target - sum(ex)
    return ex


def chain_params(rng, n, mpfr, want_beta=True):
    """(masses, lengths, g, beta) with the edge biases."""
    if rng.random() < 0.3:  # one parameter at an edge, the others ordinary: mostly accepted
        masses = ["%.3g" % (10 ** rng.uniform(-0.5, 0.5)) for _ in range(n)]
        lengths = ["%.3g" % (10 ** rng.uniform(-0.5, 0.5)) for _ in range(n)]
        g, beta = "%.3g" % (10 ** rng.uniform(-0.5, 0.5)), "%.3g" % (10 ** rng.uniform(-1, 1))
        which = rng.randrange(4)
        edge = fmt_mag(rng, rng.choice([-1, 1]) * rng.randint(1, 300)) if rng.random() < 0.7 \
            else positive(rng, mpfr)
        if which == 0:
            masses[rng.choice([n - 1, rng.randrange(n)])] = edge
        elif which == 1:
            lengths[rng.choice([n - 1, rng.randrange(n)])] = edge
        elif which == 2:
            g = edge
        else:
            beta = edge
        return masses, lengths, g, beta
    masses = mass_list(rng, n, mpfr)
    lengths = mass_list(rng, n, mpfr) if rng.random() < 0.5 else \
        ["%.3g" % (10 ** rng.uniform(-0.5, 0.5)) for _ in range(n)]
    g = positive(rng, mpfr) if rng.random() < 0.5 else "1"
    if rng.random() < 0.06:
        g = "0"
    beta = positive(rng, mpfr) if rng.random() < 0.6 else "1"
    if rng.random() < 0.25:  # products near 1e308 (or the 1e150 guard, or underflow)
        eb, eg, em, el = overflow_split(rng, 4)
        beta = fmt_mag(rng, eb) if want_beta else beta
        g = fmt_mag(rng, eg)
        masses = ["%s" % fmt_mag(rng, em) for _ in range(n)]
        lengths = ["%s" % fmt_mag(rng, el) for _ in range(n)]
        if rng.random() < 0.5:  # and the last link far heavier or longer
            masses[-1] = fmt_mag(rng, em + rng.randint(1, 200))
    return masses, lengths, g, beta


def mpfr_digits(rng):
    return rng.choice([17, 17, 20, 20, 25, 30, 40, 60])


def gen_average(rng, idx):
    method = rng.choice(["auto", "auto", "integral", "series", "torus-trapezoid", "torus-gauss",
                         "transfer", "transfer", "qmc"])
    if method in ("integral", "series"):
        n = 2 if rng.random() < 0.93 else rng.choice([1, 3])
    elif method in ("torus-trapezoid", "torus-gauss"):
        n = rng.choice([1, 2, 3, 3, 4])
    elif method == "transfer":
        # large N: 64 and 256 run (about a second at --tol 1e-2..1e-3), beyond 16384 refused
        n = rng.choice([1, 2, 3, 5, 8]) if rng.random() < 0.8 else rng.choice([64, 256, 16385,
                                                                                20000])
    elif method == "qmc":
        n = rng.choice([1, 2, 3, 5, 8]) if rng.random() < 0.8 else rng.choice([64, 256, 257])
    else:
        n = rng.choice([1, 2, 2, 3, 3, 4, 5, 6, 8])
    mpfr = rng.random() < 0.3 and method not in ("transfer", "qmc") and n <= 3
    if method in ("transfer", "qmc") and rng.random() < 0.05:
        mpfr = True  # must be refused
    digits = mpfr_digits(rng) if mpfr else 16
    if mpfr and n == 3:
        digits = 17  # a torus in MPFR costs n^(N-1) nodes at every digit
    elif mpfr and n == 2 and method.startswith("torus"):
        digits = min(digits, 30)
    large = n > 8
    masses, lengths, g, beta = chain_params(rng, min(n, 8), mpfr)
    if large:  # huge N: the extremes on a few links, the others unit
        masses = ["1"] * n
        lengths = ["1"] * n
        for _ in range(rng.randint(1, 3)):
            masses[rng.choice([0, n - 1, rng.randrange(n)])] = positive(rng)
        if rng.random() < 0.5:
            lengths[n - 1] = positive(rng)
        if rng.random() < 0.5:
            beta = fmt_mag(rng, rng.randint(-300, 308))
    argv = ["average", "--masses", ",".join(masses), "--lengths", ",".join(lengths),
            "--g", g, "--beta", beta]
    if method != "auto":
        argv += ["--method", method]
    if digits != 16:
        argv += ["--digits", str(digits)]
    if method in ("transfer",) or (method == "auto" and n >= 5):
        tol = rng.choice(["1e-4", "1e-6", "1e-8"] if n <= 8 else ["1e-2", "1e-3"])
        if rng.random() < 0.15:
            tol = rng.choice(["1e-300", "5e-324", "0", "1", "1e300", "nan"])
        argv += ["--tol", tol]
    elif method in ("torus-trapezoid", "torus-gauss") or (method == "auto" and n in (1, 3, 4)):
        if rng.random() < 0.4 and digits == 16:
            argv += ["--tol", rng.choice(["1e-6", "1e-8", "1e-10", "1e-300", "5e-324", "0.5",
                                          "1e300"])]
        elif n == 4 and digits == 16:
            argv += ["--tol", "1e-8"]
    if method == "qmc":
        argv += ["--samples", rng.choice(["1024", "1024", "2048", "1000", "0"]),
                 "--shifts", rng.choice(["4", "4", "8", "3"]),
                 "--seed", str(rng.choice([1, 2, 0, 18446744073709551615, 18446744073709551616]))]
    if rng.random() < 0.3:
        argv += ["--format", rng.choice(["csv", "text"])]
    else:
        argv += ["--format", "json"]  # (the default before schema 1: the cross checks read it)
    cross = None
    fmt = argv[argv.index("--format") + 1]
    if fmt == "json" and digits == 16:
        if n == 2 and method in ("auto", "integral", "series"):
            cross = (with_option(without_option(argv, "method"), "digits", "30"), "average")
        elif n in (3, 4) and method in ("auto", "torus-trapezoid"):
            cross = (with_option(without_option(argv, "tol"), "method", "transfer") +
                     ["--tol", "1e-8"], "average")
    return Case("random-%d" % idx, argv, cross=cross)


def gen_micro(rng, idx):
    n = rng.choice([1, 2, 2, 2, 3, 5])
    mpfr = n <= 2 and rng.random() < 0.35
    digits = mpfr_digits(rng) if mpfr else 16
    masses, lengths, g, _ = chain_params(rng, n, mpfr, want_beta=False)
    if rng.random() < 0.5:
        which, val = "excitation", positive(rng, mpfr)
    else:
        which = "energy"
        u = rng.random()
        val = rng.choice(["-1", "0", "1", "-2.9999999999999996", "-3"]) if u < 0.3 else \
            ("-" if rng.random() < 0.5 else "") + positive(rng, mpfr, allow_bad=False)
    argv = ["average", "--masses", ",".join(masses), "--lengths", ",".join(lengths), "--g", g,
            "--" + which, val]
    if n >= 5:
        argv += ["--method", "qmc", "--samples", "1024", "--shifts", "4"]
    elif n == 2 and rng.random() < 0.2:
        argv += ["--method", "torus-trapezoid"]
    if n == 3 and digits == 16:
        argv += ["--tol", "1e-8"]
    if digits != 16:
        argv += ["--digits", str(digits)]
    if rng.random() < 0.15 and n < 5:
        argv += ["--tol", rng.choice(["1e-300", "0", "1e300", "1e-6"])]
    argv += ["--format", "json"]  # (the default before schema 1: the cross checks read it)
    cross = None
    if n == 2 and digits == 16 and "--method" not in argv and "--tol" not in argv:
        cross = (argv + ["--digits", "30"], "average")
    return Case("random-%d" % idx, argv, cross=cross)


def gen_limit(rng, idx):
    n = rng.choice([1, 2, 2, 2, 3, 3, 4, 6])
    mpfr = rng.random() < 0.3 and n <= 3
    digits = mpfr_digits(rng) if mpfr else 16
    if n == 3 and mpfr:
        digits = 17
    masses, lengths, g, _ = chain_params(rng, n, mpfr, want_beta=False)
    argv = ["limit", "--masses", ",".join(masses)]
    if rng.random() < 0.7:
        argv += ["--lengths", ",".join(lengths)]
    if rng.random() < 0.3:
        argv += ["--g", g]
    if digits != 16:
        argv += ["--digits", str(digits)]
    if rng.random() < 0.25:
        argv += ["--format", rng.choice(["csv", "text"])]
    else:
        argv += ["--format", "json"]  # (the default before schema 1: the cross checks read it)
    cross = None
    if n == 2 and digits == 16 and argv[-1] == "json":
        cross = (argv + ["--digits", "30"], "limit")
    return Case("random-%d" % idx, argv, cross=cross)


def gen_series(rng, idx):
    mpfr = rng.random() < 0.4
    digits = mpfr_digits(rng) if mpfr else 16
    masses, lengths, g, beta = chain_params(rng, 2, mpfr)
    if rng.random() < 0.3:  # mu2 near 1 needs many terms: keep the cost bounded
        masses = [rng.choice(["1e-300", "1e-30", "1e-10", "1e-3"]), "1"]
    argv = ["series", "--masses", ",".join(masses), "--lengths", ",".join(lengths), "--g", g,
            "--beta", beta]
    if digits != 16:
        argv += ["--digits", str(digits)]
    if rng.random() < 0.4:
        argv += ["--terms", rng.choice(["1", "5", "50", "0"])]
    cross = None
    if digits == 16 and "--terms" not in argv:
        cross = (["average", "--masses", ",".join(masses), "--lengths", ",".join(lengths),
                  "--g", g, "--beta", beta, "--method", "integral", "--digits", "30",
                  "--format", "json"], "series")
    return Case("random-%d" % idx, argv, cross=cross)


def time_and_dt(rng):
    u = rng.random()
    if u < 0.6:  # cheap: at most ~2e4 steps
        dt = rng.choice(["1e-3", "1e-2", "5e-3", "1e-4"])
        time_ = "%.3g" % (float(dt) * rng.randint(1, 20000))
    elif u < 0.75:  # tiny or huge step, huge or tiny time: must be refused
        dt = rng.choice(["1e-300", "5e-324", "1e-20", "1e300", "1.7976931348623157e308", "0",
                         "nan"])
        time_ = rng.choice(["1", "1e-3", "10"])
    elif u < 0.9:
        dt = "1e-3"
        time_ = rng.choice(["1e300", "1.7976931348623157e308", "1e20", "5e-324", "1e-300",
                            "inf", "1e11"])  # 1e10 / 1e-3 = 1e13 steps is still accepted
    else:
        dt = positive(rng)
        time_ = positive(rng)
    return time_, dt


def gen_simulate(rng, idx):
    n = rng.choice([1, 2, 2, 3, 3, 4])
    masses, lengths, g, beta = chain_params(rng, n, False)
    time_, dt = time_and_dt(rng)
    argv = ["simulate", "--masses", ",".join(masses), "--lengths", ",".join(lengths), "--g", g]
    if rng.random() < 0.7:
        theta = rng.choice(["1", "90deg", "0.1", "3.14159", "1e-300", "1e300", "5e-324",
                            "1e-8", "180deg", "1e308deg", "-1", "nan", "inf"])
        argv += ["--theta", theta]
    else:
        argv += ["--phi", ",".join(rng.choice(["0.5", "1e-300", "1e300", "1", "-2", "0"])
                                   for _ in range(n))]
        if rng.random() < 0.6:
            argv += ["--phidot", ",".join(rng.choice(["0", "1", "1e-300", "1e150", "1e300",
                                                      "-1e10"]) for _ in range(n))]
    argv += ["--time", time_, "--dt", dt]
    if rng.random() < 0.4:
        argv += ["--thermostat", "langevin", "--beta", beta]
        if rng.random() < 0.4:
            argv += ["--friction", positive(rng)]
    if rng.random() < 0.4:
        argv += ["--integrator", rng.choice(["yoshida6", "yoshida4", "suzuki4", "kahan-li6",
                                             "rattle2"])]
    if rng.random() < 0.3:
        argv += ["--replicas", rng.choice(["2", "3", "4"])]
        if rng.random() < 0.5 and "--thermostat" not in argv:
            argv += ["--perturb", rng.choice(["1e-6", "1e-300", "1e300", "1", "10", "nan",
                                              "5e-324", "0"])]
    if rng.random() < 0.2:
        argv += ["--burn-in", rng.choice(["1", "1e300", "1e-300", "0"])]
    if n >= 4 and rng.random() < 0.7:
        argv += ["--exact", "no"]
    if rng.random() >= 0.3:  # CSV is the default
        argv += ["--format", "json"]
    outputs = []
    if rng.random() < 0.15:
        argv += ["--trajectory", "traj.csv", "--every", rng.choice(["1", "100", "0"])]
        outputs = ["traj.csv"]
    case = Case("random-%d" % idx, argv, outputs=outputs)
    p = case.option("perturb")
    if p is not None and case.option("replicas"):
        try:
            if float(p) > 3.2:  # more than pi: not a perturbation
                case.expect, case.note = "refuse", "--perturb %s is not a small perturbation" % p
        except ValueError:
            pass
    return case


def gen_poincare(rng, idx):
    masses, lengths, g, _ = chain_params(rng, 2, False, want_beta=False)
    e = rng.choice(["-1", "0", "1", "10", "-2.9999999999999996"]) if rng.random() < 0.4 else \
        ("-" if rng.random() < 0.5 else "") + positive(rng)
    argv = ["poincare", "--masses", ",".join(masses), "--lengths", ",".join(lengths), "--g", g,
            "--energy", e, "--orbits", rng.choice(["1", "2", "0"]),
            "--points", rng.choice(["2", "5", "20"])]
    if rng.random() < 0.4:
        argv += ["--dt", rng.choice(["1e-2", "1e-300", "1e300", "5e-324", "0.5"])]
    outputs = []
    if rng.random() < 0.5:
        argv += ["--output", "section.csv"]
        outputs = ["section.csv"]
    return Case("random-%d" % idx, argv, outputs=outputs)


def spec(rng, mpfr, lo_hi=None):
    u = rng.random()
    if u < 0.4:
        return positive(rng, mpfr)
    if u < 0.7:
        a, b = positive(rng, mpfr, allow_bad=False), positive(rng, mpfr, allow_bad=False)
        return "log:%s:%s:%d" % (a, b, rng.choice([2, 3]))
    if u < 0.85:
        return "lin:%s:%s:%d" % (positive(rng, mpfr, allow_bad=False),
                                 positive(rng, mpfr, allow_bad=False), rng.choice([2, 3]))
    return ",".join(positive(rng, mpfr) for _ in range(rng.choice([1, 2, 3])))


def gen_table(rng, idx):
    mpfr = rng.random() < 0.3
    digits = rng.choice(["17", "20", "30", "16,20"]) if mpfr else "16"
    argv = ["table"]
    kind = rng.random()
    if kind < 0.45:
        mu = rng.choice(["0.5", "1e-300", "0.9999999999999999", "1e-150", "0.999999", "5e-324",
                         "1e-400", "0.25,0.75"])
        argv += ["--beta", spec(rng, mpfr), "--mu1", mu]
        if rng.random() < 0.5:
            argv += ["--l2", spec(rng, mpfr)]
        if rng.random() < 0.3:
            argv += ["--l1", positive(rng, mpfr)]
        if rng.random() < 0.5:
            argv += ["--g", spec(rng, mpfr)]
    elif kind < 0.8:
        chain = rng.choice(["3", "3", "4", "8", "3,8", "16385", "2"])  # 16384 costs minutes
        argv += ["--chain", chain, "--beta", spec(rng, mpfr)]
        if rng.random() < 0.6:
            argv += ["--g", spec(rng, mpfr)]
        if chain in ("8", "3,8", "16384", "16385"):
            argv += ["--tol", "1e-3" if "1638" in chain else "1e-6"]
            digits = "16"
        elif chain == "4" and digits == "16":
            argv += ["--tol", "1e-8"]
        if mpfr and chain != "3":
            digits = "16"
    else:
        argv += ["--" + rng.choice(["energy", "excitation"]), spec(rng, mpfr)]
        if rng.random() < 0.5:
            argv += ["--mu1", rng.choice(["0.5", "1e-300", "0.999999"])]
        else:
            argv += ["--chain", "3", "--tol", "1e-8"]
            digits = "16"
        if mpfr and "--chain" not in argv:
            digits = "17"
        elif mpfr:
            digits = "16"
    if digits != "16":
        argv += ["--digits", digits]
    outputs = []
    if rng.random() < 0.6:
        argv += ["--output", "table.csv"]
        outputs = ["table.csv"]
    return Case("random-%d" % idx, argv, outputs=outputs)


def gen_cases(rng, idx):
    n = rng.choice([1, 2, 2, 3, 5])
    micro = rng.random() < 0.3 and n <= 3
    mpfr = rng.random() < 0.3 and n <= 2
    rows = []
    for _ in range(rng.randint(1, 4)):
        masses, lengths, g, beta = chain_params(rng, n, mpfr)
        first = positive(rng, mpfr) if micro else beta
        rows.append([first, g] + masses + lengths)
    head = ["excitation" if micro else "beta", "g"] + ["m%d" % (i + 1) for i in range(n)] + \
        ["l%d" % (i + 1) for i in range(n)]
    text = ",".join(head) + "\n" + "".join(",".join(r) + "\n" for r in rows)
    argv = ["average", "--cases", "{in}/cases.csv"]
    if mpfr:
        argv += ["--digits", str(mpfr_digits(rng))]
    if n >= 5:
        argv += ["--method", "qmc", "--samples", "1024", "--shifts", "4"] if micro else \
            ["--tol", "1e-6"]
    elif n == 3 and not mpfr:
        argv += ["--tol", "1e-8"]
    outputs = []
    if rng.random() < 0.6:
        argv += ["--output", "rows.csv"]
        outputs = ["rows.csv"]
    return Case("random-%d" % idx, argv, files={"cases.csv": text}, outputs=outputs)


GENERATORS = [(gen_average, 30), (gen_micro, 10), (gen_limit, 13), (gen_series, 6),
              (gen_simulate, 15), (gen_poincare, 5), (gen_table, 11), (gen_cases, 10)]


def random_case(seed, idx):
    rng = random.Random("%s:%d" % (seed, idx))
    total = sum(w for _, w in GENERATORS)
    u = rng.random() * total
    for gen, w in GENERATORS:
        if u < w:
            return gen(rng, idx)
        u -= w
    return GENERATORS[0][0](rng, idx)


# ---------------------------------------------------------------------------- fixed cases

def fixed_cases():
    ones3 = ["--masses", "1,1,1", "--lengths", "1,1,1"]
    sim = ["simulate", "--masses", "1,1", "--lengths", "1e-300,1", "--theta", "1", "--time", "1"]
    f = [
        Case("limit-light-first", ["limit", "--masses", "1e-300,1e20", "--lengths", "1,0.5"],
             cross=(["limit", "--masses", "1e-300,1e20", "--lengths", "1,0.5", "--digits", "30"],
                    "limit")),
        Case("limit-heavy-middle", ["limit", "--masses", "1,1e154,1"]),
        Case("limit-dbl-max-tail", ["limit", "--masses", "0.5,1e-300,5.467694768196e306"]),
        Case("limit-ratio-1e400", ["limit", "--masses", "1e-200,1e200"]),
        Case("limit-ratio-1e400-mpfr", ["limit", "--masses", "1e-200,1e200", "--digits", "30"]),
        Case("simulate-tiny-link", list(sim)),
        Case("simulate-tiny-link-langevin", sim + ["--thermostat", "langevin", "--beta", "1"]),
        Case("simulate-tiny-link-rattle2", sim + ["--integrator", "rattle2"]),
        Case("simulate-tiny-link-replicas", sim + ["--replicas", "2"]),
        Case("simulate-tiny-link-n3", ["simulate", "--masses", "1,1,1", "--lengths",
                                       "1e-300,1,1", "--theta", "1", "--time", "1"]),
        Case("average-beta-1e400-mpfr", ["average"] + ones3 + ["--beta", "1e400", "--digits",
                                                               "20"]),
        Case("average-g-1e400-mpfr", ["average"] + ones3 + ["--beta", "1", "--g", "1e400",
                                                            "--digits", "20"]),
        Case("average-length-1e400-mpfr", ["average", "--masses", "1,1,1", "--lengths",
                                           "1,1e400,1", "--beta", "1", "--digits", "20"]),
        Case("average-beta-1e400-mpfr-n4", ["average", "--masses", "1,1,1,1", "--lengths",
                                            "1,1,1,1", "--beta", "1e400", "--digits", "20"]),
        Case("average-g-6e307", ["average"] + ones3 + ["--beta", "1", "--g", "6e307"]),
        Case("average-length-6e307", ["average", "--masses", "1,1,1", "--lengths", "6e307,1,1",
                                      "--beta", "1"]),
        Case("table-g-dbl-max", ["table", "--chain", "3", "--beta", "1", "--g",
                                 "1.7976931348623157e308", "--output", "F"], outputs=["F"]),
        Case("average-n1-var-underflow", ["average", "--masses", "2", "--lengths", "3", "--g",
                                          "1", "--beta", "1e300"]),
        Case("average-beta-1e200000000", ["average", "--masses", "1,1", "--lengths", "1,1",
                                          "--beta", "1e200000000", "--digits", "30"]),
        Case("simulate-perturb-1e300", ["simulate", "--masses", "1,1", "--lengths", "1,1",
                                        "--theta", "1", "--time", "1", "--replicas", "4",
                                        "--perturb", "1e300"],
             expect="refuse", note="--perturb 1e300 radians is not a perturbation"),
        # more edges of the same kinds
        Case("average-n2-beta-dbl-max", ["average", "--masses", "1,1", "--lengths", "1,1",
                                         "--beta", "1.7976931348623157e308"]),
        Case("average-n2-subnormal-mass", ["average", "--masses", "5e-324,1", "--lengths",
                                           "1,1", "--beta", "1"]),
        Case("average-transfer-n16385", ["average", "--masses", ",".join(["1"] * 16385),
                                         "--lengths", ",".join(["1"] * 16385), "--beta", "1"]),
        Case("average-qmc-n257", ["average", "--masses", ",".join(["1"] * 257), "--lengths",
                                  ",".join(["1"] * 257), "--beta", "1", "--method", "qmc"]),
        Case("average-transfer-heavy-tail", ["average", "--masses", "1,1,1,1,1e300",
                                             "--lengths", "1,1,1,1,1", "--beta", "1", "--tol",
                                             "1e-6"]),
        Case("micro-excitation-subnormal", ["average", "--masses", "1,1", "--lengths", "1,1",
                                            "--excitation", "5e-324"]),
        Case("micro-energy-1e308", ["average", "--masses", "1,1", "--lengths", "1,1",
                                    "--energy", "1e308"]),
        Case("series-beta-1e300", ["series", "--masses", "1,1", "--lengths", "1,1", "--beta",
                                   "1e300"]),
        Case("poincare-g-tiny", ["poincare", "--masses", "1,1", "--lengths", "1,1", "--g",
                                 "1e-300", "--energy", "1", "--orbits", "1", "--points", "2"]),
        # a soft link between stiff ones: the joints' stiffness (3e7) hid link 2's alpha = 0.02
        # and the low-temperature extrapolation printed <cos phi_2> = 0.9995 (truth 0.0084)
        Case("average-soft-link-between-stiff",
             ["average", "--masses", "1,1,1", "--lengths", "1,1e-9,1e3", "--beta", "1e7"],
             cross=(["average", "--masses", "1,1,1", "--lengths", "1,1e-9,1e3", "--beta", "1e7",
                     "--method", "transfer"], "average")),
        # the torus' work cap: each ran for minutes (the MPFR one for hours) before it
        Case("average-torus-cap-light-mpfr",
             ["average", "--masses", "1.27,5e-101,0.986", "--lengths", "0.835,2.26,0.88", "--g",
              "1.58", "--beta", "2.02", "--method", "torus-trapezoid", "--digits", "17"]),
        Case("average-torus-cap-extreme-lengths-n4",
             ["average", "--masses", "3.7e144,0.593,0.73,0.626", "--lengths",
              "7e27,0.1169,1.4916681462400413e-154,1.234567890123e126", "--g", "3.328", "--beta",
              "0.9746", "--tol", "1e-8"]),
        Case("average-transfer-cap-alternating-links",
             ["average", "--masses", "2.98,0.835,0.846,0.416,0.798,2.2,2.94,2.03", "--lengths",
              "5e-118,7e118,9.99e-118,7e118,3.7e-118,7e118,2e-118,3.7e118", "--g", "0.9548",
              "--beta", "1", "--method", "transfer", "--tol", "1e-8"]),
        Case("average-transfer-stiff-soft-first-link",
             ["average", "--masses", "0.442,2.43,0.817,2.65,0.678,1.23,1.1,0.536", "--lengths",
              "9.99e-165,0.411,1.22,0.742,0.517,0.433,1.57,1.72", "--g", "5e196", "--beta",
              "2.052", "--tol", "1e-6"], expect="refuse"),
        Case("cases-overflow-row", ["average", "--cases", "{in}/c.csv", "--output", "o.csv"],
             files={"c.csv": "beta,g,m1,m2,l1,l2\n1,1,1,1,1,1\n1e300,1e10,1,1,1,1\n"},
             outputs=["o.csv"]),
    ]
    # average and limit printed JSON by default before schema 1 (csv since): these cases and
    # their cross checks still read JSON
    for case in f:
        for argv in [case.argv] + ([case.cross[0]] if case.cross else []):
            if argv[0] in ("average", "limit") and "--cases" not in argv and "--format" not in argv:
                argv += ["--format", "json"]
    return f


# ----------------------------------------------------------------------------------- driver

class Report:
    def __init__(self, binary, log):
        self.binary = binary
        self.failures = []  # (case, finding, seconds)
        self.soft = []
        self.runs = 0
        self.log = open(log, "w") if log else None

    def record(self, case, r, findings, verbose):
        self.runs += 1
        for f in findings:
            (self.soft if f.soft else self.failures).append((case, f, r.seconds if r else 0))
            line = "%s %s [%s] %s\n    %s" % ("SOFT" if f.soft else "FAIL", f.cls, case.name,
                                             f.detail[:400], shell_line(self.binary, case))
            print(line, flush=True)
            if self.log:
                self.log.write(json.dumps({"class": f.cls, "soft": f.soft, "case": case.name,
                                           "argv": case.argv, "files": case.files,
                                           "detail": f.detail,
                                           "seconds": r.seconds if r else None}) + "\n")
                self.log.flush()
        if verbose and r is not None:
            print("  ok %-28s rc=%s %.2fs %s" % (case.name, r.rc, r.seconds,
                                                  " ".join(case.argv)[:150]), flush=True)


def run_case(binary, case, args, scratch, report, depth=0):
    r = execute(binary, case, args.timeout, scratch)
    c, doc = judge(case, r, args)
    findings = list(c.findings)
    # the refusal's advice must be true
    if depth == 0:
        adv, msg = advice_case(case, r)
        if isinstance(adv, str):
            findings.append(Finding(adv, msg))
        elif adv is not None:
            r2 = execute(binary, adv, args.timeout, scratch)
            c2, _ = judge(adv, r2, args)
            follow = "--dt " + adv.option("dt") if "use --dt" in msg else \
                "--digits " + (adv.option("digits") or "")
            if r2.timed_out:
                findings.append(Finding("advice-unverified", "%s -> following it (%s): no exit "
                                        "within %.0f s" % (msg[:200], follow, args.timeout),
                                        soft=True))
            elif r2.rc != 0:
                msg2 = r2.stderr.strip().splitlines()[-1] if r2.stderr.strip() else ""
                # a sweep's advice is about one row; --digits moves every row: another row
                # refused at the new digits says nothing about the advice
                other_row = sweep_row(case, msg) != sweep_row(case, msg2)
                findings.append(Finding(
                    "advice-sweep-inconclusive" if other_row else "false-advice",
                    "%s -> following it (%s): exit %d: %s" % (msg[:200], follow, r2.rc,
                                                              msg2[:200]), soft=other_row))
            for f in c2.findings:
                if f.cls not in ("slow-refusal", "slow-refusal-soft", "unbounded-run",
                                 "refusal-stderr-lines"):
                    findings.append(Finding(f.cls, "following the advice (%s): %s" % (
                        follow, f.detail), f.soft))
    report.record(case, r, findings, args.verbose)
    # an independent run of the same quantities
    if depth == 0 and case.cross and r.rc == 0 and not r.timed_out and not any(
            not f.soft for f in c.findings):
        argv2, kind = case.cross
        cc = Case(case.name + "+cross", argv2, files=case.files)
        r2 = execute(binary, cc, args.timeout, scratch)
        c2, doc2 = judge(cc, r2, args)
        report.record(cc, r2, [f for f in c2.findings], args.verbose)
        if r2.rc == 0 and not r2.timed_out:
            if kind == "limit" and doc and doc2:
                a, b = pairs_limit(doc), pairs_limit(doc2)
            elif kind == "series" and doc2:
                a, b = pairs_series(r.stdout), pairs_average(doc2)
                b = {"beta_K[0]": b.get("beta_K[0]", (None, None))}
            elif doc and doc2:
                a, b = pairs_average(doc), pairs_average(doc2)
            else:
                a, b = {}, {}
            bad = compare(a, b, "this run", "the check")
            if bad:
                report.record(case, None, [Finding(
                    "crosscheck-mismatch", "against `%s`: %s" % (" ".join(
                        x if len(x) < 40 else x[:37] + "..." for x in argv2), "; ".join(bad[:3])))],
                    False)
        elif not r2.timed_out and r2.rc == 2:
            report.record(case, None, [Finding(
                "crosscheck-refused", "accepted, but the independent run `%s` is refused: %s" % (
                    " ".join(x if len(x) < 40 else x[:37] + "..." for x in argv2),
                    r2.stderr.strip().splitlines()[-1][:200] if r2.stderr.strip() else ""),
                soft=True)], False)
    return r


def summarize(report, binary):
    print("\n==== summary: %d runs, %d failures, %d soft findings" % (
        report.runs, len(report.failures), len(report.soft)))
    for title, items in (("FAILURES", report.failures), ("SOFT", report.soft)):
        groups = {}
        for case, f, secs in items:
            key = (f.cls, case.command() + (" --" + ("cases" if case.option("cases") else
                                                      "energy" if case.option("energy") or
                                                      case.option("excitation") else "")
                                             if case.command() == "average" else ""),
                   case.option("method", ""))
            groups.setdefault(key, []).append((case, f))
        if groups:
            print("-- %s by class, command, method (count; shortest reproducer):" % title)
        for key in sorted(groups, key=lambda k: (k[0], k[1], k[2])):
            lst = groups[key]
            case, f = min(lst, key=lambda cf: len(" ".join(cf[0].argv)))
            print("  %-24s %-22s %-16s x%d\n    %s\n    %s" % (
                key[0], key[1].strip(), key[2], len(lst), shell_line(binary, case),
                f.detail[:300]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pendavg", required=True)
    ap.add_argument("--seed", default="1", help="an integer, or 'random' (printed)")
    ap.add_argument("--seconds", type=float, default=60,
                    help="wall-time budget of the random phase (default 60)")
    ap.add_argument("--runs", type=int, default=None,
                    help="run exactly this many random cases (still capped by --seconds)")
    ap.add_argument("--timeout", type=float, default=20, help="per-run limit (default 20 s)")
    ap.add_argument("--refusal-soft", type=float, default=0.1)
    ap.add_argument("--refusal-hard", type=float, default=2.0)
    ap.add_argument("--only", default=None,
                    help="'fixed', 'random', a fixed case's name or a random case's index")
    ap.add_argument("--log", default=None, help="write every finding as a JSON line")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args()

    binary = os.path.abspath(args.pendavg)
    if not os.access(binary, os.X_OK):
        print("extreme_inputs: %s is not executable" % binary)
        return 2
    seed = args.seed
    if seed == "random":
        seed = str(int.from_bytes(os.urandom(4), "little"))
    print("extreme_inputs: seed %s (replay: %s --pendavg %s --seed %s --only INDEX)" % (
        seed, sys.argv[0], binary, seed), flush=True)
    report = Report(binary, args.log)
    scratch = tempfile.mkdtemp(prefix="pendavg-extreme-")
    t0 = time.monotonic()
    try:
        fixed = fixed_cases()
        only = args.only
        if only is None or only == "fixed" or (only and not only.isdigit() and only != "random"):
            for case in fixed:
                if only not in (None, "fixed") and case.name != only:
                    continue
                run_case(binary, case, args, scratch, report)
        fixed_seconds = time.monotonic() - t0
        if only is not None and only.isdigit():
            run_case(binary, random_case(seed, int(only)), args, scratch, report)
        elif only in (None, "random"):
            t1 = time.monotonic()
            idx = 0
            while True:
                if args.runs is not None and idx >= args.runs:
                    break
                if time.monotonic() - t1 >= args.seconds:
                    if args.runs is not None:
                        print("extreme_inputs: the --seconds budget ended the random phase "
                              "after %d of %d cases" % (idx, args.runs))
                    break
                run_case(binary, random_case(seed, idx), args, scratch, report)
                idx += 1
            print("extreme_inputs: fixed cases %.1f s, %d random cases (indices 0..%d) %.1f s" % (
                fixed_seconds, idx, idx - 1, time.monotonic() - t1))
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    summarize(report, binary)
    print("extreme_inputs: seed %s, %.1f s, %d runs, %d failures, %d soft" % (
        seed, time.monotonic() - t0, report.runs, len(report.failures), len(report.soft)))
    return 1 if report.failures else 0


if __name__ == "__main__":
    sys.exit(main())
