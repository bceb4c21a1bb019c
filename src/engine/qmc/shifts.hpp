// SPDX-License-Identifier: GPL-3.0-or-later
// engine/qmc/shifts.hpp -- the random shifts of qmc_average: drawing them, running them (in
// parallel, or shared among processes through a ShiftPartition), bringing their sums to one
// scale, and the delete-one-shift jackknife behind the error bars.
//
// Equations (src/engine/qmc/README.md, 'Error bar'): with R shifts and theta_(r) a quantity
// estimated from the totals over every shift but r,
//     theta = (sum_r N_r) / (sum_r D_r),   SE^2 = (R - 1)/R sum_r (theta_(r) - mean_r theta_(r))^2.
#pragma once

#include "engine/numerics/parallel.hpp"
#include "engine/qmc/lattice_table.hpp"
#include "engine/qmc/options.hpp"
#include "engine/qmc/pivot_sampler.hpp"
#include "engine/qmc/shifted_lattice.hpp"
#include "engine/torus/reduced_weight.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace pendavg::detail::qmc {

/// Delete-one jackknife standard errors: leave_out[r][q] is quantity q estimated without shift r
/// (R shifts); SE_q = sqrt((R - 1)/R sum_r (leave_out[r][q] - mean_q)^2).
template <class Real>
std::vector<Real> jackknife_standard_errors(const std::vector<std::vector<Real>>& leave_out,
                                            std::size_t count) {
  using std::sqrt;
  const std::size_t shifts = leave_out.size();
  const Real R = Real(static_cast<double>(shifts));
  std::vector<Real> standard_error(count);
  for (std::size_t q = 0; q < count; ++q) {
    Real mean = 0;
    for (std::size_t r = 0; r < shifts; ++r) mean += leave_out[r][q];
    mean /= R;
    Real ss = 0;
    for (std::size_t r = 0; r < shifts; ++r) {
      const Real d = leave_out[r][q] - mean;
      ss += d * d;
    }
    standard_error[q] = sqrt((R - 1) / R * ss);
  }
  return standard_error;
}

/// Random shifts of a lattice rule: `shifts` vectors of `n` coordinates in [0, 1), 53 random
/// bits each, drawn in a fixed order from std::mt19937_64(seed) (so results depend on the seed
/// only, never on the thread count).
template <class Real>
std::vector<std::vector<Real>> random_shifts(std::size_t shifts, std::size_t n, std::uint64_t seed) {
  std::vector<std::vector<Real>> shift(shifts, std::vector<Real>(n));
  std::mt19937_64 rng(seed);
  for (auto& s : shift) {
    for (auto& v : s) v = Real(static_cast<double>(rng() >> 11) * 0x1.0p-53);
  }
  return shift;
}

/// The shifts [first, last) that this part of a ShiftPartition computes (all without one).
struct ShiftRange {
  std::size_t first = 0, last = 0;
};
inline ShiftRange shift_range(const ShiftPartition* partition, std::size_t shifts) {
  if (!partition) return {0, shifts};
  const auto part = static_cast<std::size_t>(partition->part());
  const auto parts = static_cast<std::size_t>(partition->parts());
  return {shifts * part / parts, shifts * (part + 1) / parts};
}

