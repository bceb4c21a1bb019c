// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/parallel.hpp -- exceptions out of OpenMP regions.
//
// An exception may not leave an OpenMP structured block (the runtime calls std::terminate). Each
// parallel loop body runs inside ParallelErrors::capture, which keeps the first exception; the
// loops poll failed() to skip the remaining iterations, and the caller rethrows after the region.
#pragma once

#include <atomic>
#include <exception>
#include <mutex>

namespace pendavg {

class ParallelErrors {
 public:
  /// Runs body(); an exception is stored (the first one wins) instead of propagating.
  template <class Body>
  void capture(Body&& body) noexcept {
    if (failed()) return;
    try {
      body();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!first_) first_ = std::current_exception();
      failed_.store(true, std::memory_order_relaxed);
    }
  }
  bool failed() const { return failed_.load(std::memory_order_relaxed); }
  /// After the parallel region: rethrows the stored exception, if any.
  void rethrow() const {
    if (first_) std::rethrow_exception(first_);
  }

 private:
  std::mutex mutex_;
  std::exception_ptr first_;
  std::atomic<bool> failed_{false};
};

}  // namespace pendavg
