// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/distribute_mpi.cpp -- distribute.hpp over MPI (the build with MPI). Only the main
// thread calls MPI (MPI_THREAD_FUNNELED): the sweep engine's coordinator runs there and its
// compute threads never communicate.
#include "distribute.hpp"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdio>
#include <deque>
#include <cstdlib>
#include <list>
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
/// The shared cells (open_shared_cells), and whether this rank let them go (release_shared_cells;
/// they are freed at the farewell).
MPI_Win shared_window = MPI_WIN_NULL;
bool shared_window_released = false;
bool met_at_farewell = false;
int farewell_failed = 0, every_rank_failed = 0;  // the reduction's buffers (MPI_MIN)

/// Arrives at the end of the job (`failed`: this rank ends with a failure) and waits until
/// every rank has, or (`limit_seconds` >= 0) until that many seconds passed. Polls with short
/// sleeps: a rank waiting here (for rank 0's computation, say) leaves its core to the others.
/// Returns whether all met.
bool meet_at_farewell(bool failed, double limit_seconds) {
  if (met_at_farewell || farewell == MPI_COMM_NULL) return true;
  static MPI_Request request = MPI_REQUEST_NULL;
  if (request == MPI_REQUEST_NULL) {
    farewell_failed = failed ? 1 : 0;
    MPI_Iallreduce(&farewell_failed, &every_rank_failed, 1, MPI_INT, MPI_MIN, farewell, &request);
  }
  const double start = MPI_Wtime();
  long pause_us = 50;
  for (;;) {
    int done = 0;
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) {
      met_at_farewell = true;
      // Every rank is here, so every rank let the cells go (at the end of its sweep, or when a
      // failure left it): they are freed together.
      if (shared_window != MPI_WIN_NULL) {
        release_shared_cells();
        MPI_Win_free(&shared_window);
      }
      return true;
    }
    if (limit_seconds >= 0 && MPI_Wtime() - start > limit_seconds) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(pause_us));
    pause_us = std::min(2 * pause_us, 5000L);
  }
}

/// Started by an MPI launcher? OpenMPI's mpirun, PMIx (srun --mpi=pmix, prterun), PMI-1/2
/// (MPICH's hydra, srun --mpi=pmi2).
bool launched_by_mpi() {
  if (const char* forced = std::getenv("PENDAVG_MPI"); forced && *forced)
    return std::string_view(forced) != "0";
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(name)) return true;
  return false;
}

void check(int status, const char* what) {
  if (status != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

struct PendingSend {
  std::string payload;
  MPI_Request request = MPI_REQUEST_NULL;
};
std::list<PendingSend> pending_sends;
/// Payloads of completed sends, until sends_pending(&sent) takes them.
std::vector<std::string> sent_payloads;
constexpr std::size_t max_sent_payloads = 16;

/// Messages being received, in arrival order: a long one (a chunk's rows) goes by rendezvous
/// and needs both sides to make progress, so it is received without waiting (MPI_Imrecv) and
/// handed out only when complete, in order.
struct PendingReceive {
  Message message;
  MPI_Request request = MPI_REQUEST_NULL;
};
std::deque<PendingReceive> pending_receives;
/// Payloads given back by recycle_received, for long messages to arrive in.
std::vector<std::string> receive_pool;
std::size_t receive_pool_bytes = 0;
constexpr std::size_t receive_pool_limit = 16u << 20;
constexpr std::size_t long_message_bytes = 64u << 10;

/// A buffer for a message of `size` bytes: the smallest kept one that holds it (else the largest,
/// which grows), or a fresh one. Its bytes are left as they were (the message overwrites them).
std::string receive_buffer(std::size_t size) {
  std::string buffer;
  if (size >= long_message_bytes && !receive_pool.empty()) {
    auto best = receive_pool.end(), largest = receive_pool.begin();
    for (auto it = receive_pool.begin(); it != receive_pool.end(); ++it) {
      if (it->capacity() >= size && (best == receive_pool.end() || it->capacity() < best->capacity()))
        best = it;
      if (it->capacity() > largest->capacity()) largest = it;
    }
    const auto chosen = best != receive_pool.end() ? best : largest;
    receive_pool_bytes -= chosen->capacity();
    buffer = std::move(*chosen);
    receive_pool.erase(chosen);
  }
  buffer.resize(size);
  return buffer;
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
  if (!launched_by_mpi()) return;
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
  while (sends_pending()) {
  }
  meet_at_farewell(false, -1);
  // For tests, PENDAVG_TEST_UNRECEIVED=1: every message of the commands' protocol must have been
  // received (MPI_Finalize with one pending is erroneous); each rank names what is left for it.
  if (const char* check = std::getenv("PENDAVG_TEST_UNRECEIVED"); check && *check == '1') {
    const double start = MPI_Wtime();
    while (MPI_Wtime() - start < 0.05) {  // every rank has sent all it will: let it arrive
      int arrived = 0;
      MPI_Status status;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, world, &arrived, &status);
      if (!arrived) continue;
      std::fprintf(stderr, "pendavg: test: rank %d did not receive a message from rank %d (tag %d)\n",
                   my_rank, status.MPI_SOURCE, status.MPI_TAG);
      int size = 0;
      MPI_Get_count(&status, MPI_BYTE, &size);
      std::string bytes(static_cast<std::size_t>(size), '\0');
      MPI_Recv(bytes.data(), size, MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG, world,
               MPI_STATUS_IGNORE);
    }
  }
  MPI_Comm_free(&farewell);
  MPI_Comm_free(&world);
  MPI_Finalize();
}

int rank() { return my_rank; }
int ranks() { return my_size; }
std::string distribution_text() {
  return joined ? "MPI, " + std::to_string(my_size) + (my_size == 1 ? " rank" : " ranks")
                : "built with MPI, not started by an MPI launcher";
}

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

std::vector<std::string> gather_to_root(const std::string& local) {
  if (my_size == 1) return {local};
  const int mine = byte_count(local.size());
  std::vector<int> counts(static_cast<std::size_t>(my_size)), offsets(counts.size());
  check(MPI_Gather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, world), "MPI_Gather");
  std::string all;
  if (my_rank == 0) {
    std::size_t total = 0;
    for (std::size_t r = 0; r < counts.size(); ++r) {
      offsets[r] = byte_count(total);
      total += static_cast<std::size_t>(counts[r]);
    }
    all.resize(total);
  }
  check(MPI_Gatherv(local.data(), mine, MPI_BYTE, all.data(), counts.data(), offsets.data(),
                    MPI_BYTE, 0, world),
        "MPI_Gatherv");
  if (my_rank != 0) return {};
  std::vector<std::string> parts;
  for (std::size_t r = 0; r < counts.size(); ++r)
    parts.push_back(all.substr(static_cast<std::size_t>(offsets[r]),
                               static_cast<std::size_t>(counts[r])));
  return parts;
}

