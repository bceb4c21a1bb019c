// SPDX-License-Identifier: GPL-3.0-or-later
// Microcanonical averages (pendavg/microcanonical.hpp): the three rules, the two entry points
// (energy, excitation) and their explicit instantiations (double, long double, mpfr_real).
#include "domain.hpp"
#include "engine/microcanonical/microcanonical.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"
#include "engine/numerics/text.hpp"

#include <algorithm>

#include <cmath>
#include <optional>
#include <sstream>
#include <string>

namespace pendavg {

namespace detail::microcanonical {

/// The integrated quantities of a rule, before they become averages: Z = ∫ T~ d theta and the
/// numerators (integrals over the (N-1)-torus of the quantities of NestedShellIntegral), each
/// with an absolute error estimate.
template <class Real>
struct ShellSums {
  std::vector<Real> value, error;  // q = 1 + 3N entries each
  std::size_t evaluations = 0;
  bool converged = true;
};

template <class Real>
typename NestedShellIntegral<Real>::Shared nested_shared(const Chain<Real>& chain,
                                                         const ShellSetup<Real>& setup,
                                                         std::shared_ptr<const TanhSinhTable<Real>> table,
                                                         const MicrocanonicalOptions& options,
                                                         const Real& tolerance) {
  const std::size_t n = setup.n;
  typename NestedShellIntegral<Real>::Shared shared;
  shared.chain = &chain;
  shared.setup = &setup;
  shared.table = std::move(table);
  // each level gets a quarter of the budget: the inner errors are carried outwards
  shared.tolerance = tolerance / 4;
  shared.max_level = options.max_level;
  shared.control = &options.control;
  shared.targets.resize(n);
  shared.light.assign(n, false);
  const bool below_zero = setup.excitation < setup.gamma_sum;  // E < 0
  for (std::size_t j = 1; j < n; ++j) {
    // t = | |E| + sum_{k > j} eps_k gamma_k | over every sign pattern. For E < 0, |E| = S - D and
    // t = |head_j - d| with d = D - P, P = sum of 2 gamma_k over the k with eps_k = +1: where
    // d <= head_j the deficit d is kept (cuts near the bottom of the well without cancellation).
    std::vector<Real> subset{Real(0)};  // P over every subset of the links beyond j
    for (std::size_t k = j + 1; k < n; ++k) {
      const std::size_t count = subset.size();
      for (std::size_t a = 0; a < count; ++a) subset.push_back(subset[a] + 2 * setup.gamma[k]);
    }
    std::vector<CriticalRadius<Real>> values;
    const Real head = setup.head_gamma[j];
    const Real tail = setup.gamma_sum - head;
    for (const Real& plus : subset) {
      CriticalRadius<Real> t;
      if (below_zero) {
        const Real d = setup.excitation - plus;
        if (d <= head) {
          t.radius = head - d;
          t.deficit = d;
          t.has_deficit = true;
        } else {
          t.radius = d - head;
        }
      } else {
        t.radius = abs(setup.energy + plus - tail);
      }
      values.push_back(t);
    }
    std::sort(values.begin(), values.end(),
              [](const CriticalRadius<Real>& a, const CriticalRadius<Real>& b) {
                return a.radius < b.radius;
              });
    values.erase(std::unique(values.begin(), values.end(),
                             [](const CriticalRadius<Real>& a, const CriticalRadius<Real>& b) {
                               return a.radius == b.radius;
                             }),
                 values.end());
    shared.targets[j] = values;
    shared.light[j] = chain.mass(j - 1) / chain.tail_mass(j - 1) < Real(0.09);
  }
  return shared;
}

template <class Real>
ShellSums<Real> integral_sums(const Chain<Real>& chain, const ShellSetup<Real>& setup,
                              const MicrocanonicalOptions& options, const Real& tolerance) {
  auto shared = nested_shared(chain, setup, TanhSinhTable<Real>::shared(), options, tolerance);
  const std::size_t q = 1 + 3 * setup.n;
  const auto run = [&](std::size_t& evaluations, std::size_t& unconverged) {
    NestedShellIntegral<Real> master(shared, options.threads);
    std::vector<std::unique_ptr<NestedShellIntegral<Real>>> workers;
    if (options.threads > 1) {
      for (int t = 0; t < options.threads; ++t) {
        workers.push_back(std::make_unique<NestedShellIntegral<Real>>(shared, 1));
      }
      master.workers = &workers;
    }
    std::vector<Real> all = master.integrate();
    evaluations += master.evaluations;
    unconverged += master.unconverged_pieces;
    for (const auto& w : workers) {
      evaluations += w->evaluations;
      unconverged += w->unconverged_pieces;
    }
    return all;
  };
  std::size_t evaluations = 0, unconverged = 0;
  if (setup.n > 2) {
    // Rough first pass (h = 1/2 on every piece): the global sizes behind the absolute floors.
    shared.max_level = 1;
    shared.force_stop = true;
    const std::vector<Real> rough = run(evaluations, unconverged);
    shared.max_level = options.max_level;
    shared.force_stop = false;
    shared.floor.assign(setup.n, std::vector<Real>(q, Real(0)));
    Real outer_measure = 1;
    for (std::size_t j = 1; j < setup.n; ++j) {
      for (std::size_t c = 0; c < q; ++c) {
        const Real size = NestedShellIntegral<Real>::own_scale(c, setup.n) ? abs(rough[c])
                                                                            : abs(rough[0]);
        shared.floor[j][c] = tolerance / 16 * size / outer_measure;
      }
      outer_measure *= 2 * pi<Real>();
    }
  }
  const std::vector<Real> all = run(evaluations, unconverged);
  ShellSums<Real> out;
  out.value.assign(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(q));
  out.error.assign(all.begin() + static_cast<std::ptrdiff_t>(q), all.end());
  out.evaluations = evaluations;
  out.converged = unconverged == 0;
  return out;
}

/// The plain tensor trapezoid rule on the (N-1)-torus, n = 16, 32, ... per dimension.
template <class Real>
ShellSums<Real> torus_sums(const Chain<Real>& chain, const ShellSetup<Real>& setup,
                           const MicrocanonicalOptions& options, const Real& tolerance) {
  using std::pow;
  const std::size_t n = setup.n, dims = n - 1, q = 1 + 3 * n;
  const auto shared =
      nested_shared(chain, setup, TanhSinhTable<Real>::shared(), options, tolerance);
  ShellSums<Real> out;
  out.value.assign(q, Real(0));
  out.error.assign(q, Real(0));
  if (dims == 0) {
    NestedShellIntegral<Real> node(shared, 1);
    out.value = node.integrate();
    out.value.resize(q);
    out.evaluations = 1;
    return out;
  }
  const Real two_pi = 2 * pi<Real>();
  std::vector<Real> previous;
  out.converged = false;
  for (std::size_t points = 16; points <= options.max_points_per_dim; points *= 2) {
    if (std::pow(double(points), double(dims)) > 4e8) break;
    std::size_t inner = 1;
    for (std::size_t d = 1; d < dims; ++d) inner *= points;
    std::vector<std::vector<Real>> partial(points, std::vector<Real>(q, Real(0)));
    const int team = std::max(options.threads, 1);
    ParallelErrors errors;  // an exception may not leave the parallel region
#if defined(_OPENMP)
#pragma omp parallel num_threads(team) if (team > 1)
#endif
    {
      NestedShellIntegral<Real> node(shared, 1);
      std::vector<Real> theta(n, Real(0)), f(2 * q);
      std::vector<std::size_t> index(dims);
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1)
#endif
      for (std::ptrdiff_t k0 = 0; k0 < static_cast<std::ptrdiff_t>(points); ++k0) {
        errors.capture([&] {
          std::vector<detail::CompensatedSum<Real>> sums(q);
          for (std::size_t r = 0; r < inner; ++r) {
            std::size_t rest = r;
            theta[1] = two_pi * Real(static_cast<double>(k0)) / Real(static_cast<double>(points));
            for (std::size_t d = 1; d < dims; ++d) {
              theta[d + 1] = two_pi * Real(static_cast<double>(rest % points)) /
                             Real(static_cast<double>(points));
              rest /= points;
            }
            node.evaluate_at(theta.data(), f.data());
            for (std::size_t c = 0; c < q; ++c) sums[c].add(f[c]);
          }
          for (std::size_t c = 0; c < q; ++c)
            partial[static_cast<std::size_t>(k0)][c] = sums[c].value();
        });
      }
    }
    errors.rethrow();
    (void)team;
    std::vector<Real> value(q, Real(0));
    const Real cell =
        pow(two_pi / Real(static_cast<double>(points)), Real(static_cast<double>(dims)));
    for (std::size_t c = 0; c < q; ++c) {
      detail::CompensatedSum<Real> s;
      for (std::size_t k0 = 0; k0 < points; ++k0) s.add(partial[k0][c]);
      value[c] = cell * s.value();
    }
    out.evaluations += static_cast<std::size_t>(std::pow(double(points), double(dims)));
    out.value = value;
    if (!previous.empty()) {
      bool done = true;
      for (std::size_t c = 0; c < q; ++c) {
        out.error[c] = abs(value[c] - previous[c]);
        const Real scale =
            NestedShellIntegral<Real>::own_scale(c, n) ? abs(value[c]) : abs(value[0]);
        if (!(out.error[c] <= tolerance * scale)) done = false;
      }
      if (done) {
        out.converged = true;
        break;
      }
    } else {
      for (std::size_t c = 0; c < q; ++c) out.error[c] = abs(value[c]) + abs(value[0]);
    }
    previous = value;
  }
  return out;
}

/// Randomized lattice QMC: per shift, sums of w, w^2, w tr X_i F_{p+1}/F_p, w cos G_p/F_p and
/// w ((tr X_i)^2 + 2 tr X_i^2) F_{p+2}/F_p, with the weights kept as exp(log w - log_scale): the
/// reference log_scale is the first point's log weight, raised when a later one exceeds it by
/// 256 (log-sum-exp with a running maximum), so no weight under- or overflows for any N or E.
template <class Real>
struct QmcShellShift {
  detail::CompensatedSum<Real> weight, weight_squared;
  std::vector<detail::CompensatedSum<Real>> kinetic, cosine, kinetic_squared;
  Real log_scale{0};
  bool scaled = false;  ///< log_scale is set (a point reached the shell)
  explicit QmcShellShift(std::size_t n = 0) : kinetic(n), cosine(n), kinetic_squared(n) {}
  void rescale(const Real& factor) {
    const auto scale = [](detail::CompensatedSum<Real>& s, const Real& f) {
      s.sum *= f;
      s.compensation *= f;
    };
    scale(weight, factor);
    scale(weight_squared, factor * factor);
    for (auto& s : kinetic) scale(s, factor);
    for (auto& s : cosine) scale(s, factor);
    for (auto& s : kinetic_squared) scale(s, factor);
  }
};

template <class Real>
QmcShellShift<Real> qmc_shift_sums(const Chain<Real>& chain, const ShellSetup<Real>& setup,
                                   const Real& beta_star,
                                   const std::vector<detail::qmc::BestFisherMap<Real>>& maps,
                                   const std::vector<Real>& shift, std::size_t points,
                                   const std::vector<std::uint32_t>& generator) {
  const std::size_t n = setup.n;
  QmcShellShift<Real> sums(n);
  TraceWorkspace<Real> ws(chain);
  std::vector<Real> phi(n), sphi(n), cphi(n), delta(n > 1 ? n - 1 : 1);
  const std::uint64_t mask = points - 1;
  const Real inv_points = Real(1) / Real(static_cast<double>(points));
  for (std::uint64_t k = 0; k < points; ++k) {
    Real log_ratio_sum = 0;
    Real zx = 0, zy = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const std::uint64_t kz = (k * generator[j]) & mask;
      Real u = Real(static_cast<double>(kz)) * inv_points + shift[j];
      if (u >= 1) u -= 1;
      Real log_ratio;
      maps[j].map(u, phi[j], sphi[j], cphi[j], log_ratio);
      log_ratio_sum += log_ratio;
      zx += setup.gamma[j] * cphi[j];
      zy += setup.gamma[j] * sphi[j];
    }
    const Real rho = sqrt(zx * zx + zy * zy);
    // S - rho without cancellation, and E + rho = D - (S - rho) below E = 0: the excitation form
    const Real deficit = rho > 0 ? well_deficit(setup.gamma, cphi.data(), sphi.data(), zx, zy, rho)
                                 : setup.gamma_sum;
    const ShellMoments<Real> m =
        setup.shell(setup.energy, rho, setup.depth(rho, deficit), setup.scale);
    if (m.weight == 0 && m.kinetic == 0) continue;
    for (std::size_t i = 0; i + 1 < n; ++i) delta[i] = phi[i + 1] - phi[i];
    const NodeTraces<Real>& t = node_traces_relative(chain, delta.data(), ws);
    const Real x = beta_star * rho;
    const Real log_bessel = x > 0 ? Real(log(scaled_bessel_i01(x).i0e)) : Real(0);
    const Real log_base = log_ratio_sum + t.log_sqrt_det_A - setup.log_hadamard +
                          beta_star * deficit - log_bessel;
    if (!sums.scaled) {
      sums.log_scale = log_base;
      sums.scaled = true;
    } else if (log_base > sums.log_scale + 256) {
      sums.rescale(exp(sums.log_scale - log_base));
      sums.log_scale = log_base;
    }
    const Real base = exp(log_base - sums.log_scale);
    const Real w = base * m.weight;
    sums.weight.add(w);
    sums.weight_squared.add(w * w);
    const Real bk = base * m.kinetic, bk2 = base * m.kinetic_squared;
    const Real bc = rho > 0 ? Real(base * m.cosine / rho) : Real(0);
    for (std::size_t i = 0; i < n; ++i) {
      const Real& tr = t.trace_X[i];
      sums.kinetic[i].add(bk * tr);
      sums.cosine[i].add(bc * (cphi[i] * zx + sphi[i] * zy));
      sums.kinetic_squared[i].add(bk2 * (tr * tr + 2 * t.trace_X_squared[i]));
    }
  }
  return sums;
}