/// Hands every part the sums of all shifts: each part packs its own shifts' sums (both words of
/// every compensated sum, the scale and whether it is set), all_gather concatenates them in part order, which is
/// shift order, and they are unpacked exactly.
template <class Real>
void gather_shift_sums(const ShiftPartition& partition, std::vector<ShiftSums<Real>>& sums) {
  if constexpr (!std::is_same_v<Real, double>) {
    throw invalid_input("qmc_average: a shift partition is for double runs");
  } else {
    const std::size_t shifts = sums.size();
    const ShiftRange mine = shift_range(&partition, shifts);
    const std::size_t n = sums.empty() ? 0 : sums[0].trace.size();
    const std::size_t width = 6 + 6 * n;  // doubles per shift
    std::vector<double> local;
    local.reserve((mine.last - mine.first) * width);
    for (std::size_t r = mine.first; r < mine.last; ++r) {
      const ShiftSums<double>& s = sums[r];
      const auto put = [&](const detail::CompensatedSum<double>& c) {
        local.push_back(c.sum);
        local.push_back(c.compensation);
      };
      put(s.weight);
      put(s.weight_squared);
      for (std::size_t i = 0; i < n; ++i) {
        put(s.trace[i]);
        put(s.second_moment[i]);
        put(s.cosine[i]);
      }
      local.push_back(s.log_scale);
      local.push_back(s.scaled ? 1.0 : 0.0);
    }
    const std::vector<double> all = partition.all_gather(local);
    if (all.size() != shifts * width)
      throw std::logic_error("qmc_average: the shift partition gathered " +
                             std::to_string(all.size()) + " values, expected " +
                             std::to_string(shifts * width));
    std::size_t k = 0;
    for (ShiftSums<double>& s : sums) {
      const auto get = [&](detail::CompensatedSum<double>& c) {
        c.sum = all[k++];
        c.compensation = all[k++];
      };
      get(s.weight);
      get(s.weight_squared);
      for (std::size_t i = 0; i < n; ++i) {
        get(s.trace[i]);
        get(s.second_moment[i]);
        get(s.cosine[i]);
      }
      s.log_scale = all[k++];
      s.scaled = all[k++] != 0;
    }
  }
}

/// The generating vector of a qmc run: options.generating_vector, checked, or the built-in
/// lattice row for n particles and `points` points. Throws invalid_input.
inline std::vector<std::uint32_t> qmc_generating_vector(const QmcOptions& options, std::size_t n) {
  const std::size_t points = options.points;
  std::vector<std::uint32_t> generator = options.generating_vector;
  if (generator.empty()) {
    unsigned log2_points = 0;
    while ((std::size_t(1) << log2_points) < points) ++log2_points;
    if (n > lattice_max_dimension || log2_points > lattice_rows_max_log2) {
      throw invalid_input(
          "qmc_average: the built-in lattices cover N <= 256 and 2^10..2^20 points; pass "
          "options.generating_vector (e.g. from cbc_generating_vector) for N = " +
          std::to_string(n) + " with " + std::to_string(points) + " points");
    }
    const auto& row = lattice_table[log2_points - lattice_table_min_log2];
    generator.assign(row, row + n);
  } else if (generator.size() != n) {
    throw invalid_input("qmc_average: the generating vector needs one entry per particle");
  } else {
    for (std::uint32_t zj : generator) {
      if (zj % 2 == 0) throw invalid_input("qmc_average: generating vector entries must be odd");
    }
  }
  return generator;
}

/// The sums of every random shift this process runs (options.partition: its share), in
/// parallel over the shifts; finished[r] marks the shifts that ran to the end (a stop request
/// through options.control leaves the others unfinished).
template <class Real>
std::vector<ShiftSums<Real>> run_shifts(const Chain<Real>& chain,
                                        const detail::torus::WeightConstants<Real>& constants,
                                        const PivotSampler<Real>& sampler,
                                        const std::vector<std::uint32_t>& generator,
                                        const QmcOptions& options, std::vector<char>& finished) {
  const std::size_t n = chain.size();
  const std::size_t points = options.points;
  const std::size_t shifts = options.shifts;
  const std::vector<std::vector<Real>> shift = random_shifts<Real>(shifts, n, options.seed);
  std::vector<ShiftSums<Real>> sums(shifts, ShiftSums<Real>(n));
  ParallelErrors errors;  // an exception may not leave the parallel region
  const ShiftRange mine = shift_range(options.partition, shifts);
  const RunControl* control = options.partition ? nullptr : options.control;
  finished.assign(shifts, 0);
  // Progress over every point of every shift, and a stop request, polled every
  // lattice_poll_points points inside each shift (a big point stops within a fraction of a
  // second; the unfinished shifts are dropped).
  std::size_t points_done = 0;
  const double all_points = static_cast<double>(points) * static_cast<double>(shifts);
  const std::function<bool(std::size_t)> poll = [&](std::size_t count) {
    if (control->stop_requested()) return false;
#if defined(_OPENMP)
#pragma omp critical(pendavg_qmc_progress)
#endif
    {
      points_done += count;
      control->report(static_cast<double>(points_done) / all_points);
    }
    return true;
  };
  int team = 1;
  if constexpr (std::is_floating_point_v<Real>) team = std::max(options.threads, 1);
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(dynamic, 1) if (team > 1)
#endif
  for (std::ptrdiff_t r = static_cast<std::ptrdiff_t>(mine.first);
       r < static_cast<std::ptrdiff_t>(mine.last); ++r) {
    errors.capture([&] {
      const auto rr = static_cast<std::size_t>(r);
      if (control != nullptr && control->stop_requested()) return;
      bool complete = true;
      sums[rr] = shifted_lattice_sums(chain, constants, sampler, shift[rr], points, generator,
                                      control != nullptr ? &poll : nullptr, &complete);
      if (!complete) return;
      finished[rr] = 1;
      if (control != nullptr) poll(points % lattice_poll_points ? points % lattice_poll_points
                                                                : lattice_poll_points);
    });
  }
  errors.rethrow();
  (void)team;
  if (options.partition) gather_shift_sums(*options.partition, sums);
  return sums;
}

