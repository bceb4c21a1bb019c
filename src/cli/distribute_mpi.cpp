// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute_mpi.cpp -- distribute.hpp over MPI (the build with MPI). Only the main
// thread calls MPI (MPI_THREAD_FUNNELED): the sweep engine's coordinator runs there and its
// compute threads never communicate. Errors: MPI_COMM_WORLD's handler is set to
// MPI_ERRORS_ARE_FATAL (MPI's default, pinned here against a launcher's -initial-errhandler; the
// communicators duplicated from it inherit it, the window gets it too): a failing MPI call stops
// the job inside the call, so return codes are not checked.
#include "distribute.hpp"

#include <mpi.h>

#include <chrono>
#include <csignal>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <numeric>
#include <stdexcept>
#include <string_view>
#include <thread>
#include <utility>

namespace pendavg::cli {

namespace {

bool joined = false;  // MPI_Init_thread was called by us
int my_rank = 0, my_size = 1;
/// Where the ranks meet at their end (a reduction of its own, never mixed with the commands'
/// collectives on MPI_COMM_WORLD): a rank that failed learns there whether the others failed too.
MPI_Comm farewell = MPI_COMM_NULL;
/// The window of the sweep link's counters, and whether this rank's access epoch on it is open
/// (while its sweep link lives). It is freed at the farewell, where every rank is: freeing it is
/// collective.
MPI_Win sweep_window = MPI_WIN_NULL;
bool sweep_window_locked = false;
int farewell_failed = 0, every_rank_failed = 0;  // the reduction's buffers (MPI_MIN)

/// Arrives at the end of the job (`failed`: this rank ends with a failure; a later call waits
/// for the same meeting) and waits until every rank has (every_rank: all failed, or
/// not_every_rank) or (`limit_seconds` >= 0) until that many seconds passed (others_went_on).
/// Polls every millisecond: a rank waiting here (for rank 0's computation, say) leaves its core
/// to the others.
FailureReach meet_at_farewell(bool failed, double limit_seconds) {
  static MPI_Request request = MPI_REQUEST_NULL;
  static bool started = false;
  if (!std::exchange(started, true)) {
    farewell_failed = failed ? 1 : 0;
    MPI_Iallreduce(&farewell_failed, &every_rank_failed, 1, MPI_INT, MPI_MIN, farewell, &request);
  }
  for (const double start = MPI_Wtime();;) {
    int done = 0;
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);  // a completed request is null: done at once
    if (done) {
      // Every rank is here, and every rank let the sweep's window go: it is freed together.
      if (std::exchange(sweep_window_locked, false)) MPI_Win_unlock_all(sweep_window);
      if (sweep_window != MPI_WIN_NULL) MPI_Win_free(&sweep_window);
      return every_rank_failed ? FailureReach::every_rank : FailureReach::not_every_rank;
    }
    if (limit_seconds >= 0 && MPI_Wtime() - start > limit_seconds)
      return FailureReach::others_went_on;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

/// Started by an MPI launcher? OpenMPI's mpirun, PMIx (srun --mpi=pmix, prterun), PMI-1/2
/// (MPICH's hydra, srun --mpi=pmi2).
bool launched_by_mpi() {
  if (const char* forced = std::getenv("PENDAVG_MPI"); forced && *forced)
    return std::string_view(forced) != "0";
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(name)) return true;
  return launched_ranks() > 1;
}

int byte_count(std::size_t size) {
  if (size > static_cast<std::size_t>(INT_MAX))
    throw std::runtime_error("MPI: a message of " + std::to_string(size) + " bytes is too long");
  return static_cast<int>(size);
}

/// The shifts of one qmc point split between the ranks (shift_partition: only with 2 or more).
class RankPartition final : public ShiftPartition {
 public:
  int part() const override { return my_rank; }
  int parts() const override { return my_size; }
  /// Every rank's `local` values concatenated in rank order, on every rank (collective).
  std::vector<double> all_gather(std::span<const double> local) const override {
    const int mine = byte_count(local.size() * sizeof(double)) / static_cast<int>(sizeof(double));
    std::vector<int> counts(static_cast<std::size_t>(my_size)), offsets(counts.size());
    MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
    std::exclusive_scan(counts.begin(), counts.end(), offsets.begin(), 0);
    std::vector<double> all(static_cast<std::size_t>(offsets.back() + counts.back()));
    MPI_Allgatherv(local.data(), mine, MPI_DOUBLE, all.data(), counts.data(), offsets.data(),
                   MPI_DOUBLE, MPI_COMM_WORLD);
    return all;
  }
};
const RankPartition rank_partition;

/// The counters in a window of rank 0's memory, changed by MPI_Fetch_and_op (passive target: in
/// one lock_all epoch for the whole sweep); rows go to rank 0 in messages of the sweep's own
/// communicator.
class MpiSweepLink final : public SweepLink {
 public:
  MpiSweepLink() {
    if (sweep_window != MPI_WIN_NULL) MPI_Win_free(&sweep_window);  // an earlier sweep's
    if (comm_ == MPI_COMM_NULL) MPI_Comm_dup(MPI_COMM_WORLD, &comm_);
    const MPI_Aint bytes = my_rank == 0 ? 3 * sizeof(std::uint64_t) : 0;
    MPI_Win_allocate(bytes, sizeof(std::uint64_t), MPI_INFO_NULL, comm_, &counters_, &sweep_window);
    MPI_Win_set_errhandler(sweep_window, MPI_ERRORS_ARE_FATAL);
    if (my_rank == 0)
      for (int k = 0; k < 3; ++k) counters_[k] = 0;
    MPI_Barrier(comm_);  // the zeros are there before anyone fetches
    MPI_Win_lock_all(0, sweep_window);
    sweep_window_locked = true;
  }
  /// Local: the window is freed at the farewell (a rank that ends the sweep early -- abandoned
  /// rows, a failure -- must not wait there for the others).
  ~MpiSweepLink() override {
    if (std::exchange(sweep_window_locked, false)) MPI_Win_unlock_all(sweep_window);
    // Normally none left: the last message waited for them.
    for (Outgoing& message : outgoing_) MPI_Wait(&message.request, MPI_STATUS_IGNORE);
  }
  int rank() const override { return my_rank; }
  int ranks() const override { return my_size; }
  std::uint64_t fetch(Counter counter, Op op, std::uint64_t operand) override {
    static const MPI_Op mpi_ops[] = {MPI_SUM, MPI_BOR, MPI_REPLACE, MPI_NO_OP};  // Op's order
    std::uint64_t before = 0;
    MPI_Fetch_and_op(&operand, &before, MPI_UINT64_T, 0, counter, mpi_ops[static_cast<int>(op)],
                     sweep_window);
    MPI_Win_flush(0, sweep_window);
    return before;
  }
  /// Rank 0 receives when its coordinator polls (every 2 ms): a blocking send of a long message
  /// would spin on this rank's core until then, time taken from its compute threads.
  void send(int tag, std::string payload) override {
    int gone = 1;  // let go of the payloads that have gone
    while (gone && !outgoing_.empty()) {
      MPI_Test(&outgoing_.front().request, &gone, MPI_STATUS_IGNORE);
      if (gone) outgoing_.pop_front();
    }
    Outgoing& message = outgoing_.emplace_back(Outgoing{MPI_REQUEST_NULL, std::move(payload)});
    MPI_Isend(message.payload.data(), byte_count(message.payload.size()), MPI_BYTE, 0, tag, comm_,
              &message.request);
    if (tag != finished) return;
    // The rank's last message: everything it sent must reach rank 0 before the process may end
    // (a rank with abandoned rows exits right after).
    for (Outgoing& sent : outgoing_) MPI_Wait(&sent.request, MPI_STATUS_IGNORE);
    outgoing_.clear();
  }
  std::optional<Message> receive() override {
    int arrived = 0, size = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, comm_, &arrived, &status);
    if (!arrived) return std::nullopt;
    MPI_Get_count(&status, MPI_BYTE, &size);
    Message message{status.MPI_SOURCE, status.MPI_TAG,
                    std::string(static_cast<std::size_t>(size), '\0')};
    MPI_Recv(message.payload.data(), size, MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG, comm_,
             MPI_STATUS_IGNORE);
    return message;
  }