/// 1 - I1(x)/I0(x) >= 0 (the scaled Bessel functions' difference; only the proposal uses it).
template <class Real>
Real bessel_gap(const Real& x) {
  const ScaledBesselI01<Real> b = scaled_bessel_i01(x);
  return (b.i0e - b.i1e) / b.i0e;
}

/// beta* of the qmc proposal from the excitation D (see matched_beta).
template <class Real>
Real matched_beta_excitation(const Chain<Real>& chain, const Real& excitation) {
  const std::size_t n = chain.size();
  const Real half_n = Real(static_cast<double>(n)) / 2;
  // N/(2 beta) + sum_j gamma_j (1 - I1/I0)(beta gamma_j) - D: the proposal's mean excitation
  // (equipartition kinetic energy plus the von Mises potential energy above U_min) minus D,
  // decreasing in beta; no cancellation near the bottom of the well.
  const auto excess = [&](const Real& beta) {
    Real u = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const Real g = chain.potential_coefficient(j);
      u += g * bessel_gap(Real(beta * g));
    }
    return half_n / beta + u - excitation;
  };
  Real lo = 1, hi = 1;
  for (int i = 0; i < 2000 && excess(lo) < 0; ++i) lo /= 2;
  for (int i = 0; i < 2000 && excess(hi) > 0; ++i) hi *= 2;
  for (int i = 0; i < 200; ++i) {
    const Real mid = sqrt(lo * hi);
    if (excess(mid) > 0) {
      lo = mid;
    } else {
      hi = mid;
    }
    if (hi - lo <= Real(1e-13) * hi) break;
  }
  return sqrt(lo * hi);
}

