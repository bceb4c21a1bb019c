// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/interrupt.hpp -- SIGINT/SIGTERM end long CLI runs cleanly: a handler sets a flag that
// the library polls (DynamicsObserver::stop) or the CLI checks between points, and the command
// still prints what it finished. While an output file is being written (temporary file, then
// rename), the same signals are deferred, so that none leaves a truncated temporary behind.
#pragma once

#include <atomic>
#include <chrono>
#include <csignal>
#include <string>

namespace pendavg::cli {

/// The flag the handlers set (false until a signal arrives while a StopOnSignal is alive).
std::atomic<bool>& stop_flag();

/// Installs SIGINT/SIGTERM handlers that set stop_flag() for its lifetime (and clears the flag
/// first); restores the previous handlers after.
class StopOnSignal {
 public:
  StopOnSignal();
  ~StopOnSignal();
  StopOnSignal(const StopOnSignal&) = delete;
  StopOnSignal& operator=(const StopOnSignal&) = delete;

 private:
  struct sigaction previous_int_{}, previous_term_{};
};

/// While alive, SIGINT, SIGTERM and SIGHUP only set stop_flag() and are remembered; on
/// destruction the previous handlers come back and a remembered signal whose previous action
/// was the default one is raised again (so it still ends the process, but only after the file
/// was committed or removed). Nests: only the outermost object acts.
class DeferSignals {
 public:
  DeferSignals();
  ~DeferSignals();
  DeferSignals(const DeferSignals&) = delete;
  DeferSignals& operator=(const DeferSignals&) = delete;
};

/// Prints "[command] ..." to stderr at most every 2 s, starting after 2 s.
class Progress {
 public:
  explicit Progress(std::string command) : command_(std::move(command)) {}
  void operator()(double fraction, const std::string& detail = "");
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::string command_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  double last_ = 0;
};

}  // namespace pendavg::cli
