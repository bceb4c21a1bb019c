// SPDX-License-Identifier: GPL-3.0-or-later
// The working precision of MPFR values: a shared lock on Boost 1.74's process-wide default
// precision (include/pendavg/mpfr.hpp explains the contract).
//
// Epochs. At any time the process computes in MPFR at one precision, the epoch's, held by
// `holders` threads. A thread that asks for the epoch's precision joins it unless an earlier
// request for another precision is waiting (first come, first served, so no precision starves);
// otherwise it waits until the epoch is empty. The default precision changes only when an epoch
// begins (and is restored to what it was before the first epoch when the last holder leaves), so
// no thread ever sees it change under a computation. A thread's nested guards form a stack: a
// nested guard of the same precision costs nothing, one of another precision leaves the outer
// epoch, enters its own, and re-enters the outer one when it ends.
#include "engine/precision.hpp"

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <stdexcept>

namespace pendavg {

namespace {

class PrecisionEpochs {
 public:
  /// Waits until this thread may compute at `precision` (alone, when `exclusive`), then holds it.
  void enter(unsigned precision, bool exclusive) {
    std::unique_lock lock(mutex_);
    const std::uint64_t ticket = next_ticket_++;
    waiting_.push_back({ticket, precision, exclusive});
    changed_.wait(lock, [&] { return may_enter(ticket, precision, exclusive); });
    for (auto it = waiting_.begin(); it != waiting_.end(); ++it) {
      if (it->ticket == ticket) {
        waiting_.erase(it);
        break;
      }
    }
    if (holders_ == 0) {
      if (!idle_known_) {
        idle_precision_ = mpfr_real::default_precision();
        idle_known_ = true;
      }
      epoch_precision_ = precision;
      mpfr_real::default_precision(precision);
    }
    exclusive_ = exclusive;
    ++holders_;
    changed_.notify_all();  // later requests of this precision may join now
  }

  void leave() {
    std::lock_guard lock(mutex_);
    if (--holders_ == 0) {
      mpfr_real::default_precision(idle_precision_);
      idle_known_ = false;
      exclusive_ = false;
    }
    changed_.notify_all();
  }

 private:
  struct Request {
    std::uint64_t ticket;
    unsigned precision;
    bool exclusive;
  };

  /// First come, first served: a request waits behind every earlier request it cannot share
  /// an epoch with. An exclusive request needs an empty epoch; a shared one joins the epoch of
  /// its precision (or starts one).
  bool may_enter(std::uint64_t ticket, unsigned precision, bool exclusive) const {
    if (exclusive) {
      if (holders_ > 0) return false;
      return waiting_.front().ticket == ticket;
    }
    if (holders_ > 0 && (exclusive_ || epoch_precision_ != precision)) return false;
    for (const Request& r : waiting_) {
      if (r.ticket >= ticket) break;
      if (r.exclusive || r.precision != precision) return false;
    }
    return true;
  }

  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Request> waiting_;
  std::uint64_t next_ticket_ = 0;
  std::size_t holders_ = 0;
  unsigned epoch_precision_ = 0;
  bool exclusive_ = false;
  unsigned idle_precision_ = 0;
  bool idle_known_ = false;
};

PrecisionEpochs& epochs() {
  static PrecisionEpochs instance;
  return instance;
}

/// This thread's nested working precisions (trivially destructible: no work at thread exit).
/// Inside an exclusive region the thread owns MPFR alone, and nested precisions are set
/// directly (`previous` restores them).
struct HeldPrecisions {
  struct Frame {
    unsigned precision;
    unsigned previous;
    bool exclusive;
  };
  static constexpr int capacity = 64;
  Frame frame[capacity];
  int depth = 0;
  int exclusive_depth = 0;
};
thread_local HeldPrecisions held;

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

void push_precision(int digits10, bool exclusive) {
  thread_local const MpfrThreadCaches caches;  // constructed once per thread, freed at its end
  if (digits10 < 1) throw std::invalid_argument("working_precision: digits must be >= 1");
  if (held.depth == HeldPrecisions::capacity)
    throw std::length_error("working_precision: nested too deeply");
  const auto precision = static_cast<unsigned>(digits10);
  const unsigned previous = mpfr_real::default_precision();
  if (held.exclusive_depth > 0) {
    mpfr_real::default_precision(precision);
  } else if (held.depth > 0) {
    const unsigned outer = held.frame[held.depth - 1].precision;
    if (exclusive || outer != precision) {
      epochs().leave();
      epochs().enter(precision, exclusive);
    }
  } else {
    epochs().enter(precision, exclusive);
  }
  held.frame[held.depth++] = {precision, previous, exclusive};
  if (exclusive) ++held.exclusive_depth;
}

void pop_precision() {
  const HeldPrecisions::Frame frame = held.frame[--held.depth];
  if (frame.exclusive) --held.exclusive_depth;
  if (held.exclusive_depth > 0) {
    mpfr_real::default_precision(frame.previous);
  } else if (held.depth > 0) {
    const unsigned outer = held.frame[held.depth - 1].precision;
    if (frame.exclusive || outer != frame.precision) {
      epochs().leave();
      epochs().enter(outer, false);
    }
  } else {
    epochs().leave();
  }
}

}  // namespace

working_precision::working_precision(int digits10) { push_precision(digits10, false); }

working_precision::~working_precision() { pop_precision(); }

exclusive_precision::exclusive_precision(int digits10) { push_precision(digits10, true); }

exclusive_precision::~exclusive_precision() { pop_precision(); }

int current_mpfr_digits() { return static_cast<int>(mpfr_real::default_precision()); }

}  // namespace pendavg
