// SPDX-License-Identifier: GPL-3.0-or-later
// The chain model, its validation, and the method names.
#include "pendavg/chain.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/result.hpp"
#include "pendavg/version.hpp"

#include <boost/math/special_functions/fpclassify.hpp>

#include <limits>
#include <string>

namespace pendavg {
namespace {

template <class Real>
bool finite(const Real& x) {
  return (boost::math::isfinite)(x);
}

std::string position(const char* what, std::size_t i) {
  return std::string(what) + " " + std::to_string(i + 1);
}

/// A hardware float below its normal range carries fewer significant bits than the digits
/// asked for (1e-320 as a double is off by 1e-3 relative): refused, with the way out. `what()`
/// names the parameter (called only for the message).
template <class Real, class What>
void check_normal(const Real& x, const What& what) {
  if constexpr (std::numeric_limits<Real>::is_specialized && std::numeric_limits<Real>::is_iec559) {
    if (x < std::numeric_limits<Real>::min()) {
      // No advice here: whether more digits help depends on the method (transfer, qmc and the
      // dynamics run in double only); the front ends add it where it is true.
      throw invalid_input(std::string(what()) + " is below the normal range of double " +
                          "(2.2e-308), where it loses digits");
    }
  } else {
    (void)x;
    (void)what;
  }
}

}  // namespace

template <class Real>
Chain<Real>::Chain(std::vector<Real> masses, std::vector<Real> lengths, Real g)
    : masses_(std::move(masses)), lengths_(std::move(lengths)), g_(std::move(g)) {
  if (masses_.empty()) throw invalid_input("a chain needs at least one mass");
  if (masses_.size() != lengths_.size()) {
    throw invalid_input("got " + std::to_string(masses_.size()) + " masses but " +
                        std::to_string(lengths_.size()) + " lengths");
  }
  for (std::size_t i = 0; i < masses_.size(); ++i) {
    if (!finite(masses_[i]) || !(masses_[i] > 0)) {
      throw invalid_input(position("mass", i) + " must be finite and > 0");
    }
    if (!finite(lengths_[i]) || !(lengths_[i] > 0)) {
      throw invalid_input(position("length", i) + " must be finite and > 0");
    }
    check_normal(masses_[i], [i] { return position("mass", i); });
    check_normal(lengths_[i], [i] { return position("length", i); });
  }
  if (!finite(g_) || g_ < 0) throw invalid_input("g must be finite and >= 0");
  if (g_ > 0) check_normal(g_, [] { return "g"; });
  tail_masses_.assign(masses_.size(), Real(0));
  Real sum = 0;
  for (std::size_t j = masses_.size(); j-- > 0;) {
    sum += masses_[j];
    tail_masses_[j] = sum;
  }
  if (!finite(sum)) throw invalid_input("the total mass overflows");
}

template <class Real>
void check_beta(const Real& beta) {
  if (!finite(beta) || !(beta > 0)) throw invalid_input("beta must be finite and > 0");
  check_normal(beta, [] { return "beta"; });
}

template <class Real>
void check_digits(int digits) {
  if constexpr (is_mpfr_v<Real>) {
    if (digits < min_digits || digits > max_digits) {
      throw invalid_input("digits must be in " + std::to_string(min_digits) + ".." +
                          std::to_string(max_digits) + ", got " + std::to_string(digits));
    }
  } else if (digits != min_digits) {
    throw invalid_input("double precision gives " + std::to_string(min_digits) +
                        " digits; more need the MPFR type");
  }
}

const char* method_name(Method m) {
  switch (m) {
    case Method::series: return "series";
    case Method::reduced_integral: return "integral";
    case Method::high_temperature_limit: return "limit-beta0";
    case Method::low_temperature_limit: return "limit-beta-infinity";
    case Method::torus_trapezoid: return "torus-trapezoid";
    case Method::torus_gauss_legendre: return "torus-gauss";
    case Method::qmc: return "qmc";
    case Method::transfer: return "transfer";
    case Method::low_temperature_extrapolation: return "low-temperature-extrapolation";
    case Method::microcanonical: return "microcanonical";
    case Method::dynamics_nve: return "dynamics-nve";
    case Method::dynamics_langevin: return "dynamics-langevin";
    case Method::certified_integral: return "certified-integral";
  }
  return "unknown";
}

const char* version() { return PENDAVG_VERSION; }

const char* error_kind_name(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::bound: return "bound";
    case ErrorKind::estimate: return "estimate";
    case ErrorKind::statistical: return "statistical";
  }
  return "unknown";
}

const char* work_unit_name(WorkUnit unit) {
  switch (unit) {
    case WorkUnit::terms: return "terms";
    case WorkUnit::nodes: return "nodes";
    case WorkUnit::samples: return "samples";
    case WorkUnit::steps: return "steps";
  }
  return "unknown";
}

template class PENDAVG_EXPORT Chain<double>;
template class PENDAVG_EXPORT Chain<long double>;
template class PENDAVG_EXPORT Chain<mpfr_real>;
template PENDAVG_EXPORT void check_beta<double>(const double&);
template PENDAVG_EXPORT void check_beta<long double>(const long double&);
template PENDAVG_EXPORT void check_beta<mpfr_real>(const mpfr_real&);
template PENDAVG_EXPORT void check_digits<double>(int);
template PENDAVG_EXPORT void check_digits<long double>(int);
template PENDAVG_EXPORT void check_digits<mpfr_real>(int);

}  // namespace pendavg
