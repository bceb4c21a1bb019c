// Microcanonical averages (pendavg/microcanonical.hpp): the three rules and their explicit
// instantiations (double, long double).
#include "engine/microcanonical.hpp"

#include <cmath>
#include <string>

namespace pendavg {

namespace detail::microcanonical {

/// The integrated quantities of a rule, before they become averages: Z = ∫ T~ d theta and the
/// numerators (integrals over the (N-1)-torus of the quantities of NestedShellIntegral), each
/// with an absolute error estimate.
template <class Real>
struct ShellSums {
  std::vector<Real> value, error;  // q = 1 + 2N entries each
  std::size_t evaluations = 0;
  bool converged = true;
};

template <class Real>
typename NestedShellIntegral<Real>::Shared nested_shared(const Chain<Real>& chain,
                                                         const ShellSetup<Real>& setup,
                                                         const TanhSinhTable<Real>& table,
                                                         const MicrocanonicalOptions& options) {
  const std::size_t n = setup.n;
  typename NestedShellIntegral<Real>::Shared shared;
  shared.chain = &chain;
  shared.setup = &setup;
  shared.table = &table;
  // each level gets a quarter of the budget: the inner errors are carried outwards
  shared.tolerance = Real(options.tolerance) / 4;
  shared.max_level = options.max_level;
  shared.tail_gamma.assign(n + 1, Real(0));
  for (std::size_t j = n; j-- > 0;) shared.tail_gamma[j] = shared.tail_gamma[j + 1] + setup.gamma[j];
  shared.targets.resize(n);
  shared.light.assign(n, false);
  const Real abs_energy = abs(setup.energy);
  for (std::size_t j = 1; j < n; ++j) {
    // | |E| + sum_{k > j} eps_k gamma_k | over every sign pattern
    std::vector<Real> values{abs_energy};
    for (std::size_t k = j + 1; k < n; ++k) {
      std::vector<Real> next;
      for (const Real& v : values) {
        next.push_back(v + setup.gamma[k]);
        next.push_back(v - setup.gamma[k]);
      }
      values.swap(next);
    }
    for (Real& v : values) v = abs(v);
    std::sort(values.begin(), values.end());
    values.erase(std::unique(values.begin(), values.end()), values.end());
    shared.targets[j] = values;
    shared.light[j] = chain.mass(j - 1) / chain.tail_mass(j - 1) < Real(0.09);
  }
  return shared;
}

template <class Real>
ShellSums<Real> integral_sums(const Chain<Real>& chain, const ShellSetup<Real>& setup,
                              const MicrocanonicalOptions& options) {
  const TanhSinhTable<Real>& table = TanhSinhTable<Real>::shared();
  auto shared = nested_shared(chain, setup, table, options);
  const std::size_t q = 1 + 2 * setup.n;
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
        const Real size = (c >= 1 && c <= setup.n) ? abs(rough[c]) : abs(rough[0]);
        shared.floor[j][c] = Real(options.tolerance) / 16 * size / outer_measure;
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
                           const MicrocanonicalOptions& options) {
  const std::size_t n = setup.n, dims = n - 1, q = 1 + 2 * n;
  const auto shared = nested_shared(chain, setup, TanhSinhTable<Real>::shared(), options);
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
        std::vector<detail::torus::CompensatedSum<Real>> sums(q);
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
        for (std::size_t c = 0; c < q; ++c) partial[static_cast<std::size_t>(k0)][c] = sums[c].value();
      }
    }
    (void)team;
    std::vector<Real> value(q, Real(0));
    const Real cell = std::pow(two_pi / Real(static_cast<double>(points)), Real(static_cast<double>(dims)));
    for (std::size_t c = 0; c < q; ++c) {
      detail::torus::CompensatedSum<Real> s;
      for (std::size_t k0 = 0; k0 < points; ++k0) s.add(partial[k0][c]);
      value[c] = cell * s.value();
    }
    out.evaluations += static_cast<std::size_t>(std::pow(double(points), double(dims)));
    out.value = value;
    if (!previous.empty()) {
      bool done = true;
      for (std::size_t c = 0; c < q; ++c) {
        out.error[c] = abs(value[c] - previous[c]);
        const Real scale = (c >= 1 && c <= n) ? abs(value[c]) : abs(value[0]);
        if (!(out.error[c] <= Real(options.tolerance) * scale)) done = false;
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

/// Randomized lattice QMC: per shift, sums of w, w^2, w tr X_i F_{p+1}/F_p, w cos G_p/F_p.
template <class Real>
struct QmcShellShift {
  detail::torus::CompensatedSum<Real> weight, weight_squared;
  std::vector<detail::torus::CompensatedSum<Real>> kinetic, cosine;
  explicit QmcShellShift(std::size_t n = 0) : kinetic(n), cosine(n) {}
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
    const ShellMoments<Real> m = setup.shell(setup.energy, rho, setup.scale);
    if (m.weight == 0 && m.kinetic == 0) {
      sums.weight.add(Real(0));
      continue;
    }
    for (std::size_t i = 0; i + 1 < n; ++i) delta[i] = phi[i + 1] - phi[i];
    const NodeTraces<Real>& t = node_traces_relative(chain, delta.data(), ws);
    const Real x = beta_star * rho;
    const Real log_bessel = x > 0 ? Real(log(scaled_bessel_i01(x).i0e)) : Real(0);
    const Real base = exp(log_ratio_sum + t.log_sqrt_det_A - setup.log_hadamard +
                          beta_star * (setup.gamma_sum - rho) - log_bessel);
    const Real w = base * m.weight;
    sums.weight.add(w);
    sums.weight_squared.add(w * w);
    const Real bk = base * m.kinetic, bc = rho > 0 ? Real(base * m.cosine / rho) : Real(0);
    for (std::size_t i = 0; i < n; ++i) {
      sums.kinetic[i].add(bk * t.trace_X[i]);
      sums.cosine[i].add(bc * (cphi[i] * zx + sphi[i] * zy));
    }
  }
  return sums;
}

}  // namespace detail::microcanonical

template <class Real>
Real matched_beta(const Chain<Real>& chain, const Real& energy) {
  using std::log;
  const std::size_t n = chain.size();
  Real gamma_sum = 0;
  for (std::size_t j = 0; j < n; ++j) gamma_sum += chain.potential_coefficient(j);
  if (!(energy + gamma_sum > 0)) throw invalid_input("matched_beta: energy below the minimum");
  const Real half_n = Real(static_cast<double>(n)) / 2;
  const auto excess = [&](const Real& beta) {  // decreasing in beta
    Real u = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const Real g = chain.potential_coefficient(j);
      const ScaledBesselI01<Real> b = scaled_bessel_i01(Real(beta * g));
      u -= g * (b.i1e / b.i0e);
    }
    return half_n / beta + u - energy;
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
    if (hi - lo <= 1e-13 * hi) break;
  }
  return sqrt(lo * hi);
}