const ShiftPartition* shift_partition() { return my_size > 1 ? &rank_partition : nullptr; }

void post(int destination, int tag, std::string payload) {
  PendingSend& send = pending_sends.emplace_back();
  send.payload = std::move(payload);
  check(MPI_Isend(send.payload.data(), byte_count(send.payload.size()), MPI_BYTE, destination,
                  tag, world, &send.request),
        "MPI_Isend");
}

std::optional<Message> receive(int urgent_tag) {
  if (!joined) return std::nullopt;
  for (;;) {  // start receiving everything that has arrived
    int arrived = 0;
    MPI_Message handle;
    MPI_Status status;
    check(MPI_Improbe(MPI_ANY_SOURCE, MPI_ANY_TAG, world, &arrived, &handle, &status),
          "MPI_Improbe");
    if (!arrived) break;
    int size = 0;
    MPI_Get_count(&status, MPI_BYTE, &size);
    PendingReceive& receiving = pending_receives.emplace_back();
    receiving.message.source = status.MPI_SOURCE;
    receiving.message.tag = status.MPI_TAG;
    receiving.message.payload = receive_buffer(static_cast<std::size_t>(size));
    check(MPI_Imrecv(receiving.message.payload.data(), size, MPI_BYTE, &handle,
                     &receiving.request),
          "MPI_Imrecv");
  }
  if (pending_receives.empty()) return std::nullopt;
  if (urgent_tag >= 0) {
    for (auto it = pending_receives.begin() + 1; it != pending_receives.end(); ++it) {
      if (it->message.tag != urgent_tag) continue;
      int complete = 0;
      check(MPI_Test(&it->request, &complete, MPI_STATUS_IGNORE), "MPI_Test");
      if (!complete) continue;
      Message message = std::move(it->message);
      pending_receives.erase(it);
      return message;
    }
  }
  int done = 0;
  check(MPI_Test(&pending_receives.front().request, &done, MPI_STATUS_IGNORE), "MPI_Test");
  if (!done) return std::nullopt;
  Message message = std::move(pending_receives.front().message);
  pending_receives.pop_front();
  return message;
}

