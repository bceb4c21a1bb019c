// SPDX-License-Identifier: GPL-3.0-or-later
// The working precision of MPFR values: this thread's default precision and precision rule in
// Boost.Multiprecision (>= 1.77 keeps both per thread; include/pendavg/mpfr.hpp explains the
// contract). Nothing here is shared between threads: no lock.
#include "engine/numerics/precision.hpp"

#include <stdexcept>

namespace pendavg {

namespace {

/// MPFR keeps caches per thread (constants such as pi and log 2, a pool of integers) that every
/// thread must free before it ends (mpfr_free_cache2), or they leak: a worker of the caller's, a
/// sweep's thread and its OpenMP team. A thread that computed under a working_precision frees
/// them when it ends.
struct MpfrThreadCaches {
  MpfrThreadCaches() = default;
  MpfrThreadCaches(const MpfrThreadCaches&) = delete;
  MpfrThreadCaches& operator=(const MpfrThreadCaches&) = delete;
  ~MpfrThreadCaches() { mpfr_free_cache2(MPFR_FREE_LOCAL_CACHE); }
};

}  // namespace

working_precision::working_precision(int digits10)
    : previous_digits10_(mpfr_real::thread_default_precision()),
      previous_options_(mpfr_real::thread_default_variable_precision_options()) {
  thread_local const MpfrThreadCaches caches;  // constructed once per thread, freed at its end
  if (digits10 < 1) throw std::invalid_argument("working_precision: digits must be >= 1");
  mpfr_real::thread_default_precision(static_cast<unsigned>(digits10));
  mpfr_real::thread_default_variable_precision_options(mpfr_precision_rule);
}

working_precision::~working_precision() {
  mpfr_real::thread_default_variable_precision_options(previous_options_);
  mpfr_real::thread_default_precision(previous_digits10_);
}

int current_mpfr_digits() { return static_cast<int>(mpfr_real::thread_default_precision()); }

}  // namespace pendavg
