// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute_serial.cpp -- distribute.hpp for a build without MPI: one process.
#include "distribute.hpp"

#include <cstdio>
#include <cstdlib>

namespace pendavg::cli {

ProcessGroup::ProcessGroup(int&, char**&) {
  refuse_copies("this pendavg was built without MPI");
}
ProcessGroup::~ProcessGroup() = default;

int rank() { return 0; }
int ranks() { return 1; }

std::uint64_t min_over_ranks(std::uint64_t value) { return value; }
std::string broadcast_from_root(std::string text) { return text; }
std::vector<double> all_gather(std::span<const double> local) {
  return {local.begin(), local.end()};
}
const ShiftPartition* shift_partition() { return nullptr; }
std::unique_ptr<SweepLink> open_sweep_link() { return local_sweep_link(); }

FailureReach failure_reach() { return FailureReach::every_rank; }
void abort_job(int code) { exit_process(code); }

void exit_process(int code) {
  std::fflush(stdout);
  std::fflush(stderr);
  std::_Exit(code);
}

}  // namespace pendavg::cli