bool sends_pending(std::vector<std::string>* sent) {
  for (auto it = pending_sends.begin(); it != pending_sends.end();) {
    int done = 0;
    check(MPI_Test(&it->request, &done, MPI_STATUS_IGNORE), "MPI_Test");
    if (!done) {
      ++it;
      continue;
    }
    // Kept until a caller takes them (a few: the sweep's chunks of rows).
    if (sent_payloads.size() < max_sent_payloads) sent_payloads.push_back(std::move(it->payload));
    it = pending_sends.erase(it);
  }
  if (sent) {
    for (std::string& payload : sent_payloads) sent->push_back(std::move(payload));
    sent_payloads.clear();
  }
  return !pending_sends.empty();
}

void recycle_received(std::string&& payload) {
  if (payload.capacity() < long_message_bytes ||
      receive_pool_bytes + payload.capacity() > receive_pool_limit)
    return;
  // Kept with its old bytes: receive_buffer's resize then zeroes only what lies beyond them
  // (a cleared string is zeroed whole before each message overwrites it: 6 MB a 20,000-row
  // double sweep on 2 ranks, on rank 0's core).
  receive_pool_bytes += payload.capacity();
  receive_pool.push_back(std::move(payload));
}

bool receives_pending() { return !pending_receives.empty(); }

std::uint64_t* open_shared_cells(int count) {
  if (!joined || my_size == 1) return nullptr;
  // Every rank must agree: one node (a shared-memory communicator of all ranks) and nobody
  // asked for messages.
  MPI_Comm node = MPI_COMM_NULL;
  check(MPI_Comm_split_type(world, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node),
        "MPI_Comm_split_type");
  int node_size = 0;
  MPI_Comm_size(node, &node_size);
  MPI_Comm_free(&node);
  const char* wanted = std::getenv("PENDAVG_SWEEP_SHARED");
  std::uint64_t usable = node_size == my_size && !(wanted && std::string_view(wanted) == "0");
  if (min_over_ranks(usable) == 0) return nullptr;
  void* base = nullptr;
  if (shared_window != MPI_WIN_NULL) {  // an earlier sweep's (every rank is here: collective)
    release_shared_cells();
    MPI_Win_free(&shared_window);
  }
  shared_window_released = false;
  const MPI_Aint bytes = my_rank == 0 ? static_cast<MPI_Aint>(count) * 8 : 0;
  // An MPI without a shared-memory window (e.g. its osc/sm component missing or excluded, or
  // no room for the segment) fails here on every rank: then rank 0's messages hand out the
  // chunks instead (the errors return rather than abort the job for this one call).
  MPI_Comm_set_errhandler(world, MPI_ERRORS_RETURN);
  const int allocated =
      MPI_Win_allocate_shared(bytes, 8, MPI_INFO_NULL, world, &base, &shared_window);
  MPI_Comm_set_errhandler(world, MPI_ERRORS_ARE_FATAL);
  if (allocated != MPI_SUCCESS) shared_window = MPI_WIN_NULL;
  if (min_over_ranks(allocated == MPI_SUCCESS) == 0) {
    // A window that exists on some ranks only cannot be freed (collective over ranks that do
    // not have it): those ranks leave it to MPI_Finalize.
    shared_window = MPI_WIN_NULL;
    return nullptr;
  }
  // The cells are read and written with the CPU's atomic instructions: that needs the unified
  // memory model (public and private copies are the same memory), as every rank must agree.
  int* model = nullptr;
  int has_model = 0;
  MPI_Win_get_attr(shared_window, MPI_WIN_MODEL, &model, &has_model);
  const std::uint64_t unified = has_model && model && *model == MPI_WIN_UNIFIED;
  if (min_over_ranks(unified) == 0) {
    MPI_Win_free(&shared_window);
    shared_window = MPI_WIN_NULL;
    return nullptr;
  }
  MPI_Aint size = 0;
  int unit = 0;
  check(MPI_Win_shared_query(shared_window, 0, &size, &unit, &base), "MPI_Win_shared_query");
  auto* cells = static_cast<std::uint64_t*>(base);
  if (my_rank == 0)
    for (int i = 0; i < count; ++i) cells[i] = 0;
  // A passive-target epoch for the whole sweep (the cells are read and written with atomic
  // instructions in the unified memory model); the barrier publishes the zeros.
  check(MPI_Win_lock_all(MPI_MODE_NOCHECK, shared_window), "MPI_Win_lock_all");
  MPI_Win_sync(shared_window);
  check(MPI_Barrier(world), "MPI_Barrier");
  MPI_Win_sync(shared_window);
  return cells;
}

void release_shared_cells() {
  if (shared_window == MPI_WIN_NULL || shared_window_released) return;
  MPI_Win_unlock_all(shared_window);  // local: ends this rank's access epoch
  shared_window_released = true;
}

void exit_process(int code) {
  std::fflush(stdout);
  std::fflush(stderr);
  if (joined) {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) {
      while (sends_pending()) {
      }
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