template <class Real>
MicrocanonicalAverages<Real> microcanonical_average(const Chain<Real>& chain, const Real& energy,
                                                     const MicrocanonicalOptions& options) {
  using namespace detail::microcanonical;
  using Rule = MicrocanonicalOptions::Rule;
  using std::isfinite;
  const std::size_t n = chain.size();
  if (!isfinite(energy)) throw invalid_input("microcanonical: the energy must be finite");
  if (!(options.tolerance > 0) || !std::isfinite(options.tolerance)) {
    throw invalid_input("microcanonical: tolerance must be positive and finite");
  }
  if (options.threads < 1) throw invalid_input("microcanonical: threads must be >= 1");
  if (options.max_level < 2 || options.max_level > 12) {
    throw invalid_input("microcanonical: max_level must be in 2..12");
  }
  const ShellSetup<Real> setup(chain, energy);
  if (!(setup.scale > 0)) {
    throw invalid_input("microcanonical: no accessible states: E must exceed the minimum energy "
                        "-sum_j g S_j l_j");
  }
  Rule rule = options.rule;
  if (rule == Rule::automatic) rule = n <= 4 ? Rule::integral : Rule::qmc;
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

  MicrocanonicalAverages<Real> out;
  out.energy = energy;
  const Real u = std::numeric_limits<Real>::epsilon() / 2;
  const Real rounding = (Real(32) + Real(8 * static_cast<double>(n))) * u;
  const Real nn = Real(static_cast<double>(n));
  const Real p = setup.shell.p();
  std::vector<Real> value, error;  // Z~, kinetic numerators, cosine numerators
  if (rule == Rule::qmc) {
    using namespace detail::qmc;
    const std::size_t points = options.points;
    if (points < 1024 || points > (std::size_t(1) << lattice_table_max_log2) ||
        (points & (points - 1)) != 0) {
      throw invalid_input("microcanonical qmc: points must be a power of two in [2^10, 2^16]");
    }
    if (options.shifts < 4) throw invalid_input("microcanonical qmc: at least 4 random shifts");
    if (!(options.sigmas > 0) || !std::isfinite(options.sigmas)) {
      throw invalid_input("microcanonical qmc: sigmas must be positive");
    }
    if (!(options.proposal_beta >= 0) || !std::isfinite(options.proposal_beta)) {
      throw invalid_input("microcanonical qmc: proposal_beta must be >= 0 and finite");
    }
    if (n > lattice_max_dimension) {
      throw invalid_input("microcanonical qmc: the built-in lattices cover N <= 32");
    }
    unsigned log2_points = 0;
    while ((std::size_t(1) << log2_points) < points) ++log2_points;
    const auto& row = lattice_table[log2_points - lattice_table_min_log2];
    const std::vector<std::uint32_t> generator(row, row + n);
    const Real beta_star =
        options.proposal_beta > 0 ? Real(options.proposal_beta) : matched_beta(chain, energy);
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
    const int team = std::max(options.threads, 1);
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(dynamic, 1) if (team > 1)
#endif
    for (std::ptrdiff_t r = 0; r < static_cast<std::ptrdiff_t>(shifts); ++r) {
      const std::size_t rr = static_cast<std::size_t>(r);
      sums[rr] = qmc_shift_sums(chain, setup, beta_star, maps, shift[rr], points, generator);
    }
    (void)team;
    // Per-shift totals; every reported quantity is a ratio of them: jackknife over shifts.
    const std::size_t q = 1 + 2 * n;
    std::vector<std::vector<Real>> per(shifts, std::vector<Real>(q));
    Real total_w = 0, total_w2 = 0;
    for (std::size_t r = 0; r < shifts; ++r) {
      per[r][0] = sums[r].weight.value();
      for (std::size_t i = 0; i < n; ++i) {
        per[r][1 + i] = sums[r].kinetic[i].value();
        per[r][1 + n + i] = sums[r].cosine[i].value();
      }
      total_w += per[r][0];
      total_w2 += sums[r].weight_squared.value();
    }
    if (!(total_w > 0)) throw invalid_input("microcanonical qmc: no point reached the shell");
    // quantities: <K_i> (n), <cos_i> (n), <K> (1), Z~ (1)
    const std::size_t count = 2 * n + 2;
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
      }
      res[2 * n] = total;
      res[2 * n + 1] = t[0] / (used * z_norm);
      return res;
    };
    const std::vector<Real> est = quantities(shifts);
    std::vector<std::vector<Real>> leave(shifts);
    for (std::size_t r = 0; r < shifts; ++r) leave[r] = quantities(r);
    const std::vector<Real> se = detail::qmc::jackknife_standard_errors(leave, count);
    const Real sig = Real(options.sigmas);
    out.quadrature = Method::qmc;
    out.evaluations = points * shifts;
    out.proposal_beta = beta_star;
    out.effective_sample_fraction =
        total_w * total_w / (total_w2 * Real(static_cast<double>(points * shifts)));
    constexpr ErrorKind kind = ErrorKind::statistical;
    out.error_kind = kind;
    out.kinetic.resize(n);
    out.cos_angle.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      out.kinetic[i] = {est[i], sig * se[i] + rounding * abs(est[i]), kind};
      out.cos_angle[i] = {est[n + i], sig * se[n + i] + rounding, kind};
    }
    out.kinetic_total = {est[2 * n], sig * se[2 * n] + rounding * abs(est[2 * n]), kind};
    const Real z = est[2 * n + 1], z_error = sig * se[2 * n + 1] + rounding * z;
    const Real log_factor = setup.log_momentum_sphere + setup.log_hadamard + p * log(setup.scale);
    out.density_of_states = {exp(log_factor) * z, exp(log_factor) * z_error, kind};
  } else {
    const ShellSums<Real> sums = rule == Rule::integral ? integral_sums(chain, setup, options)
                                                        : torus_sums(chain, setup, options);
    out.quadrature = rule == Rule::integral ? Method::reduced_integral : Method::torus_trapezoid;
    out.evaluations = sums.evaluations;
    out.converged = sums.converged;
    const Real z = sums.value[0], z_error = sums.error[0];
    if (!(z > 0)) throw invalid_input("microcanonical: the accessible region was not resolved");
    const Real z_rel = z_error / z;
    constexpr ErrorKind kind = ErrorKind::estimate;
    out.error_kind = kind;
    out.kinetic.resize(n);
    out.cos_angle.resize(n);
    Real numerator = 0, numerator_error = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Real kn = sums.value[1 + i], ke = sums.error[1 + i];
      numerator += kn;
      numerator_error += ke;
      const Real kinetic = setup.scale * kn / (nn * z);
      out.kinetic[i] = {kinetic, abs(kinetic) * (z_rel + rounding) + setup.scale * ke / (nn * z),
                        kind};
      out.cos_angle[i] = {sums.value[1 + n + i] / z,
                          (sums.error[1 + n + i] + abs(sums.value[1 + n + i]) * z_rel) / z +
                              rounding,
                          kind};
    }
    const Real kinetic_total = setup.scale * numerator / (nn * z);
    out.kinetic_total = {kinetic_total,
                         kinetic_total * (z_rel + rounding) + setup.scale * numerator_error / (nn * z),
                         kind};
    if (sums.converged) {
      // the budget was tolerance; report converged only if the propagated errors stay within it
      out.converged = z_rel <= Real(2 * options.tolerance);
    }
    const Real log_factor = setup.log_momentum_sphere + setup.log_hadamard + p * log(setup.scale);
    out.density_of_states = {exp(log_factor) * z, exp(log_factor) * (z_error + rounding * z), kind};
  }
  out.kinetic_canonical = {out.kinetic_total.value / nn, out.kinetic_total.error / nn,
                           out.kinetic_total.kind};
  return out;
}

#define PENDAVG_MICROCANONICAL_INSTANTIATE(Real)                                              \
  template MicrocanonicalAverages<Real> microcanonical_average<Real>(                         \
      const Chain<Real>&, const Real&, const MicrocanonicalOptions&);                          \
  template Real matched_beta<Real>(const Chain<Real>&, const Real&);
PENDAVG_MICROCANONICAL_INSTANTIATE(double)
PENDAVG_MICROCANONICAL_INSTANTIATE(long double)
#undef PENDAVG_MICROCANONICAL_INSTANTIATE

}  // namespace pendavg
