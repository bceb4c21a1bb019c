#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/bench/near_minimum_ladder.py -- the microcanonical near-minimum ladder through the CLI,
against an independent mpmath evaluation of the definition (issue 15).

    python3 tests/bench/near_minimum_ladder.py PENDAVG [--digits 40] [--nodes 24]
    python3 tests/bench/near_minimum_ladder.py --reference MASSES LENGTHS G D [--digits 40]
    python3 tests/bench/near_minimum_ladder.py PENDAVG --separatrix --digits 30

For each chain (N = 2 and 3, unit and unequal) and each excitation D = 10^-k |E_min|
(k = 4..12) it runs `pendavg average --excitation D` and `pendavg average --energy E` (E the
double nearest E_min + D), and prints per quantity the worst relative error and the worst
|value - truth| / reported error over the particles (a ratio below 1: the bar covers the truth).
`--reference` prints the oracle's <K_i>_E, Var K_i and <cos phi_i>_E at one exact D (a decimal
string, read exactly), the source of the CLI tests' near-minimum reference strings.
`--separatrix` checks N = 2 at every separatrix energy (exactly and 1e-9 of the top off) and
above the top against definition_2d, the definition over (phi_1, phi_2) by nested tanh-sinh.

The oracle is the definition (src/engine/microcanonical/README.md) integrated over the N absolute angles, written here
from the paper's matrices alone: A_jk = S_max(j,k) l_j l_k cos(phi_j - phi_k), A^(i)_jk =
m_i l_j l_k cos(phi_j - phi_k) for j, k <= i, X_i = A^(i) A^{-1}; per node the weight sqrt(det A)
(E - U)^(N/2 - 1), <K_i | phi> = tr X_i (E - U) / N and <K_i^2 | phi> = (E - U)^2 ((tr X_i)^2 +
2 tr X_i^2) / (N (N + 2)). The angles are nested from the last outwards in the excitation form
(the budget left for phi_{j-1} is 2 gamma_j sin((b_j - phi_j)/2) sin((b_j + phi_j)/2) with
2 gamma_j sin^2(b_j/2) the budget for phi_j, nothing cancels), phi_j = b_j sin t_j makes every
level analytic, and Gauss-Legendre rules in t_j converge geometrically; the oracle's own error is
bounded by n against 3n/2 nodes (printed as "oracle spread", the error of the n-node values, at
the ends of the ladder; the values used are the 3n/2-node ones there and the n-node ones
elsewhere: n = 24 gives ~1e-23 relative for N = 2 and 3). Only for D < 2 min_j gamma_j (no angle wraps around). It shares
no code with the library (no psi reduction, shell integrals, trace recurrences or cuts).
"""
import argparse
import json
import subprocess
import sys

import mpmath as mp


def gauss_legendre(n):
    """Nodes and weights of the n-point Gauss-Legendre rule on [-1, 1] at mp.mp.dps."""
    nodes, weights = [], []
    for k in range(1, n + 1):
        x = mp.cos(mp.pi * (k - mp.mpf(1) / 4) / (n + mp.mpf(1) / 2))
        for _ in range(100):
            p0, p1 = mp.mpf(1), x
            for m in range(2, n + 1):
                p0, p1 = p1, ((2 * m - 1) * x * p1 - (m - 1) * p0) / m
            dp = n * (x * p1 - p0) / (x * x - 1)
            dx = p1 / dp
            x -= dx
            if abs(dx) < mp.mpf(10) ** (-mp.mp.dps - 5):
                break
        nodes.append(x)
        weights.append(2 / ((1 - x * x) * dp * dp))
    return nodes, weights


def near_minimum(masses, lengths, g, excitation, nodes):
    """<K_i>_E, Var K_i, <cos phi_i>_E at the excitation D (mpf inputs)."""
    n = len(masses)
    tail = [sum(masses[j:]) for j in range(n)]
    gamma = [g * tail[j] * lengths[j] for j in range(n)]
    if not all(excitation < 2 * gj for gj in gamma):
        raise ValueError("D must stay below 2 min gamma_j")
    t_nodes, t_weights = gauss_legendre(nodes)
    half_pi = mp.pi / 2
    sums = [mp.mpf(0)] * (1 + 3 * n)
    phi = [mp.mpf(0)] * n

    def leaf(rest, jacobian):
        # A^(i) = m_i U_i U_i^T with the rows u_j = l_j (cos phi_j, sin phi_j) for j <= i (zero
        # below): tr X_i = m_i tr W_i and tr X_i^2 = m_i^2 tr W_i^2 with W_i = U_i^T A^{-1} U_i.
        u = [(lengths[j] * mp.cos(phi[j]), lengths[j] * mp.sin(phi[j])) for j in range(n)]
        a = mp.matrix(n, n)
        for j in range(n):
            for k in range(n):
                a[j, k] = tail[max(j, k)] * (u[j][0] * u[k][0] + u[j][1] * u[k][1])
        a_inv = mp.inverse(a)
        weight = jacobian * mp.sqrt(mp.det(a)) * rest ** (mp.mpf(n) / 2 - 1)
        sums[0] += weight
        for i in range(n):
            w = [[sum(u[j][p] * a_inv[j, k] * u[k][q] for j in range(i + 1) for k in range(i + 1))
                  for q in range(2)] for p in range(2)]
            trace = masses[i] * (w[0][0] + w[1][1])
            trace_squared = masses[i] ** 2 * (w[0][0] ** 2 + 2 * w[0][1] * w[1][0] + w[1][1] ** 2)
            sums[1 + i] += weight * trace * rest / n
            sums[1 + n + i] += weight * rest ** 2 * (trace ** 2 + 2 * trace_squared) / (n * (n + 2))
            sums[1 + 2 * n + i] += weight * mp.cos(phi[i])

    def level(j, budget, jacobian):
        b = 2 * mp.asin(mp.sqrt(budget / (2 * gamma[j])))
        for t, w in zip(t_nodes, t_weights):
            st, ct = mp.sin(half_pi * t), mp.cos(half_pi * t)
            phi[j] = b * st
            minus = b * ct * ct / (1 + st) if st >= 0 else b * (1 - st)
            plus = b * ct * ct / (1 - st) if st <= 0 else b * (1 + st)
            rest = 2 * gamma[j] * mp.sin(minus / 2) * mp.sin(plus / 2)
            w_here = jacobian * half_pi * w * b * ct
            if j > 0:
                level(j - 1, rest, w_here)
            else:
                leaf(rest, w_here)

    level(n - 1, excitation, mp.mpf(1))
    kinetic = [sums[1 + i] / sums[0] for i in range(n)]
    variance = [sums[1 + n + i] / sums[0] - kinetic[i] ** 2 for i in range(n)]
    cosine = [sums[1 + 2 * n + i] / sums[0] for i in range(n)]
    return kinetic, variance, cosine


def checked(masses, lengths, g, excitation, nodes):
    """The oracle at 3n/2 nodes and its largest relative difference from n nodes (<K>, Var K)."""
    coarse = near_minimum(masses, lengths, g, excitation, nodes)
    fine = near_minimum(masses, lengths, g, excitation, nodes * 3 // 2)
    spread = max(abs(a / b - 1) for qa, qb in zip(coarse[:2], fine[:2]) for a, b in zip(qa, qb))
    return fine, spread


def tanh_sinh(f, a, b, size, tolerance, scale_of=None):
    """Vector tanh-sinh quadrature of f (a list of `size` values) over [a, b], the step halved
    until every sum changes by less than `tolerance` times its scale: scale_of(sums)[c], by
    default |sums[c]|. tolerance None: the sums at h = 1/8 (a rough value)."""
    half, mid = (b - a) / 2, (a + b) / 2
    t_max = mp.mpf(4)

    def node(t):
        u = mp.pi / 2 * mp.sinh(t)
        x, w = mp.tanh(u), mp.pi / 2 * mp.cosh(t) / mp.cosh(u) ** 2
        if w == 0 or abs(x) == 1:
            return None
        return x, w

    total, h, previous = [mp.mpf(0)] * size, mp.mpf(1), None
    points = [mp.mpf(0)]
    points += [k * h for k in range(1, int(t_max / h) + 1)] + [-k * h for k in range(1, int(t_max / h) + 1)]
    while True:
        for t in points:
            xw = node(t)
            if xw is None:
                continue
            values = f(mid + half * xw[0])
            total = [s + xw[1] * v for s, v in zip(total, values)]
        estimate = [half * h * s for s in total]
        if tolerance is None and h <= mp.mpf(1) / 8:  # a rough value: h = 1/8, no test
            return estimate
        scales = scale_of(estimate) if scale_of and tolerance else [abs(e) for e in estimate]
        if tolerance is not None and previous is not None and all(abs(e - p) <= tolerance * sc
                                        for e, p, sc in zip(estimate, previous, scales)):
            return estimate
        previous = estimate
        h /= 2
        points = [(2 * k + 1) * h for k in range(int(t_max / h / 2) + 1)]
        points += [-t for t in points]
        if h < mp.mpf(2) ** -12:
            raise RuntimeError("tanh_sinh: no convergence")


def definition_2d(masses, lengths, g, energy, tolerance, floors=None):
    """N = 2 at any energy: the definition over (phi_1, phi_2) literally (src/engine/microcanonical/README.md), with
    the paper's closed forms det A = l1^2 l2^2 m2 (M - m2 c^2), tr X_1 = m1 / (M - m2 c^2)
    (c = cos(phi_2 - phi_1); X_1 has rank one, X_2 = 1 - X_1). phi_1 over its exact accessible
    arc, phi_2 over [0, pi] (the integrand is even) split where that arc opens or closes. Each
    fibre's integral is converged to `tolerance` relative or to `floors` (absolute, per quantity:
    tolerance x a rough value of the whole integral / pi), so that fibres where E - U is lost to
    rounding (a vanishing arc) do not stall it; floors=None: a rough pass (h = 1/8) first."""
    if floors is None and tolerance is not None:
        rough = definition_2d(masses, lengths, g, energy, None)
        floors = [tolerance * abs(r) / mp.pi for r in rough[3]]
    m1, m2 = masses
    l1, l2 = lengths
    big_m = m1 + m2
    g1, g2 = g * big_m * l1, g * m2 * l2
    cuts = [mp.mpf(0), mp.pi]
    for s in (-1, 1):
        x = (-energy - s * g1) / g2
        if -1 < x < 1:
            cuts.append(mp.acos(x))
    cuts.sort()

    def node(phi1, phi2):  # phi1 inside the arc: no indicator (rounding could flip it)
        rest = energy + g1 * mp.cos(phi1) + g2 * mp.cos(phi2)  # E - U
        c = mp.cos(phi2 - phi1)
        q = big_m - m2 * c * c
        w = l1 * l2 * mp.sqrt(m2 * q)
        t1 = m1 / q
        t2 = 2 - t1
        out = [w, w * t1 * rest / 2, w * t2 * rest / 2, w * mp.cos(phi1), w * mp.cos(phi2)]
        for trace, trace_squared in ((t1, t1 * t1), (t2, 2 - 2 * t1 + t1 * t1)):
            out.append(w * rest * rest * (trace * trace + 2 * trace_squared) / 8)
        return out

    def scales(sums):  # the cosine moments can vanish: compared with the weight
        if tolerance is None:
            return None
        return [max(abs(v) if c not in (3, 4) else max(abs(v), abs(sums[0])),
                    floors[c] / tolerance) for c, v in enumerate(sums)]

    def fibre(phi2):
        with mp.extradps(mp.mp.dps):  # the arc's half-width a = acos(x) loses digits near x = 1
            x = -(energy + g2 * mp.cos(phi2)) / g1
            if x >= 1:
                return [mp.mpf(0)] * 7
            a = mp.pi if x <= -1 else mp.acos(x)
        a = +a
        return tanh_sinh(lambda phi1: node(phi1, phi2), -a, a, 7, tolerance, scales)

    total = [mp.mpf(0)] * 7
    for lo, hi in zip(cuts, cuts[1:]):
        part = tanh_sinh(fibre, lo, hi, 7, tolerance, scales)
        total = [t + p for t, p in zip(total, part)]
    kinetic = [total[1] / total[0], total[2] / total[0]]
    cosine = [total[3] / total[0], total[4] / total[0]]
    variance = [total[5 + i] / total[0] - kinetic[i] ** 2 for i in range(2)]
    return kinetic, variance, cosine, total


def separatrices(pendavg):
    """N = 2: every critical energy +-gamma_1 +-gamma_2 > E_min, exactly and 1e-9 top off, and
    1.5, 10 and 1000 times the top, against definition_2d at the tolerances 10^(14 - digits) and
    10^(10 - digits) (their change printed as "oracle change")."""
    chains = [(["1", "1"], ["1", "1"], "1"), (["1", "0.3"], ["1.3", "0.6"], "9.81")]
    worst_ratio = 0
    print("masses lengths g | E | rel. error K, Var K | |dev|/error K, Var K, cos phi | oracle change")
    for masses, lengths, g in chains:
        m = [mp.mpf(float(x)) for x in masses]
        l = [mp.mpf(float(x)) for x in lengths]
        gg = mp.mpf(float(g))
        g1, g2 = gg * (m[0] + m[1]) * l[0], gg * m[1] * l[1]
        top = float(g1 + g2)
        energies = []
        for e in sorted({float(-g1 + g2), float(g1 - g2), top}):
            energies += [e, e + 1e-9 * top, e - 1e-9 * top]
        energies += [1.5 * top, 10 * top, 1e3 * top]
        for e in energies:
            coarse = definition_2d(m, l, gg, mp.mpf(e), mp.mpf(10) ** (14 - mp.mp.dps))
            kin, var, cos, _ = definition_2d(m, l, gg, mp.mpf(e), mp.mpf(10) ** (10 - mp.mp.dps))
            change = max(abs(a / b - 1) for qa, qb in zip(coarse[:2], (kin, var))
                         for a, b in zip(qa, qb))
            o = run(pendavg, masses, lengths, g, "energy", repr(e))
            rel_k = max(abs(mp.mpf(v) / t - 1) for v, t in zip(o["K"], kin))
            rel_v = max(abs(mp.mpf(v) / t - 1) for v, t in zip(o["var_K"], var))
            ratio = [max(abs(mp.mpf(v) - t) / mp.mpf(err) for v, err, t in
                         zip(o[key], o[key + "_error"], truth))
                     for key, truth in (("K", kin), ("var_K", var), ("cos_phi", cos))]
            worst_ratio = max([worst_ratio] + ratio)
            print(f"{','.join(masses)} {','.join(lengths)} {g} | {e!r:22} | {mp.nstr(rel_k, 2):8} "
                  f"{mp.nstr(rel_v, 2):8} | " + " ".join(f"{mp.nstr(r, 2):8}" for r in ratio)
                  + f" | {mp.nstr(change, 2)}", flush=True)
    print("worst |dev|/error:", mp.nstr(worst_ratio, 3))
    return 0 if worst_ratio < 1 else 1


def run(pendavg, masses, lengths, g, state, value):
    command = [pendavg, "average", "--masses", ",".join(masses), "--lengths", ",".join(lengths),
               "--g", g, "--" + state, value, "--format", "json"]
    return json.loads(subprocess.run(command, check=True, capture_output=True, text=True).stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pendavg", nargs="?")
    parser.add_argument("--reference", nargs=4, metavar=("MASSES", "LENGTHS", "G", "D"))
    parser.add_argument("--digits", type=int, default=40)
    parser.add_argument("--nodes", type=int, default=24)
    parser.add_argument("--separatrix", action="store_true",
                        help="N = 2 at the separatrix energies and above the top instead")
    args = parser.parse_args()
    mp.mp.dps = args.digits
    if args.reference:
        masses, lengths, g, d = args.reference
        values, spread = checked([mp.mpf(x) for x in masses.split(",")],
                                 [mp.mpf(x) for x in lengths.split(",")], mp.mpf(g), mp.mpf(d),
                                 args.nodes)
        for name, v in zip(("K", "var_K", "cos_phi"), values):
            print(name, [mp.nstr(x, args.digits - 5) for x in v])
        print("oracle n vs 3n/2 relative difference", mp.nstr(spread, 3))
        return
    if not args.pendavg:
        parser.error("PENDAVG (the CLI binary) or --reference")
    if args.separatrix:
        return separatrices(args.pendavg)
    chains = [(["1", "1"], ["1", "1"], "1"), (["1", "0.3"], ["1.3", "0.6"], "9.81"),
              (["1", "1", "1"], ["1", "1", "1"], "1"),
              (["0.7", "1.9", "0.4"], ["0.8", "1.1", "1.7"], "2.5")]
    print("N masses lengths g | D/|E_min| from | worst rel. error K, Var K | worst |dev|/error K, "
          "Var K, cos phi | oracle spread")
    worst = {"rel_K": 0, "rel_V": 0, "ratio": 0}
    for masses, lengths, g in chains:
        # the CLI's chain: every parameter the double nearest the decimal, read exactly here
        m = [mp.mpf(float(x)) for x in masses]
        l = [mp.mpf(float(x)) for x in lengths]
        gg = mp.mpf(float(g))
        depth = sum(gg * sum(m[j:]) * l[j] for j in range(len(m)))  # -E_min, exact
        for k in range(4, 13):
            d_double = float(mp.mpf(10) ** -k * depth)
            e_double = float(-depth + mp.mpf(d_double))
            for state, text, d_exact in (("excitation", repr(d_double), mp.mpf(d_double)),
                                         ("energy", repr(e_double), mp.mpf(e_double) + depth)):
                if state == "excitation" and k in (4, 12):
                    (kin, var, cos), spread = checked(m, l, gg, d_exact, args.nodes)
                    spread_text = mp.nstr(spread, 2)
                else:
                    kin, var, cos = near_minimum(m, l, gg, d_exact, args.nodes)
                    spread_text = "-"
                o = run(args.pendavg, masses, lengths, g, state, text)
                rel_k = max(abs(mp.mpf(v) / t - 1) for v, t in zip(o["K"], kin))
                rel_v = max(abs(mp.mpf(v) / t - 1) for v, t in zip(o["var_K"], var))
                ratio = [max(abs(mp.mpf(v) - t) / mp.mpf(e) for v, e, t in
                             zip(o[key], o[key + "_error"], truth))
                         for key, truth in (("K", kin), ("var_K", var), ("cos_phi", cos))]
                worst["rel_K"] = max(worst["rel_K"], rel_k)
                worst["rel_V"] = max(worst["rel_V"], rel_v)
                worst["ratio"] = max([worst["ratio"]] + ratio)
                print(f"{len(m)} {','.join(masses)} {','.join(lengths)} {g} | 1e-{k:<2} {state:10} | "
                      f"{mp.nstr(rel_k, 2):8} {mp.nstr(rel_v, 2):8} | "
                      + " ".join(f"{mp.nstr(r, 2):8}" for r in ratio) + f" | {spread_text}",
                      flush=True)
    print("worst relative error <K_i>:", mp.nstr(worst["rel_K"], 3), " Var K_i:",
          mp.nstr(worst["rel_V"], 3), " worst |dev|/error:", mp.nstr(worst["ratio"], 3))
    return 0 if worst["ratio"] < 1 else 1


if __name__ == "__main__":
    sys.exit(main())
