// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/interrupt.cpp -- see interrupt.hpp.
#include "interrupt.hpp"

#include <array>
#include <csignal>
#include <cstdio>
#include <mutex>

namespace pendavg::cli {

namespace {

std::atomic<bool> stop_requested{false};
extern "C" void request_stop(int) { stop_requested.store(true); }

constexpr std::array<int, 3> deferred_signals{SIGINT, SIGTERM, SIGHUP};
std::array<volatile std::sig_atomic_t, 3> deferred_pending{};
extern "C" void defer_signal(int signal) {
  for (std::size_t k = 0; k < deferred_signals.size(); ++k)
    if (deferred_signals[k] == signal) deferred_pending[k] = 1;
  stop_requested.store(true);
}

std::mutex defer_mutex;
int defer_depth = 0;
std::array<struct sigaction, 3> deferred_previous{};

struct sigaction install(int signal, void (*handler)(int)) {
  struct sigaction action {}, previous {};
  action.sa_handler = handler;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: blocking calls return EINTR and the flag is seen
  sigaction(signal, &action, &previous);
  return previous;
}

}  // namespace

std::atomic<bool>& stop_flag() { return stop_requested; }

StopOnSignal::StopOnSignal() {
  stop_requested.store(false);
  previous_int_ = install(SIGINT, request_stop);
  previous_term_ = install(SIGTERM, request_stop);
}

StopOnSignal::~StopOnSignal() {
  sigaction(SIGINT, &previous_int_, nullptr);
  sigaction(SIGTERM, &previous_term_, nullptr);
}

DeferSignals::DeferSignals() {
  const std::lock_guard lock(defer_mutex);
  if (defer_depth++ > 0) return;
  for (std::size_t k = 0; k < deferred_signals.size(); ++k) {
    deferred_pending[k] = 0;
    deferred_previous[k] = install(deferred_signals[k], defer_signal);
  }
}

DeferSignals::~DeferSignals() {
  const std::lock_guard lock(defer_mutex);
  if (--defer_depth > 0) return;
  for (std::size_t k = 0; k < deferred_signals.size(); ++k) {
    sigaction(deferred_signals[k], &deferred_previous[k], nullptr);
    // A handler of the caller's (StopOnSignal) has seen the flag; the default action is taken
    // now that the file is in a consistent state.
    if (deferred_pending[k] && deferred_previous[k].sa_handler == SIG_DFL)
      std::raise(deferred_signals[k]);
  }
}

void Progress::operator()(double fraction, const std::string& detail) {
  const double elapsed = seconds();
  if (elapsed - last_ < 2) return;
  last_ = elapsed;
  std::fprintf(stderr, "[%s] %3.0f%% %s(%.0f s)\n", command_.c_str(), 100 * fraction,
               detail.c_str(), elapsed);
}

}  // namespace pendavg::cli