/// The engine's domain in double (and long double, checked at double's range): the node sums
/// carry (E - U)^2 and mass ratios up to M / m_min squared, so E, D = E - E_min and the well's
/// depth sum_j g S_j l_j must stay below 1e150, M / m_min too, and D must be a normal number.
/// Refused before any work, pointing to MPFR where a rule runs in it.
template <class Real>
void check_double_range(const Chain<Real>& chain, const Real& energy, const Real& excitation,
                        MicrocanonicalOptions::Rule rule) {
  using std::abs;
  const std::string advice = rule == MicrocanonicalOptions::Rule::qmc
                                 ? "outside the double range of the microcanonical engine"
                                 : "request 17 or more digits (MPFR)";
  constexpr double largest = 1e150;
  domain::check_double_scales(chain, static_cast<const Real*>(nullptr), "microcanonical");
  Real depth = 0;
  for (std::size_t j = 0; j < chain.size(); ++j) depth += chain.potential_coefficient(j);
  const auto text = [](const Real& x) { return short_decimal(static_cast<double>(x)); };
  if (!(abs(energy) <= Real(largest)) || !(excitation <= Real(largest)) ||
      !(depth <= Real(largest)))
    throw invalid_input("microcanonical: the energy scale (E = " + text(energy) + ", E - E_min = " +
                        text(excitation) + ", well depth " + text(depth) +
                        ") is beyond 1e150, where the shell's squares leave double's range; " +
                        advice);
  if (excitation < Real(std::numeric_limits<double>::min()))
    throw invalid_input("microcanonical: the excitation E - E_min = " + text(excitation) +
                        " is subnormal in double; " + advice);
  // N = 2 with a light top particle: <K_1>_E lost digits below mu1 = m1/M = 1e-8 while its error
  // estimate did not (measured against 30 digits: mu1 = 1e-10 off by 3x its error, 1e-20 by
  // 1e5x, 1e-40 by 2%; 1e-8 and above covered), so double refuses it.
  if (chain.size() == 2 && rule != MicrocanonicalOptions::Rule::qmc &&
      !(chain.mass(0) / chain.total_mass() >= Real(1e-8)))
    throw invalid_input("microcanonical: the top mass is m1/M = " +
                        text(chain.mass(0) / chain.total_mass()) +
                        " of the total, below the double engine's accurate range (1e-8); " +
                        advice);
  // N >= 3 with a particle below 1e-8 of the total: the nested integral ran unbounded (masses
  // 2.454, 1e-82, 7.361 at E = -1): refused like N = 2's light top particle.
  if (chain.size() >= 3 && rule != MicrocanonicalOptions::Rule::qmc)
    for (std::size_t i = 0; i < chain.size(); ++i)
      if (!(chain.mass(i) / chain.total_mass() >= Real(1e-8)))
        throw invalid_input("microcanonical: particle " + std::to_string(i + 1) + " is " +
                            text(chain.mass(i) / chain.total_mass()) +
                            " of the total mass, below the double quadrature's accurate range "
                            "(1e-8)");
  // Link lengths far apart: the density of states lost digits beyond its error (lengths 1 and
  // 1e81 off by 5x its error; 1e40 still covered), so double takes length ratios up to 1e30.
  {
    const domain::ChainScales scales =
        domain::chain_scales(chain, static_cast<const Real*>(nullptr));
    constexpr double log2_length_ratio_max = 99.65784284662087;  // log2(1e30)
    if (!(scales.longest_length - scales.shortest_length <= log2_length_ratio_max))
      throw invalid_input("microcanonical: the longest link is more than 1e30 times the "
                          "shortest, beyond the double engine's accurate range; " + advice);
  }
  const Real lightest = *std::min_element(chain.masses().begin(), chain.masses().end());
  if (!(chain.total_mass() / lightest <= Real(largest)))
    throw invalid_input("microcanonical: the total mass is " +
                        text(chain.total_mass() / lightest) +
                        " times the lightest mass, beyond double's range (1e150); " + advice);
}