 private:
  /// The sweeps' own communicator (rows never mix with the commands' collectives), kept for a
  /// later sweep and freed by MPI_Finalize.
  static inline MPI_Comm comm_ = MPI_COMM_NULL;
  std::uint64_t* counters_ = nullptr;
  struct Outgoing {
    MPI_Request request;
    std::string payload;
  };
  std::deque<Outgoing> outgoing_;  ///< sent, not known to have gone (a deque: payloads stay put)
};

}  // namespace

ProcessGroup::ProcessGroup(int& argc, char**& argv) {
  if (!launched_by_mpi()) {  // started as several ranks only with PENDAVG_MPI=0
    refuse_copies("PENDAVG_MPI=0 keeps this pendavg out of MPI");
    return;
  }
  // Open MPI's shared-memory one-sided component (osc/sm: on one node when the vader BTL has no
  // single-copy mechanism, btl_vader_single_copy_mechanism=none, as in containers) did not show
  // the other ranks rank 0's own updates of the sweep's counters (Open MPI 4.1.4: a stop set by
  // rank 0 never reached rank 1, which computed every row left); the other components do.
  // Unless the user chose the component.
  setenv("OMPI_MCA_osc", "^sm", 0);
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);  // a failure aborts
  joined = true;
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_ARE_FATAL);  // inherited by the dups
  MPI_Comm_dup(MPI_COMM_WORLD, &farewell);
  MPI_Comm_rank(MPI_COMM_WORLD, &my_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &my_size);
  // A launcher of K ranks whose processes MPI does not connect (srun --mpi=none: K singletons).
  if (my_size == 1) refuse_copies("MPI sees one rank (launch with MPI support: srun --mpi=pmix)");
  if (provided < MPI_THREAD_FUNNELED && my_size > 1) {
    if (my_rank == 0)
      std::fprintf(stderr, "pendavg: internal error: the MPI library does not provide "
                           "MPI_THREAD_FUNNELED\n");
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
}

