// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute.cpp -- what both builds share (see distribute.hpp): failure reports, the
// launcher's rank count and a single process' sweep link.
#include "distribute.hpp"

#include "args.hpp"
#include "one_line.hpp"
#include "sweep.hpp"

#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace pendavg::cli {

namespace {

constexpr int exit_bad_input = 2;
constexpr int exit_internal_error = 1;
constexpr int exit_interrupted = 130;  // 128 + SIGINT, as a shell reports it

int report(std::string_view kind, std::string_view text, int exit_code) {
  const FailureReach reach = failure_reach();
  if (reach == FailureReach::every_rank && !is_root()) return exit_code;  // rank 0 says it
  // A failure of this rank's own names the rank; when the others went on, it stops them. Rank
  // 0's bad input and failed rows (an output it cannot write, a shard merge refuses) are the
  // job's, worded as one process words them.
  const bool named = reach == FailureReach::others_went_on ||
                     (reach == FailureReach::not_every_rank &&
                      (!is_root() || exit_code == exit_internal_error));
  const std::string who =
      !named ? ""
             : " (rank " + std::to_string(rank()) +
                   (reach == FailureReach::others_went_on ? " alone; stopping the job)" : ")");
  // One line, whatever the message, with what it echoes made safe for a terminal and capped.
  std::fprintf(stderr, "pendavg: %.*s: %s%s\n", static_cast<int>(kind.size()), kind.data(),
               one_line(text).c_str(), who.c_str());
  if (reach == FailureReach::others_went_on) abort_job(exit_code);
  return exit_code;
}

class LocalSweepLink final : public SweepLink {
 public:
  int rank() const override { return 0; }
  int ranks() const override { return 1; }
  std::uint64_t fetch(Counter counter, Op op, std::uint64_t operand) override {
    const std::uint64_t before = counters_[counter];
    if (op == Op::add) counters_[counter] += operand;
    if (op == Op::bit_or) counters_[counter] |= operand;
    if (op == Op::replace) counters_[counter] = operand;
    return before;
  }
  void send(int, std::string) override {
    throw std::logic_error("sweep link: a single process has no rank 0 to send to");
  }
  std::optional<Message> receive() override { return std::nullopt; }

 private:
  std::uint64_t counters_[3] = {};
};

}  // namespace

int launched_ranks() {
  // OpenMPI's mpirun and PMIx, MPICH's hydra and PMI-2, and Slurm's srun (a step's tasks: a batch
  // script itself has SLURM_NTASKS but not SLURM_STEP_NUM_TASKS).
  int most = 1;
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "SLURM_STEP_NUM_TASKS"})
    if (const char* value = std::getenv(name); value && *value)
      most = std::max(most, std::atoi(value));
  return most;
}

void refuse_copies(const char* why) {
  // Each process would run the whole command and write the same files: refuse instead (the
  // first rank says so; every rank exits 2).
  const int launched = launched_ranks();
  if (launched <= 1) return;
  const char* first_rank = nullptr;
  for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "SLURM_PROCID"})
    if (!first_rank) first_rank = std::getenv(name);
  if (!first_rank || std::atoi(first_rank) == 0)
    std::fprintf(stderr,
                 "pendavg: error: started as %d ranks (mpirun/srun), but %s: every rank would run "
                 "the whole command; run one process, or use --shard K/N for a job array\n",
                 launched, why);
  std::exit(2);
}

void on_root(const std::function<void()>& step) {
  std::string verdict;
  if (is_root()) try {
      step();
    } catch (const invalid_input& bad) {
      verdict = "!" + std::string(bad.what());  // not empty, whatever it says
    }
  verdict = broadcast_from_root(std::move(verdict));
  if (!verdict.empty()) throw usage_error(verdict.substr(1));
}

std::unique_ptr<SweepLink> local_sweep_link() { return std::make_unique<LocalSweepLink>(); }

ProcessGroup::~ProcessGroup() { leave_job(); }

void exit_process(int code) {
  std::fflush(nullptr);
  leave_job();
  std::_Exit(code);
}

int report_failure(const std::exception_ptr& failure) {
  try {
    std::rethrow_exception(failure);
  } catch (const rows_failed& failed) {
    return report("error", failed.what(), exit_rows_failed);
  } catch (const invalid_input& bad) {
    return report("error", bad.what(), exit_bad_input);
  } catch (const interrupted& stopped) {
    return report("interrupted", stopped.what(), exit_interrupted);
  } catch (const std::exception& error) {
    return report("internal error", error.what(), exit_internal_error);
  } catch (...) {
    return report("internal error", "unknown exception", exit_internal_error);
  }
}

}  // namespace pendavg::cli