/// Everything the run checks before its work (the rule against N and the digits, the qmc
/// options, the double range), for a chain and state at the working precision.
template <class Real>
void check_run(const Chain<Real>& chain, const Real& energy, const Real& excitation,
               const MicrocanonicalOptions& options) {
  using Rule = MicrocanonicalOptions::Rule;
  const std::size_t n = chain.size();
  const Rule rule = resolve_microcanonical_rule(n, options.rule);
  if (rule == Rule::integral && n > 6) {
    throw invalid_input("microcanonical: the integral rule is for N <= 6; use qmc for N = " +
                        std::to_string(n));
  }
  if (rule == Rule::torus && n > 5) {
    throw invalid_input("microcanonical: the torus rule is for N <= 5; use qmc for N = " +
                        std::to_string(n));
  }
  if (rule == Rule::torus && options.max_points_per_dim < 32) {
    throw invalid_input("microcanonical: max_points_per_dim must be >= 32");
  }
  if (options.digits != 0 && rule == Rule::qmc) {
    throw invalid_input("microcanonical: qmc (automatic for N >= 5) runs in double only; "
                        "digits > 16 need the integral or torus rule (N <= 4)");
  }
  if (rule == Rule::qmc) {
    using namespace detail::qmc;
    const std::size_t points = options.points;
    if (points < 1024 || points > (std::size_t(1) << lattice_table_max_log2) ||
        (points & (points - 1)) != 0) {
      throw invalid_input("microcanonical qmc: points must be a power of two in [2^10, 2^16]");
    }
    if (options.shifts < 4) throw invalid_input("microcanonical qmc: at least 4 random shifts");
    if (!(options.sigmas >= 0) || !std::isfinite(options.sigmas)) {
      throw invalid_input("microcanonical qmc: sigmas must be positive (or 0: automatic)");
    }
    if (!(options.proposal_beta >= 0) || !std::isfinite(options.proposal_beta)) {
      throw invalid_input("microcanonical qmc: proposal_beta must be >= 0 and finite");
    }
    if (n > lattice_max_dimension) {
      throw invalid_input("microcanonical qmc: the built-in lattices cover N <= " +
                          std::to_string(lattice_max_dimension));
    }
  }
  if constexpr (!is_mpfr_v<Real>) check_double_range(chain, energy, excitation, rule);
}

/// The constants every rule's averages share: the rounding budget per quantity, N, the norm of
/// <K_i^2 | phi, E>, and log of the factor from the shell sums to Omega(E).
template <class Real>
struct ShellUnits {
  Real rounding, nn, second_moment_norm, log_factor;
};

/// Per-shift totals of the qmc rule at one reference scale: per[r] = (W, W K_i (n), W cos_i (n),
/// W K_i^2 (n)), the totals of W and W^2, and the common log scale.
template <class Real>
struct ShellShiftTotals {
  std::vector<std::vector<Real>> per;
  Real total_w{0}, total_w2{0}, log_scale{0};
};