void leave_job() {
  if (!std::exchange(joined, false)) return;
  // A rank done with its share waits here for the others. The SIGINT/SIGTERM that mpirun and
  // srun send every rank must not kill it: mpirun would then kill the job while rank 0 still
  // writes what the signal stopped (the replicas rank 0 alone ran, say). The first of each is
  // absorbed; a second one ends the rank (a peer that will never come: Ctrl-C twice).
  struct sigaction absorb {};
  absorb.sa_handler = [](int) {};
  absorb.sa_flags = SA_RESETHAND;
  sigemptyset(&absorb.sa_mask);
  sigaction(SIGINT, &absorb, nullptr);
  sigaction(SIGTERM, &absorb, nullptr);
  meet_at_farewell(false, -1);
  MPI_Finalize();  // frees the communicators
}

int rank() { return my_rank; }
int ranks() { return my_size; }
std::uint64_t min_over_ranks(std::uint64_t value) {
  if (my_size == 1) return value;
  MPI_Allreduce(MPI_IN_PLACE, &value, 1, MPI_UINT64_T, MPI_MIN, MPI_COMM_WORLD);
  return value;
}

std::string broadcast_from_root(std::string text) {
  if (my_size == 1) return text;
  unsigned long long size = text.size();
  MPI_Bcast(&size, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
  text.resize(static_cast<std::size_t>(size));
  MPI_Bcast(text.data(), byte_count(text.size()), MPI_BYTE, 0, MPI_COMM_WORLD);
  return text;
}

const ShiftPartition* shift_partition() { return my_size > 1 ? &rank_partition : nullptr; }

std::unique_ptr<SweepLink> open_sweep_link() {
  return my_size == 1 ? local_sweep_link() : std::make_unique<MpiSweepLink>();
}

FailureReach failure_reach() {
  if (my_size == 1) return FailureReach::every_rank;
  return meet_at_farewell(true, failure_agreement_seconds);
}

void abort_job(int code) {
  std::fflush(nullptr);
  MPI_Abort(MPI_COMM_WORLD, code);
  std::_Exit(code);  // MPI_Abort is not declared [[noreturn]]
}

}  // namespace pendavg::cli
