// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute.hpp -- the processes of one pendavg run: a single process (a plain run, or
// a build without MPI), or the ranks of an MPI job (pendavg built with MPI and started by
// mpirun or srun). Everything MPI is behind this interface (distribute_mpi.cpp; the build
// without MPI compiles distribute_serial.cpp instead), and the library never sees it.
//
// Rank 0 reads what must be read once, prints, and writes the output files; every rank parses
// the command line and computes. The sweep engine (sweep.hpp) sends rows between ranks with
// post() and receive(); the rest are collectives that every rank calls in the same order.
#pragma once

#include "pendavg/average.hpp"

#include <cstdint>
#include <exception>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace pendavg::cli {

/// Joins the MPI job when the process was started by an MPI launcher (mpirun, mpiexec, srun;
/// PENDAVG_MPI=1 forces it, =0 prevents it) and leaves it on destruction. One per process, in
/// main(). Without MPI it does nothing.
class ProcessGroup {
 public:
  ProcessGroup(int& argc, char**& argv);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;
};

int rank();   ///< this process' rank (0 in a plain run)
int ranks();  ///< the number of ranks (1 in a plain run)
inline bool is_root() { return rank() == 0; }
/// "MPI, K ranks" or "no MPI": for messages and the --version line.
std::string distribution_text();

/// Collective: the smallest `value` over the ranks.
std::uint64_t min_over_ranks(std::uint64_t value);
/// Collective: rank 0's `text` on every rank.
std::string broadcast_from_root(std::string text);
/// Collective: every rank's `local` values concatenated in rank order, on every rank.
std::vector<double> all_gather(std::span<const double> local);
/// Collective: every rank's `local` bytes, in rank order, on rank 0 (empty elsewhere).
std::vector<std::string> gather_to_root(const std::string& local);

/// The shifts of one qmc average shared by all ranks (pendavg::ShiftPartition); null in a plain
/// run.
const ShiftPartition* shift_partition();

/// A point-to-point message of the sweep engine.
struct Message {
  int source = 0;
  int tag = 0;
  std::string payload;
};
/// Sends `payload` to `destination` without waiting (the payload is kept until it is sent).
void post(int destination, int tag, std::string payload);
/// The next message that has arrived, if any (never waits). Messages come in the order they
/// arrived, except that a complete one tagged `urgent_tag` (a short request) goes ahead of
/// long ones still arriving before it.
std::optional<Message> receive(int urgent_tag = -1);
/// True while some posted message has not been sent yet (also advances them). The payloads of
/// the sends that completed are moved into `*sent` when it is given (for reuse).
bool sends_pending(std::vector<std::string>* sent = nullptr);
/// Memory for later long messages to arrive in: a received payload the caller is done with
/// (fresh memory costs a page fault every 4 kB: ~10 us each in a VM, ~2 ms for a chunk of
/// 2,000 double rows). Up to 16 MB are kept.
void recycle_received(std::string&& payload);
/// True while a message is being received. A long one (a chunk's rows) moves while the receiver
/// calls MPI (with OpenMPI's shared-memory transport the receiver copies it out of the sender's
/// memory; the sender's MPI calls only complete the send).
bool receives_pending();

/// Cells in rank 0's memory that every rank of the job reads and changes with atomic operations
/// (an MPI-3 shared-memory window: the sweep's next row and its reorder limit, so that a rank
/// takes its next chunk without waiting for rank 0 to answer). Collective: every rank calls it at
/// the same point. Returns `count` 8-byte-aligned cells, zeroed, or null when the ranks cannot
/// all reach rank 0's memory (not one node, one rank, a plain run, a window without the unified
/// memory model, or PENDAVG_SWEEP_SHARED=0 on any rank): then the caller uses messages.
std::uint64_t* open_shared_cells(int count);
/// Local: this rank uses the cells no more (the end of its sweep, or a failure that left it;
/// nothing when there are none). They are freed where the ranks meet at the end of the job, a
/// collective step every rank reaches anyway (freeing them at the end of the sweep was one more,
/// ~0.2 ms on the sweep's critical path). When the ranks do not all meet there, the job is
/// stopped (report_failure) and the cells go with it.
void release_shared_cells();

/// Prints "pendavg: error: ..." (bad input, returns 2), "pendavg: interrupted: ..." (a signal
/// before anything was finished, returns 130) or "pendavg: internal error: ..." (returns 1) for
/// `failure`, on rank 0 only; one line. A failure not every rank shares (failure_reach) is
/// printed by the rank that met it, naming the rank; when the others went on without it, the
/// whole job stops with the same code (abort_job).
int report_failure(const std::exception_ptr& failure);

/// Ends the process now with `code`, after flushing stdio and leaving the MPI job: for a run
/// whose compute threads were left behind (an interrupted sweep with rows still running).
[[noreturn]] void exit_process(int code);

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