template <class Real>
ShellShiftTotals<Real> shell_shift_totals(const std::vector<QmcShellShift<Real>>& sums,
                                          std::size_t n) {
  const std::size_t shifts = sums.size();
  ShellShiftTotals<Real> t;
  // Every shift's sums at the largest reference scale.
  bool any = false;
  Real log_scale = 0;
  for (const QmcShellShift<Real>& s : sums) {
    if (!s.scaled) continue;
    if (!any || s.log_scale > log_scale) log_scale = s.log_scale;
    any = true;
  }
  if (!any) throw invalid_input("microcanonical qmc: no point reached the shell");
  // Per-shift totals; every reported quantity is a ratio of them: jackknife over shifts.
  const std::size_t q = 1 + 3 * n;
  std::vector<std::vector<Real>> per(shifts, std::vector<Real>(q, Real(0)));
  Real total_w = 0, total_w2 = 0;
  for (std::size_t r = 0; r < shifts; ++r) {
    if (!sums[r].scaled) continue;
    const Real f = exp(sums[r].log_scale - log_scale);
    per[r][0] = f * sums[r].weight.value();
    for (std::size_t i = 0; i < n; ++i) {
      per[r][1 + i] = f * sums[r].kinetic[i].value();
      per[r][1 + n + i] = f * sums[r].cosine[i].value();
      per[r][1 + 2 * n + i] = f * sums[r].kinetic_squared[i].value();
    }
    total_w += per[r][0];
    total_w2 += f * f * sums[r].weight_squared.value();
  }
  if (!(total_w > 0)) throw invalid_input("microcanonical qmc: no point reached the shell");
  t.per = std::move(per);
  t.total_w = total_w;
  t.total_w2 = total_w2;
  t.log_scale = log_scale;
  return t;
}

/// The qmc rule: <K_i>_E, <cos phi_i>_E, Var K_i, <K>_E and Omega(E) with jackknife bars over
/// the random shifts of the lattice, from the Best-Fisher proposal at beta*.
template <class Real>
void qmc_shell_averages(const Chain<Real>& chain, const ShellSetup<Real>& setup,
                        const MicrocanonicalOptions& options, int threads,
                        const ShellUnits<Real>& units, MicrocanonicalAverages<Real>& out) {
  using namespace detail::qmc;
  const std::size_t n = chain.size();
  const Real& rounding = units.rounding;
  const Real& nn = units.nn;
  const std::size_t points = options.points;
  unsigned log2_points = 0;
  while ((std::size_t(1) << log2_points) < points) ++log2_points;
  const auto& row = lattice_table[log2_points - lattice_table_min_log2];
  const std::vector<std::uint32_t> generator(row, row + n);
  const Real beta_star = options.proposal_beta > 0 ? Real(options.proposal_beta)
                                                   : matched_beta_excitation(chain, setup.excitation);
  std::vector<BestFisherMap<Real>> maps;
  Real log_envelope = 0;  // log prod_j (1 + rho_j) / (2 pi (1 - rho_j))
  for (std::size_t j = 0; j < n; ++j) {
    maps.emplace_back(Real(beta_star * setup.gamma[j]));
    log_envelope += log((1 + maps[j].rho) / (2 * pi<Real>() * (1 - maps[j].rho)));
  }
  const std::size_t shifts = options.shifts;
  const std::vector<std::vector<Real>> shift =
      detail::qmc::random_shifts<Real>(shifts, n, options.seed);
  std::vector<QmcShellShift<Real>> sums(shifts, QmcShellShift<Real>(n));
  const int team = std::max(threads, 1);
  ParallelErrors shift_errors;  // an exception may not leave the parallel region
  std::size_t shifts_done = 0;
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(dynamic, 1) if (team > 1)
#endif
  for (std::ptrdiff_t r = 0; r < static_cast<std::ptrdiff_t>(shifts); ++r) {
    shift_errors.capture([&] {
      const std::size_t rr = static_cast<std::size_t>(r);
      if (options.control.stop_requested()) throw interrupted("microcanonical: stopped");
      sums[rr] = qmc_shift_sums(chain, setup, beta_star, maps, shift[rr], points, generator);
#if defined(_OPENMP)
#pragma omp critical(pendavg_microcanonical_progress)
#endif
      options.control.report(static_cast<double>(++shifts_done) / static_cast<double>(shifts));
    });
  }
  shift_errors.rethrow();
  (void)team;
  const ShellShiftTotals<Real> totals = shell_shift_totals(sums, n);
  const std::vector<std::vector<Real>>& per = totals.per;
  const std::size_t q = 1 + 3 * n;
  // quantities: <K_i> (n), <cos_i> (n), <K> (1), Z~ (1), Var K_i (n)
  const std::size_t count = 3 * n + 2;
  const Real z_norm = exp(log(2 * pi<Real>()) + log_envelope) *
                      Real(static_cast<double>(points));
  const auto quantities = [&](std::size_t skip) {
    std::vector<Real> t(q, Real(0)), res(count);
    Real used = 0;
    for (std::size_t r = 0; r < shifts; ++r) {
      if (r == skip) continue;
      used += 1;
      for (std::size_t c = 0; c < q; ++c) t[c] += per[r][c];
    }
    Real total = 0;
    for (std::size_t i = 0; i < n; ++i) {
      res[i] = setup.scale * t[1 + i] / (nn * t[0]);
      res[n + i] = t[1 + n + i] / t[0];
      total += res[i];
      res[2 * n + 2 + i] = setup.scale * setup.scale * t[1 + 2 * n + i] /
                               (units.second_moment_norm * t[0]) -
                           res[i] * res[i];
    }
    res[2 * n] = total;
    res[2 * n + 1] = t[0] / (used * z_norm);
    return res;
  };
  const std::vector<Real> est = quantities(shifts);
  std::vector<std::vector<Real>> leave(shifts);
  for (std::size_t r = 0; r < shifts; ++r) leave[r] = quantities(r);
  const std::vector<Real> se = detail::qmc::jackknife_standard_errors(leave, count);
  const Real sig = Real(options.sigmas > 0 ? options.sigmas : qmc_default_sigmas(shifts));
  out.quadrature = Method::qmc;
  out.work_unit = WorkUnit::samples;
  out.evaluations = points * shifts;
  out.proposal_beta = beta_star;
  out.effective_sample_fraction = totals.total_w * totals.total_w /
                                  (totals.total_w2 * Real(static_cast<double>(points * shifts)));
  constexpr ErrorKind kind = ErrorKind::statistical;
  out.error_kind = kind;
  for (std::size_t i = 0; i < n; ++i) {
    out.kinetic[i] = {est[i], sig * se[i] + rounding * abs(est[i]), kind};
    out.cos_angle[i] = {est[n + i], sig * se[n + i] + rounding, kind};
    const Real second = est[2 * n + 2 + i] + est[i] * est[i];
    out.kinetic_variance[i] = {est[2 * n + 2 + i],
                               sig * se[2 * n + 2 + i] + rounding * abs(second), kind};
  }
  out.kinetic_total = {est[2 * n], sig * se[2 * n] + rounding * abs(est[2 * n]), kind};
  const Real z = est[2 * n + 1], z_error = sig * se[2 * n + 1] + rounding * z;
  const Real density_factor = exp(units.log_factor + totals.log_scale);
  out.density_of_states = {density_factor * z, density_factor * z_error, kind};
}