/// Every shift's sums at one common scale (the weights are exp(log W - log_scale); a shift
/// without a finite weight has all sums zero), and the totals of W and W^2.
template <class Real>
struct ScaledShiftSums {
  std::vector<Real> weight;
  std::vector<std::vector<Real>> trace, second_moment, cosine;
  Real total_weight{0}, total_weight_squared{0};
};

template <class Real>
ScaledShiftSums<Real> common_scale(const std::vector<ShiftSums<Real>>& sums, std::size_t n) {
  using std::exp;
  const std::size_t shifts = sums.size();
  ScaledShiftSums<Real> s;
  s.weight.resize(shifts);
  s.trace.assign(shifts, std::vector<Real>(n));
  s.second_moment.assign(shifts, std::vector<Real>(n));
  s.cosine.assign(shifts, std::vector<Real>(n));
  bool any_scaled = false;
  Real log_scale = 0;
  for (std::size_t r = 0; r < shifts; ++r) {
    if (!sums[r].scaled) continue;
    log_scale = any_scaled ? std::max(log_scale, sums[r].log_scale) : sums[r].log_scale;
    any_scaled = true;
  }
  if (!any_scaled) {
    throw invalid_input("qmc_average: every importance weight vanished (use torus_average)");
  }
  Real total_w = 0, total_w2 = 0;
  for (std::size_t r = 0; r < shifts; ++r) {
    const Real f = sums[r].scaled ? Real(exp(sums[r].log_scale - log_scale)) : Real(0);
    s.weight[r] = f * sums[r].weight.value();
    total_w += s.weight[r];
    total_w2 += f * f * sums[r].weight_squared.value();
    for (std::size_t i = 0; i < n; ++i) {
      s.trace[r][i] = f * sums[r].trace[i].value();
      s.second_moment[r][i] = f * sums[r].second_moment[i].value();
      s.cosine[r][i] = f * sums[r].cosine[i].value();
    }
  }
  s.total_weight = total_w;
  s.total_weight_squared = total_w2;
  return s;
}

/// beta<K_i>, beta^2 Var K_i, <cos phi_i> (3n values) from the totals over the shifts except
/// `skip` (skip >= shifts: all of them), the ratio of the totals.
template <class Real>
std::vector<Real> shift_ratio_quantities(const ScaledShiftSums<Real>& s, std::size_t n,
                                         std::size_t skip) {
  const std::size_t shifts = s.weight.size();
  Real w = 0;
  std::vector<Real> tr(n, Real(0)), m2(n, Real(0)), c(n, Real(0)), out(3 * n);
  for (std::size_t r = 0; r < shifts; ++r) {
    if (r == skip) continue;
    w += s.weight[r];
    for (std::size_t i = 0; i < n; ++i) {
      tr[i] += s.trace[r][i];
      m2[i] += s.second_moment[r][i];
      c[i] += s.cosine[r][i];
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Real k = tr[i] / (2 * w);
    out[i] = k;
    out[n + i] = m2[i] / (4 * w) - k * k;
    out[2 * n + i] = c[i] / w;
  }
  return out;
}

}  // namespace pendavg::detail::qmc
