// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute.hpp -- the processes of one pendavg run: a single process (a plain run, or
// a build without MPI), or the ranks of an MPI job (pendavg built with MPI and started by
// mpirun or srun). Everything MPI is behind this interface (distribute_mpi.cpp; the build
// without MPI compiles distribute_serial.cpp instead), and the library never sees it.
//
// Rank 0 reads what must be read once, prints, and writes the output files; every rank parses
// the command line and computes. The sweep engine (sweep.hpp) talks through a SweepLink; the
// rest are collectives that every rank calls in the same order.
#pragma once

#include "pendavg/average.hpp"

#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace pendavg::cli {

/// Joins the MPI job when the process was started by an MPI launcher (mpirun, mpiexec, srun;
/// PENDAVG_MPI=1 forces it, =0 prevents it) and leaves it on destruction. One per process, in
/// main(). A process started as one of several ranks (launched_ranks() > 1) that cannot join
/// them refuses (refuse_copies): a build without MPI, PENDAVG_MPI=0, or ranks MPI does not
/// connect (srun --mpi=none). Each would run the whole command and write the same files.
class ProcessGroup {
 public:
  ProcessGroup(int& argc, char**& argv);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;
};

/// The number of ranks an MPI launcher (mpirun, mpiexec, srun) started, from the environment it
/// gives each process (1 when none did).
int launched_ranks();
/// When an MPI launcher started several ranks: says so with `why` this process does not join
/// them (rank 0 only) and exits 2 on every rank. A process not started so returns.
void refuse_copies(const char* why);

int rank();   ///< this process' rank (0 in a plain run)
int ranks();  ///< the number of ranks (1 in a plain run)
inline bool is_root() { return rank() == 0; }

/// Collective: the smallest `value` over the ranks.
std::uint64_t min_over_ranks(std::uint64_t value);
/// Collective: rank 0's `text` on every rank.
std::string broadcast_from_root(std::string text);
/// Collective: runs `step` on rank 0 alone (what must be done once: opening the output, reading
/// a resumed file); bad input it meets (invalid_input) is thrown on every rank (as usage_error).
void on_root(const std::function<void()>& step);

/// The shifts of one qmc average shared by all ranks (pendavg::ShiftPartition); null in a plain
/// run.
const ShiftPartition* shift_partition();

/// What the ranks of one sweep share (sweep.hpp), and all they need of each other: three
/// counters kept by rank 0 that every rank changes atomically, and messages to rank 0. A plain
/// run has one rank and keeps the counters in memory (local_sweep_link); an MPI job keeps them in
/// a window in rank 0's memory (MPI_Fetch_and_op: passive target, no answer from rank 0 awaited);
/// the unit tests connect ranks that are threads of one process.
class SweepLink {
 public:
  enum Counter : int { next_chunk = 0, unwritten = 1, stop = 2 };
  enum class Op { add, bit_or, replace, read };
  enum Tag : int { rows = 1, finished = 2 };  ///< messages to rank 0: rows, then one finished
  struct Message {
    int source = 0, tag = 0;
    std::string payload;
  };
  virtual ~SweepLink() = default;
  virtual int rank() const = 0;
  virtual int ranks() const = 0;
  /// Applies `op` with `operand` to the counter, atomically; returns its value before.
  virtual std::uint64_t fetch(Counter counter, Op op, std::uint64_t operand = 0) = 0;
  /// From a rank other than 0: sends to rank 0 and returns without waiting for it to receive
  /// (the link keeps the payload until it has gone), except the rank's last message (tag
  /// finished), which returns once every message has gone; messages arrive in the order sent.
  virtual void send(int tag, std::string payload) = 0;
  /// On rank 0: a message that has arrived, if any (never waits).
  virtual std::optional<Message> receive() = 0;
};

/// The link of a single process: the counters in memory, no messages.
std::unique_ptr<SweepLink> local_sweep_link();

/// Collective: the link of the ranks of this job (local_sweep_link in a plain run or on one
/// rank). Its destruction is collective too, except while an exception leaves the sweep on this
/// rank: then its share is let go here and the rest waits for the ranks' farewell.
std::unique_ptr<SweepLink> open_sweep_link();

/// Prints "pendavg: error: ..." (bad input, returns 2), "pendavg: interrupted: ..." (a signal
/// before anything was finished, returns 130) or "pendavg: internal error: ..." (returns 1) for
/// `failure`, on rank 0 only; one line. A failure not every rank shares (failure_reach) is
/// printed by the rank that met it, naming the rank; when the others went on without it, the
/// whole job stops with the same code (abort_job).
int report_failure(const std::exception_ptr& failure);

/// Ends the process now with `code`, after flushing stdio and leaving the MPI job: for a run
/// whose compute threads were left behind (an interrupted sweep with rows still running).
[[noreturn]] void exit_process(int code);
/// Leaves the MPI job, once (meets the other ranks at their end, MPI_Finalize); nothing in a
/// plain run. For ~ProcessGroup and exit_process.
void leave_job();

/// After a failure on this rank, where the others are (every rank calls this or ends normally;
/// the failed rank waits up to failure_agreement_seconds for them): every rank failed too (the
/// same bad input reaches every rank; rank 0 reports it), some ended normally (this rank reports
/// its own failure), or some did not come to their end in time: they went on into the next
/// collective step, where they would wait for this rank forever.
enum class FailureReach { every_rank, not_every_rank, others_went_on };
FailureReach failure_reach();
inline constexpr double failure_agreement_seconds = 10;
/// Stops every rank of the job with `code` (MPI_Abort; a plain run just exits).
[[noreturn]] void abort_job(int code);

}  // namespace pendavg::cli