/// The integral and torus rules: the averages as ratios of the shell integrals, their errors
/// propagated from the integrals' (kind estimate).
template <class Real>
void quadrature_shell_averages(const Chain<Real>& chain, const ShellSetup<Real>& setup,
                               const MicrocanonicalOptions& run, const Real& tolerance,
                               MicrocanonicalOptions::Rule rule, const ShellUnits<Real>& units,
                               MicrocanonicalAverages<Real>& out) {
  using Rule = MicrocanonicalOptions::Rule;
  const std::size_t n = chain.size();
  const Real& rounding = units.rounding;
  const Real& nn = units.nn;
  const ShellSums<Real> sums = rule == Rule::integral
                                   ? integral_sums(chain, setup, run, tolerance)
                                   : torus_sums(chain, setup, run, tolerance);
  out.quadrature = rule == Rule::integral ? Method::reduced_integral : Method::torus_trapezoid;
  out.work_unit = WorkUnit::nodes;
  out.evaluations = sums.evaluations;
  out.converged = sums.converged;
  const Real z = sums.value[0], z_error = sums.error[0];
  if (!(z > 0)) throw invalid_input("microcanonical: the accessible region was not resolved");
  const Real z_rel = z_error / z;
  constexpr ErrorKind kind = ErrorKind::estimate;
  out.error_kind = kind;
  Real numerator = 0, numerator_error = 0;
  const Real kinetic_unit = setup.scale / (nn * z);
  const Real second_unit = setup.scale * setup.scale / (units.second_moment_norm * z);
  for (std::size_t i = 0; i < n; ++i) {
    const Real kn = sums.value[1 + i], ke = sums.error[1 + i];
    numerator += kn;
    numerator_error += ke;
    const Real kinetic = kinetic_unit * kn;
    const Real kinetic_error = abs(kinetic) * (z_rel + rounding) + kinetic_unit * ke;
    out.kinetic[i] = {kinetic, kinetic_error, kind};
    out.cos_angle[i] = {sums.value[1 + n + i] / z,
                        (sums.error[1 + n + i] + abs(sums.value[1 + n + i]) * z_rel) / z +
                            rounding,
                        kind};
    // Var K_i = <K_i^2>_E - <K_i>_E^2
    const Real second = second_unit * sums.value[1 + 2 * n + i];
    const Real second_error =
        abs(second) * (z_rel + rounding) + second_unit * sums.error[1 + 2 * n + i];
    out.kinetic_variance[i] = {second - kinetic * kinetic,
                               second_error + 2 * abs(kinetic) * kinetic_error +
                                   rounding * abs(second),
                               kind};
  }
  const Real kinetic_total = kinetic_unit * numerator;
  out.kinetic_total = {kinetic_total,
                       kinetic_total * (z_rel + rounding) + kinetic_unit * numerator_error,
                       kind};
  if (sums.converged) {
    // the budget was tolerance; report converged only if the propagated errors stay within it
    out.converged = z_rel <= 2 * tolerance;
  }
  const Real density_factor = exp(units.log_factor);
  out.density_of_states = {density_factor * z, density_factor * (z_error + rounding * z), kind};
}

