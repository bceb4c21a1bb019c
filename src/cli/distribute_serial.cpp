// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute_serial.cpp -- distribute.hpp for a build without MPI: one process.
#include "distribute.hpp"

namespace pendavg::cli {

ProcessGroup::ProcessGroup(int&, char**&) { refuse_copies("this pendavg was built without MPI"); }
void leave_job() {}

int rank() { return 0; }
int ranks() { return 1; }

std::uint64_t min_over_ranks(std::uint64_t value) { return value; }
std::string broadcast_from_root(std::string text) { return text; }
const ShiftPartition* shift_partition() { return nullptr; }
std::unique_ptr<SweepLink> open_sweep_link() { return local_sweep_link(); }

FailureReach failure_reach() { return FailureReach::every_rank; }
void abort_job(int code) { exit_process(code); }

}  // namespace pendavg::cli
