// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute_serial.cpp -- distribute.hpp for a build without MPI: one process.
#include "distribute.hpp"

#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace pendavg::cli {

ProcessGroup::ProcessGroup(int&, char**&) {}
ProcessGroup::~ProcessGroup() = default;

int rank() { return 0; }
int ranks() { return 1; }
std::string distribution_text() { return "built without MPI"; }

std::uint64_t min_over_ranks(std::uint64_t value) { return value; }
std::string broadcast_from_root(std::string text) { return text; }
std::vector<double> all_gather(std::span<const double> local) {
  return {local.begin(), local.end()};
}
std::vector<std::string> gather_to_root(const std::string& local) { return {local}; }
const ShiftPartition* shift_partition() { return nullptr; }

void post(int, int, std::string) { throw std::logic_error("post: a plain run has no other rank"); }
std::optional<Message> receive(int) { return std::nullopt; }
bool sends_pending(std::vector<std::string>*) { return false; }
bool receives_pending() { return false; }
void recycle_received(std::string&&) {}
std::uint64_t* open_shared_cells(int) { return nullptr; }
void release_shared_cells() {}

FailureReach failure_reach() { return FailureReach::every_rank; }
void abort_job(int code) { exit_process(code); }

void exit_process(int code) {
  std::fflush(stdout);
  std::fflush(stderr);
  std::_Exit(code);
}

}  // namespace pendavg::cli