/// The run of one entry point: validated (check_run), at the working precision, from the
/// excitation D.
template <class Real>
MicrocanonicalAverages<Real> microcanonical_run(const Chain<Real>& chain, const Real& energy,
                                                 const Real& excitation,
                                                 const MicrocanonicalOptions& options) {
  using Rule = MicrocanonicalOptions::Rule;
  using std::isfinite;
  using std::pow;
  const std::size_t n = chain.size();
  constexpr bool multiprecision = is_mpfr_v<Real>;
  const Rule rule = resolve_microcanonical_rule(n, options.rule);
  check_run(chain, energy, excitation, options);
  Real tolerance = Real(options.tolerance.value_or(default_microcanonical_tolerance(n)));
  if (options.digits != 0) tolerance = pow(Real(10), -options.digits);
  MicrocanonicalOptions run = options;
  if constexpr (multiprecision) run.threads = 1;  // MPFR runs on the calling thread

  const ShellSetup<Real> setup(chain, energy, excitation);
  MicrocanonicalAverages<Real> out;
  out.energy = energy;
  out.excitation = excitation;
  const Real u = unit_roundoff<Real>() / 2;
  const Real rounding = (Real(32) + Real(8 * static_cast<double>(n))) * u;
  const Real nn = Real(static_cast<double>(n));
  const Real second_moment_norm = nn * (nn + 2);  // <K_i^2 | phi, E> = (E-U)^2 (...) / (N (N+2))
  const Real p = setup.shell.p();
  const Real log_factor = setup.log_momentum_sphere + setup.log_hadamard + p * log(setup.scale);
  const ShellUnits<Real> units{rounding, nn, second_moment_norm, log_factor};
  out.kinetic.resize(n);
  out.cos_angle.resize(n);
  out.kinetic_variance.resize(n);
  if (rule == Rule::qmc) {
    qmc_shell_averages(chain, setup, options, run.threads, units, out);
  } else {
    quadrature_shell_averages(chain, setup, run, tolerance, rule, units, out);
  }
  out.kinetic_canonical = {out.kinetic_total.value / nn, out.kinetic_total.error / nn,
                           out.kinetic_total.kind};
  // Never a non-finite value reported as converged.
  const auto finite = [](const Estimate<Real>& e) {
    return isfinite(e.value) && isfinite(e.error);
  };
  bool all_finite = finite(out.kinetic_total) && finite(out.density_of_states);
  for (std::size_t i = 0; i < n; ++i) {
    all_finite = all_finite && finite(out.kinetic[i]) && finite(out.cos_angle[i]) &&
                 finite(out.kinetic_variance[i]);
  }
  if (!all_finite) out.converged = false;
  return out;
}

/// Validation shared by the two entry points (before any work).
template <class Real>
void check_microcanonical_options(const MicrocanonicalOptions& options) {
  if (options.tolerance && !(*options.tolerance > 0 && *options.tolerance < 1)) {
    throw invalid_input("microcanonical: tolerance must be in (0, 1)");
  }
  if (options.threads < 1) throw invalid_input("microcanonical: threads must be >= 1");
  if (options.max_level < 2 || options.max_level > 12) {
    throw invalid_input("microcanonical: max_level must be in 2..12");
  }
  if (options.digits != 0) check_digits<Real>(options.digits);
}

/// "E must exceed the minimum energy E_min = -sum_j g S_j l_j = <value>".
template <class Real>
std::string below_minimum_message(const Chain<Real>& chain, const char* what) {
  const DoubleWord<Real> depth = well_depth(chain);
  std::ostringstream text;
  text.precision(17);
  text << "microcanonical: no accessible states: " << what << " E_min = -sum_j g S_j l_j = "
       << static_cast<double>(-(depth.hi + depth.lo));
  return text.str();
}

}  // namespace detail::microcanonical

template <class Real>
Real minimum_energy(const Chain<Real>& chain) {
  const auto depth = detail::microcanonical::well_depth(chain);
  return -(depth.hi + depth.lo);
}

template <class Real>
Real excitation_energy(const Chain<Real>& chain, const Real& energy) {
  return detail::microcanonical::excitation_of(chain, energy);
}

template <class Real>
Real matched_beta(const Chain<Real>& chain, const Real& energy) {
  const Real excitation = detail::microcanonical::excitation_of(chain, energy);
  if (!(excitation > 0)) throw invalid_input("matched_beta: energy below the minimum");
  return detail::microcanonical::matched_beta_excitation(chain, excitation);
}

namespace detail::microcanonical {

/// The state of an entry point at the working precision: the chain, E and D = E - E_min, checked
/// (finite, D > 0).
template <class Real>
struct State {
  Chain<Real> chain;
  Real energy, excitation;
};

template <class Real>
State<Real> state_from_energy(const Chain<Real>& chain, const Real& energy) {
  using std::isfinite;
  State<Real> s{at_working_precision(chain), at_working_precision(energy), Real(0)};
  if (!isfinite(s.energy)) throw invalid_input("microcanonical: the energy must be finite");
  s.excitation = excitation_of(s.chain, s.energy);
  if (!(s.excitation > 0)) {
    throw invalid_input(below_minimum_message(s.chain, "the energy must exceed the minimum energy"));
  }
  return s;
}

template <class Real>
State<Real> state_from_excitation(const Chain<Real>& chain, const Real& excitation) {
  using std::isfinite;
  State<Real> s{at_working_precision(chain), Real(0), at_working_precision(excitation)};
  if (!isfinite(s.excitation)) throw invalid_input("microcanonical: the excitation must be finite");
  if (!(s.excitation > 0)) {
    throw invalid_input("microcanonical: no accessible states: the excitation D = E - E_min "
                        "must be > 0");
  }
  const DoubleWord<Real> depth = well_depth(s.chain);
  s.energy = s.excitation - depth.hi - depth.lo;
  return s;
}

/// The entry points' common start: the options checked, the working precision held (MPFR,
/// options.digits), the state (energy or excitation: `from_excitation`) formed at it; then
/// `then(state)` runs under that precision.
template <class Real, class Then>
decltype(auto) at_state(const Chain<Real>& chain, const Real& x, bool from_excitation,
                        const MicrocanonicalOptions& options, Then&& then) {
  check_microcanonical_options<Real>(options);
  std::optional<precision_guard<Real>> guard;
  if (options.digits != 0) guard.emplace(options.digits + guard_digits);
  const State<Real> s =
      from_excitation ? state_from_excitation(chain, x) : state_from_energy(chain, x);
  return then(s);
}

}  // namespace detail::microcanonical

