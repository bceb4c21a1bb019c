// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute_mpi.cpp -- distribute.hpp over MPI (the build with MPI). Only the main
// thread calls MPI (MPI_THREAD_FUNNELED): the sweep engine's coordinator runs there and its
// compute threads never communicate.
#include "distribute.hpp"

#include <mpi.h>

#include <chrono>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <stdexcept>
#include <string_view>
#include <thread>

namespace pendavg::cli {

namespace {

bool joined = false;  // MPI_Init_thread was called by us
MPI_Comm world = MPI_COMM_NULL;
int my_rank = 0, my_size = 1;
/// Where the ranks meet at their end (a reduction of its own, never mixed with the commands'
/// collectives): a rank that failed learns there whether the others failed too.
MPI_Comm farewell = MPI_COMM_NULL;
/// The window of the sweep link's counters, and whether this rank let it go (it is freed at the
/// farewell, where every rank is: freeing it is collective).
MPI_Win sweep_window = MPI_WIN_NULL;
bool sweep_window_released = false;
bool met_at_farewell = false;
int farewell_failed = 0, every_rank_failed = 0;  // the reduction's buffers (MPI_MIN)

/// Arrives at the end of the job (`failed`: this rank ends with a failure) and waits until
/// every rank has, or (`limit_seconds` >= 0) until that many seconds passed. Polls every
/// millisecond: a rank waiting here (for rank 0's computation, say) leaves its core to the
/// others. Returns whether all met.
bool meet_at_farewell(bool failed, double limit_seconds) {
  if (met_at_farewell || farewell == MPI_COMM_NULL) return true;
  static MPI_Request request = MPI_REQUEST_NULL;
  if (request == MPI_REQUEST_NULL) {
    farewell_failed = failed ? 1 : 0;
    MPI_Iallreduce(&farewell_failed, &every_rank_failed, 1, MPI_INT, MPI_MIN, farewell, &request);
  }
  const double start = MPI_Wtime();
  for (;;) {
    int done = 0;
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) {
      met_at_farewell = true;
      // Every rank is here, and every rank let the sweep's window go: it is freed together.
      if (sweep_window != MPI_WIN_NULL) {
        if (!sweep_window_released) MPI_Win_unlock_all(sweep_window);
        MPI_Win_free(&sweep_window);
      }
      return true;
    }
    if (limit_seconds >= 0 && MPI_Wtime() - start > limit_seconds) return false;
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

void check(int status, const char* what) {
  if (status != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

int byte_count(std::size_t size) {
  if (size > static_cast<std::size_t>(INT_MAX))
    throw std::runtime_error("MPI: a message of " + std::to_string(size) + " bytes is too long");
  return static_cast<int>(size);
}

class RankPartition final : public ShiftPartition {
 public:
  int part() const override { return my_rank; }
  int parts() const override { return my_size; }
  std::vector<double> all_gather(std::span<const double> local) const override {
    return cli::all_gather(local);
  }
};
const RankPartition rank_partition;

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
  if (MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
    std::fprintf(stderr, "pendavg: internal error: MPI_Init_thread failed\n");
    std::exit(1);
  }
  joined = true;
  MPI_Comm_dup(MPI_COMM_WORLD, &world);
  MPI_Comm_dup(MPI_COMM_WORLD, &farewell);
  MPI_Comm_rank(world, &my_rank);
  MPI_Comm_size(world, &my_size);
  if (my_size == 1 && launched_ranks() > 1) {  // e.g. srun --mpi=none: K singletons
    std::fprintf(stderr, "pendavg: error: started as %d ranks, but MPI sees one (each rank would "
                         "run the whole command): launch with MPI support (srun --mpi=pmix)\n",
                 launched_ranks());
    std::exit(2);
  }
  if (provided < MPI_THREAD_FUNNELED && my_size > 1) {
    if (my_rank == 0)
      std::fprintf(stderr, "pendavg: internal error: the MPI library does not provide "
                           "MPI_THREAD_FUNNELED\n");
    MPI_Abort(world, 1);
  }
}

ProcessGroup::~ProcessGroup() {
  if (!joined) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (finalized) return;
  meet_at_farewell(false, -1);
  MPI_Comm_free(&farewell);
  MPI_Comm_free(&world);
  MPI_Finalize();
}

int rank() { return my_rank; }
int ranks() { return my_size; }
std::uint64_t min_over_ranks(std::uint64_t value) {
  if (my_size == 1) return value;
  std::uint64_t smallest = value;
  check(MPI_Allreduce(&value, &smallest, 1, MPI_UINT64_T, MPI_MIN, world), "MPI_Allreduce");
  return smallest;
}

std::string broadcast_from_root(std::string text) {
  if (my_size == 1) return text;
  unsigned long long size = text.size();
  check(MPI_Bcast(&size, 1, MPI_UNSIGNED_LONG_LONG, 0, world), "MPI_Bcast");
  text.resize(static_cast<std::size_t>(size));
  check(MPI_Bcast(text.data(), byte_count(text.size()), MPI_BYTE, 0, world), "MPI_Bcast");
  return text;
}

std::vector<double> all_gather(std::span<const double> local) {
  if (my_size == 1) return {local.begin(), local.end()};
  const int mine = byte_count(local.size() * sizeof(double)) / static_cast<int>(sizeof(double));
  std::vector<int> counts(static_cast<std::size_t>(my_size)), offsets(counts.size());
  check(MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, world), "MPI_Allgather");
  std::size_t total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    offsets[r] = static_cast<int>(total);
    total += static_cast<std::size_t>(counts[r]);
  }
  std::vector<double> all(total);
  check(MPI_Allgatherv(local.data(), mine, MPI_DOUBLE, all.data(), counts.data(), offsets.data(),
                       MPI_DOUBLE, world),
        "MPI_Allgatherv");
  return all;
}

const ShiftPartition* shift_partition() { return my_size > 1 ? &rank_partition : nullptr; }

namespace {

/// The counters in a window of rank 0's memory, changed by MPI_Fetch_and_op (passive target: in
/// one lock_all epoch for the whole sweep); rows go to rank 0 in messages of the sweep's own
/// communicator.
class MpiSweepLink final : public SweepLink {
 public:
  MpiSweepLink() {
    if (sweep_window != MPI_WIN_NULL) MPI_Win_free(&sweep_window);  // an earlier sweep's
    if (comm_ == MPI_COMM_NULL) check(MPI_Comm_dup(world, &comm_), "MPI_Comm_dup");
    const MPI_Aint bytes = my_rank == 0 ? 3 * sizeof(std::uint64_t) : 0;
    check(MPI_Win_allocate(bytes, sizeof(std::uint64_t), MPI_INFO_NULL, comm_, &counters_,
                           &sweep_window),
          "MPI_Win_allocate");
    sweep_window_released = false;
    if (my_rank == 0)
      for (int k = 0; k < 3; ++k) counters_[k] = 0;
    check(MPI_Barrier(comm_), "MPI_Barrier");  // the zeros are there before anyone fetches
    check(MPI_Win_lock_all(0, sweep_window), "MPI_Win_lock_all");
  }
  /// Local: the window is freed at the farewell (a rank that ends the sweep early -- abandoned
  /// rows, a failure -- must not wait there for the others).
  ~MpiSweepLink() override {
    if (sweep_window != MPI_WIN_NULL && !sweep_window_released) MPI_Win_unlock_all(sweep_window);
    sweep_window_released = true;
    // Normally none left: the last message waited for them.
    for (Outgoing& message : outgoing_) MPI_Wait(&message.request, MPI_STATUS_IGNORE);
  }
  int rank() const override { return my_rank; }
  int ranks() const override { return my_size; }
  std::uint64_t fetch(Counter counter, Op op, std::uint64_t operand) override {
    const MPI_Op mpi_op = op == Op::add      ? MPI_SUM
                          : op == Op::bit_or ? MPI_BOR
                          : op == Op::replace ? MPI_REPLACE
                                              : MPI_NO_OP;
    std::uint64_t before = 0;
    check(MPI_Fetch_and_op(&operand, &before, MPI_UINT64_T, 0, counter, mpi_op, sweep_window),
          "MPI_Fetch_and_op");
    check(MPI_Win_flush(0, sweep_window), "MPI_Win_flush");
    return before;
  }
  /// Rank 0 receives when its coordinator polls (every 2 ms): a blocking send of a long message
  /// would spin on this rank's core until then, time taken from its compute threads.
  void send(int tag, std::string payload) override {
    while (!outgoing_.empty()) {  // let go of the payloads that have gone
      int gone = 0;
      check(MPI_Test(&outgoing_.front().request, &gone, MPI_STATUS_IGNORE), "MPI_Test");
      if (!gone) break;
      outgoing_.pop_front();
    }
    Outgoing& message = outgoing_.emplace_back(Outgoing{MPI_REQUEST_NULL, std::move(payload)});
    check(MPI_Isend(message.payload.data(), byte_count(message.payload.size()), MPI_BYTE, 0, tag,
                    comm_, &message.request),
          "MPI_Isend");
    if (tag != finished) return;
    // The rank's last message: everything it sent must reach rank 0 before the process may end
    // (a rank with abandoned rows exits right after).
    for (Outgoing& sent : outgoing_) check(MPI_Wait(&sent.request, MPI_STATUS_IGNORE), "MPI_Wait");
    outgoing_.clear();
  }
  std::optional<Message> receive() override {
    int arrived = 0;
    MPI_Status status;
    check(MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, comm_, &arrived, &status), "MPI_Iprobe");
    if (!arrived) return std::nullopt;
    int size = 0;
    MPI_Get_count(&status, MPI_BYTE, &size);
    Message message;
    message.source = status.MPI_SOURCE;
    message.tag = status.MPI_TAG;
    message.payload.resize(static_cast<std::size_t>(size));
    check(MPI_Recv(message.payload.data(), size, MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG,
                   comm_, MPI_STATUS_IGNORE),
          "MPI_Recv");
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

std::unique_ptr<SweepLink> open_sweep_link() {
  if (!joined || my_size == 1) return local_sweep_link();
  return std::make_unique<MpiSweepLink>();
}

void exit_process(int code) {
  std::fflush(stdout);
  std::fflush(stderr);
  if (joined) {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) {
      meet_at_farewell(false, -1);
      MPI_Finalize();
    }
  }
  std::_Exit(code);
}

FailureReach failure_reach() {
  if (!joined || my_size == 1) return FailureReach::every_rank;
  if (!meet_at_farewell(true, failure_agreement_seconds)) return FailureReach::others_went_on;
  return every_rank_failed ? FailureReach::every_rank : FailureReach::not_every_rank;
}

void abort_job(int code) {
  std::fflush(stdout);
  std::fflush(stderr);
  if (!joined) std::_Exit(code);
  MPI_Abort(MPI_COMM_WORLD, code);
  std::_Exit(code);
}

}  // namespace pendavg::cli
