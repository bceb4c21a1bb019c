// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/tanh_sinh.hpp -- the nodes of the tanh-sinh (double-exponential) rule on [-1, 1]:
//     x = tanh((pi/2) sinh t),  t = k h,  h = 2^-level,  dx/dt = (pi/2) cosh t / cosh^2((pi/2) sinh t),
// stored as the distance c = 1 - |x| to the nearer end (no cancellation at the ends, where the
// integrands of the microcanonical nested integral have their square-root singularities) and
// the weight dx/dt. Levels nest: level L > 0 holds only the odd k. One table per number type
// (per MPFR precision), shared by every call and thread.
#pragma once

#include "engine/numerics/precision.hpp"

#include <cmath>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

namespace pendavg::detail {

/// Nodes of the tanh-sinh rule on [-1, 1], x = tanh((pi/2) sinh t), t = k h, h = 2^-level, as
/// the distance c = 1 - |x| to the nearer end (no cancellation) and the weight dx/dt.
template <class Real>
struct TanhSinhTable {
  struct Node {
    Real complement, weight;
    int side;  ///< -1: near the left end, +1: near the right end, 0: the midpoint
  };
  std::vector<std::vector<Node>> levels;  ///< level 0: k = all; level L > 0: k odd

  /// The table up to level 12, built once per number type (thread-safe static); for MPFR once
  /// per working precision (the nodes carry that precision), the last max_cached_precisions
  /// precisions kept (a caller holds its table while it computes).
  static std::shared_ptr<const TanhSinhTable> shared() {
    if constexpr (is_mpfr_v<Real>) {
      struct Slot {
        std::shared_ptr<const TanhSinhTable> table;
        unsigned long long used = 0;
      };
      static std::mutex mutex;
      static std::map<long, Slot> tables;
      static unsigned long long clock = 0;
      const long bits = static_cast<long>(mpfr_real::thread_default_precision());
      const std::lock_guard lock(mutex);
      Slot& slot = tables[bits];
      if (!slot.table) slot.table = std::make_shared<const TanhSinhTable>(12);
      slot.used = ++clock;
      std::shared_ptr<const TanhSinhTable> table = slot.table;
      if (tables.size() > max_cached_precisions) {
        auto oldest = tables.begin();
        for (auto it = tables.begin(); it != tables.end(); ++it)
          if (it->second.used < oldest->second.used) oldest = it;
        tables.erase(oldest);  // never this call's: it was used last
      }
      return table;
    } else {
      static const std::shared_ptr<const TanhSinhTable> table =
          std::make_shared<const TanhSinhTable>(12);
      return table;
    }
  }
  static constexpr std::size_t max_cached_precisions = 8;

  explicit TanhSinhTable(int max_level) {
    using std::asinh;
    using std::exp;
    using std::log;
    using std::cosh;
    using std::ldexp;
    using std::sinh;
    const Real u = unit_roundoff<Real>();
    const Real half_pi = pi<Real>() / 2;
    // beyond t_max the weights are below ~u^1.3: sinh t_max = 1.3 log(1/u) / pi
    const Real t_max = asinh(Real(1.3) * -log(u) / pi<Real>());
    levels.resize(static_cast<std::size_t>(max_level) + 1);
    for (int level = 0; level <= max_level; ++level) {
      const Real h = ldexp(Real(1), -level);
      const long count = static_cast<long>(t_max / h);
      for (long k = 0; k <= count; ++k) {
        if (level > 0 && k % 2 == 0) continue;
        const Real t = Real(static_cast<double>(k)) * h;
        const Real s = half_pi * sinh(t);
        const Real ch = cosh(s);
        const Real weight = half_pi * cosh(t) / (ch * ch);
        const Real complement = 1 / (exp(s) * ch);  // 1 - tanh s
        if (k == 0) {
          levels[static_cast<std::size_t>(level)].push_back({Real(1), weight, 0});
        } else {
          levels[static_cast<std::size_t>(level)].push_back({complement, weight, -1});
          levels[static_cast<std::size_t>(level)].push_back({complement, weight, +1});
        }
      }
    }
  }
};

}  // namespace pendavg::detail