namespace detail::microcanonical {

/// The result check (domain.hpp): every value and error finite, and in double no non-zero value
/// below the normal range (it would print with lost digits).
template <class Real>
MicrocanonicalAverages<Real> checked(MicrocanonicalAverages<Real> a) {
  if constexpr (std::is_same_v<Real, double>) {
    // Omega(E)'s rounding at extreme scales reached 40 ulps (masses 7e12, lengths 1e50, g 2e14,
    // against 30 digits) beyond its estimate: a floor of 64 ulps relative.
    a.density_of_states.error =
        std::max(a.density_of_states.error,
                 64 * std::numeric_limits<double>::epsilon() * std::fabs(a.density_of_states.value));
  }
  // At a critical energy of the potential (a separatrix: the single pendulum's upright state,
  // E = m g l) the motion takes infinitely long near the saddle: Omega(E) diverges
  // logarithmically and the averages are its ratios. A clear refusal, not a non-finite result.
  {
    using std::isinf;
    if (isinf(a.density_of_states.value))
      throw invalid_input("microcanonical: the density of states diverges at this energy, a "
                          "critical energy of the potential (a separatrix); take an energy "
                          "beside it");
  }
  const auto check = [](const Estimate<Real>& e, const char* what) {
    domain::check_finite_estimate(e, "microcanonical", what);
    if constexpr (std::is_same_v<Real, double>)
      if (e.value != 0 && std::fabs(e.value) < std::numeric_limits<double>::min())
        throw invalid_input(std::string("microcanonical: ") + what +
                            " is below double's normal range (2.2e-308) for this input, where "
                            "it has lost digits; request 17 or more digits (MPFR)");
  };
  for (const auto& e : a.kinetic) check(e, "<K_i>_E");
  for (const auto& e : a.cos_angle) check(e, "<cos phi_i>_E");
  for (const auto& e : a.kinetic_variance) check(e, "Var K_i");
  if constexpr (std::is_same_v<Real, double>) {
    // Var K_i ~ D^2 and Omega ~ D^(N/2-1) are positive at every accessible energy: an exact
    // zero beside D > 0 is an underflow (D = 1e-300 gives Var K_i ~ 1e-600), not a value.
    const auto zero = [](const Estimate<Real>& e) { return e.value == 0 && e.error == 0; };
    bool underflow = zero(a.density_of_states);
    for (const auto& e : a.kinetic_variance) underflow = underflow || zero(e);
    if (underflow && a.excitation > 0)
      throw invalid_input("microcanonical: Var K_i or the density of states underflows double "
                          "at the excitation " + short_decimal(a.excitation));
  }
  check(a.kinetic_canonical, "<K_i^(c)>_E");
  check(a.kinetic_total, "<K>_E");
  // Omega(E) ~ D^(N/2-1) near the well bottom: only its finiteness is the engine's promise.
  domain::check_finite_estimate(a.density_of_states, "microcanonical", "the density of states");
  return a;
}

}  // namespace detail::microcanonical

template <class Real>
MicrocanonicalAverages<Real> microcanonical_average(const Chain<Real>& chain, const Real& energy,
                                                     const MicrocanonicalOptions& options) {
  using namespace detail::microcanonical;
  return at_state(chain, energy, false, options, [&](const State<Real>& s) {
    return checked(microcanonical_run(s.chain, s.energy, s.excitation, options));
  });
}

template <class Real>
MicrocanonicalAverages<Real> microcanonical_average_excitation(
    const Chain<Real>& chain, const Real& excitation, const MicrocanonicalOptions& options) {
  using namespace detail::microcanonical;
  return at_state(chain, excitation, true, options, [&](const State<Real>& s) {
    return checked(microcanonical_run(s.chain, s.energy, s.excitation, options));
  });
}

template <class Real>
void check_microcanonical(const Chain<Real>& chain, const Real& energy,
                          const MicrocanonicalOptions& options) {
  using namespace detail::microcanonical;
  at_state(chain, energy, false, options, [&](const State<Real>& s) {
    check_run(s.chain, s.energy, s.excitation, options);
  });
}

template <class Real>
void check_microcanonical_excitation(const Chain<Real>& chain, const Real& excitation,
                                     const MicrocanonicalOptions& options) {
  using namespace detail::microcanonical;
  at_state(chain, excitation, true, options, [&](const State<Real>& s) {
    check_run(s.chain, s.energy, s.excitation, options);
  });
}

#define PENDAVG_MICROCANONICAL_INSTANTIATE(Real)                                                \
  template PENDAVG_EXPORT MicrocanonicalAverages<Real> microcanonical_average<Real>(            \
      const Chain<Real>&, const Real&, const MicrocanonicalOptions&);                           \
  template PENDAVG_EXPORT MicrocanonicalAverages<Real> microcanonical_average_excitation<Real>( \
      const Chain<Real>&, const Real&, const MicrocanonicalOptions&);                           \
  template PENDAVG_EXPORT void check_microcanonical<Real>(const Chain<Real>&, const Real&,      \
                                                          const MicrocanonicalOptions&);        \
  template PENDAVG_EXPORT void check_microcanonical_excitation<Real>(                           \
      const Chain<Real>&, const Real&, const MicrocanonicalOptions&);                           \
  template PENDAVG_EXPORT Real minimum_energy<Real>(const Chain<Real>&);                        \
  template PENDAVG_EXPORT Real excitation_energy<Real>(const Chain<Real>&, const Real&);        \
  template PENDAVG_EXPORT Real matched_beta<Real>(const Chain<Real>&, const Real&);
PENDAVG_MICROCANONICAL_INSTANTIATE(double)
PENDAVG_MICROCANONICAL_INSTANTIATE(long double)
PENDAVG_MICROCANONICAL_INSTANTIATE(mpfr_real)
#undef PENDAVG_MICROCANONICAL_INSTANTIATE

}  // namespace pendavg
