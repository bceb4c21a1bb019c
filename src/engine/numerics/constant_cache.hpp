// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/constant_cache.hpp -- tables of constants (quadrature rules, series coefficients) shared
// by every call and thread: built once per key (a size and the MPFR precision; 0 for hardware
// types), never changed afterwards. Each holds its own lock where it grows lazily. Up to
// `capacity` keys are kept, the least recently used dropped first (callers hold a shared_ptr, so
// a dropped table lives until its last user is done).
#pragma once

#include <cstddef>
#include <list>
#include <memory>
#include <mutex>
#include <utility>

namespace pendavg {

template <class Table>
class ConstantCache {
 public:
  explicit ConstantCache(std::size_t capacity = 32) : capacity_(capacity) {}

  /// The table of (size, precision), constructed from `args` when it is not cached yet.
  template <class... Args>
  std::shared_ptr<const Table> get(std::size_t size, unsigned precision, Args&&... args) {
    const std::lock_guard lock(mutex_);
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->size == size && it->precision == precision) {
        entries_.splice(entries_.begin(), entries_, it);  // most recently used first
        return entries_.front().table;
      }
    }
    entries_.push_front({size, precision, std::make_shared<const Table>(std::forward<Args>(args)...)});
    if (entries_.size() > capacity_) entries_.pop_back();
    return entries_.front().table;
  }

 private:
  struct Entry {
    std::size_t size;
    unsigned precision;
    std::shared_ptr<const Table> table;
  };
  std::size_t capacity_;
  std::mutex mutex_;
  std::list<Entry> entries_;
};

}  // namespace pendavg
