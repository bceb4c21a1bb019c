// src/cli/interrupt.cpp -- see interrupt.hpp.
#include "interrupt.hpp"

#include <csignal>
#include <cstdio>

namespace pendavg::cli {

namespace {
std::atomic<bool> stop_requested{false};
extern "C" void request_stop(int) { stop_requested.store(true); }
}  // namespace

std::atomic<bool>& stop_flag() { return stop_requested; }

StopOnSignal::StopOnSignal() {
  stop_requested.store(false);
  previous_int_ = std::signal(SIGINT, request_stop);
  previous_term_ = std::signal(SIGTERM, request_stop);
}

StopOnSignal::~StopOnSignal() {
  std::signal(SIGINT, previous_int_);
  std::signal(SIGTERM, previous_term_);
}

void Progress::operator()(double fraction, const std::string& detail) {
  const double elapsed = seconds();
  if (elapsed - last_ < 2) return;
  last_ = elapsed;
  std::fprintf(stderr, "[%s] %3.0f%% %s(%.0f s)\n", command_.c_str(), 100 * fraction,
               detail.c_str(), elapsed);
}

}  // namespace pendavg::cli
