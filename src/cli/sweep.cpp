// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep.cpp -- the sweep engine (see sweep.hpp): a coordinator on every rank's main
// thread (rank 0's also schedules and writes), and a team of compute threads.
#include "sweep.hpp"

#include "distribute.hpp"
#include "interrupt.hpp"

#include "pendavg/chain.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <deque>
#include <exception>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <utility>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg::cli {

namespace {

using Clock = std::chrono::steady_clock;

/// A chunk's aimed cost: 20 ms, or 50 us per compute thread of the job when that is more, so
/// that rank 0 receives at most ~20,000 chunks a second (each costs it a few microseconds).
constexpr double chunk_target_seconds = 0.02;
constexpr double chunk_target_per_thread = 50e-6;
/// Rows waiting to be written: 32 MB, and 128 kB more per compute thread of the job (the rows in
/// flight grow with the threads: 160 MB at 1000).
constexpr std::size_t reorder_budget_bytes = 32u << 20;
constexpr std::size_t reorder_budget_per_thread = 128u << 10;
constexpr std::size_t max_chunk_rows = 1u << 14;
/// The smallest chunk towards the end of a sweep (from the rows' mean cost; a row at least).
constexpr double chunk_floor_seconds = 2e-4;
constexpr int chunks_per_thread = 2;                     ///< queued per compute thread
constexpr std::size_t spare_text_bytes = 8u << 20;       ///< written texts kept for reuse

// Message tags of the sweep protocol (distribute.hpp's post/receive).
enum Tag : int {
  tag_request = 101,  ///< rank -> 0: u64 chunks wanted
  tag_grant,          ///< 0 -> rank: u64 n, n x (u64 first, u64 count), u8 exhausted
  tag_result,         ///< rank -> 0: finished rows (pack_finished)
  tag_stopping,       ///< rank -> 0: this rank got SIGINT/SIGTERM
  tag_stop,           ///< 0 -> rank: start no more rows, report, then say finished
  tag_finished,       ///< rank -> 0: u8 abandoned; every result was sent before
  tag_done,           ///< 0 -> rank: the sweep is over
};

// ---------------------------------------------------------------- wire format

class Packer {
 public:
  template <class T>
  Packer& put(T value) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof value);
    return *this;
  }
  Packer& put_text(std::string_view text) {
    put<std::uint64_t>(text.size());
    bytes_.append(text);
    return *this;
  }
  std::string take() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

class Unpacker {
 public:
  explicit Unpacker(std::string_view bytes) : bytes_(bytes) {}
  template <class T>
  T get() {
    T value;
    need(sizeof value);
    std::memcpy(&value, bytes_.data() + position_, sizeof value);
    position_ += sizeof value;
    return value;
  }
  std::string_view get_text() {
    const auto size = static_cast<std::size_t>(get<std::uint64_t>());
    need(size);
    const std::string_view text(bytes_.data() + position_, size);
    position_ += size;
    return text;
  }

 private:
  void need(std::size_t size) const {
    if (bytes_.size() - position_ < size) throw std::runtime_error("sweep: truncated message");
  }
  std::string_view bytes_;
  std::size_t position_ = 0;
};

struct Range {
  std::size_t first = 0, count = 0;
};

struct RowFailure {
  std::size_t row = 0;
  bool bad_input = false;
  std::string message;
};

/// Rows first..first+count-1, finished by one thread (a chunk, or its start when the chunk was
/// cut short by a stop or a failing row).
struct Finished {
  std::size_t first = 0, count = 0;
  double seconds = 0;  ///< wall time of the chunk
  std::string text;
  std::vector<double> row_us;
  std::optional<RowFailure> failure;  ///< row first + count failed
  std::size_t failed_rows = 0;        ///< rows among these written as failed rows
  std::optional<RowFailure> first_failed;  ///< the first of them
};

/// A result message is the rows' text as it is (moved, not copied: a double sweep sends ~600
/// bytes a row), then the rest of `f`, then that rest's length (u64).
std::string pack_finished(Finished&& f) {
  Packer p;
  p.put<std::uint64_t>(f.first).put<std::uint64_t>(f.count).put<double>(f.seconds);
  p.put<std::uint8_t>(f.failure.has_value());
  if (f.failure)
    p.put<std::uint64_t>(f.failure->row).put<std::uint8_t>(f.failure->bad_input).put_text(f.failure->message);
  p.put<std::uint64_t>(f.failed_rows).put<std::uint8_t>(f.first_failed.has_value());
  if (f.first_failed) p.put<std::uint64_t>(f.first_failed->row).put_text(f.first_failed->message);
  p.put<std::uint64_t>(f.row_us.size());
  for (const double us : f.row_us) p.put<double>(us);
  const std::string rest = p.take();
  std::string bytes = std::move(f.text);
  bytes.append(rest);
  const std::uint64_t rest_size = rest.size();
  bytes.append(reinterpret_cast<const char*>(&rest_size), sizeof rest_size);
  return bytes;
}

Finished unpack_finished(std::string&& bytes) {
  std::uint64_t rest_size = 0;
  if (bytes.size() < sizeof rest_size) throw std::runtime_error("sweep: truncated message");
  std::memcpy(&rest_size, bytes.data() + bytes.size() - sizeof rest_size, sizeof rest_size);
  if (rest_size > bytes.size() - sizeof rest_size)
    throw std::runtime_error("sweep: truncated message");
  const std::size_t text_size = bytes.size() - sizeof rest_size - rest_size;
  Unpacker u(std::string_view(bytes).substr(text_size, rest_size));
  Finished f;
  f.first = u.get<std::uint64_t>();
  f.count = u.get<std::uint64_t>();
  f.seconds = u.get<double>();
  if (u.get<std::uint8_t>()) {
    RowFailure failure;
    failure.row = u.get<std::uint64_t>();
    failure.bad_input = u.get<std::uint8_t>() != 0;
    failure.message = std::string(u.get_text());
    f.failure = std::move(failure);
  }
  f.failed_rows = u.get<std::uint64_t>();
  if (u.get<std::uint8_t>()) {
    RowFailure first;
    first.row = u.get<std::uint64_t>();
    first.message = std::string(u.get_text());
    f.first_failed = std::move(first);
  }
  f.row_us.resize(u.get<std::uint64_t>());
  for (double& us : f.row_us) us = u.get<double>();
  bytes.resize(text_size);  // shortens in place
  f.text = std::move(bytes);
  return f;
}

double thread_cpu_microseconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e6 * static_cast<double>(ts.tv_sec) + 1e-3 * static_cast<double>(ts.tv_nsec);
}

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// ---------------------------------------------------------------- compute threads

/// One rank's compute threads: an OpenMP team, started from a thread of its own so that the
/// coordinator (the main thread, which alone may call MPI) stays free. Chunks go in through
/// add(); finished rows come out through take().
class ComputeTeam {
 public:
  ComputeTeam(const SweepRows& rows, int threads) : rows_(rows), threads_(threads) {
    thread_ = std::thread([this] { run(); });
  }
  ~ComputeTeam() {
    stop();
    close();
    if (!thread_.joinable()) return;
    bool running = false;
    {
      const std::lock_guard lock(mutex_);
      running = running_ > 0;
    }
    // Idle threads leave at once; threads in abandoned rows are left to the process' exit.
    if (running) thread_.detach();
    else thread_.join();
  }
  ComputeTeam(const ComputeTeam&) = delete;
  ComputeTeam& operator=(const ComputeTeam&) = delete;

  /// Queues `range` with the memory its rows will be written to, taken here (the coordinator's
  /// thread; see memory.hpp: the main thread's heap is in huge pages) from the spare texts or
  /// afresh.
  void add(Range range) {
    std::string text;
    {
      const std::lock_guard lock(mutex_);
      if (!spare_texts_.empty()) {
        spare_bytes_ -= spare_texts_.back().capacity();
        text = std::move(spare_texts_.back());
        spare_texts_.pop_back();
      }
    }
    text.reserve(std::min(range.count * rows_.row_bytes, reorder_budget_bytes));
    {
      const std::lock_guard lock(mutex_);
      queue_.push_back(Queued{range, std::move(text)});
    }
    work_.notify_one();
  }
  /// No more chunks: the threads leave once the queue is empty.
  void close() {
    {
      const std::lock_guard lock(mutex_);
      closed_ = true;
    }
    work_.notify_all();
  }
  /// Start no more rows (running rows finish).
  void stop() {
    stopping_.store(true);
    {
      const std::lock_guard lock(mutex_);
      queue_.clear();
    }
    work_.notify_all();
  }
  /// Chunks wanted to keep every thread busy with some in reserve.
  std::size_t wanted() const {
    const std::lock_guard lock(mutex_);
    const std::size_t target = static_cast<std::size_t>(chunks_per_thread * threads_);
    const std::size_t have = queue_.size() + static_cast<std::size_t>(running_);
    return have < target ? target - have : 0;
  }
  /// No row is running and none will start (queue empty, or stopping).
  bool idle() const {
    const std::lock_guard lock(mutex_);
    return running_ == 0 && (queue_.empty() || stopping_.load());
  }
  std::vector<Finished> take() {
    const std::lock_guard lock(mutex_);
    return std::exchange(results_, {});
  }
  /// A written chunk's text, kept for a later chunk's rows (fresh memory costs page faults);
  /// at most 2 per queued chunk and spare_text_bytes in all.
  /// Returns false (and leaves `text` as it was) when the team keeps enough already.
  bool recycle(std::string& text) {
    const std::lock_guard lock(mutex_);
    if (spare_texts_.size() >= static_cast<std::size_t>(2 * chunks_per_thread * threads_) ||
        spare_bytes_ + text.capacity() > spare_text_bytes)
      return false;
    text.clear();
    spare_bytes_ += text.capacity();
    spare_texts_.push_back(std::move(text));
    return true;
  }
  /// Waits until a result is ready or `timeout` passed; a zero `timeout` only yields the core.
  void wait(std::chrono::microseconds timeout) {
    if (timeout.count() == 0) {
      std::this_thread::yield();
      return;
    }
    std::unique_lock lock(mutex_);
    done_.wait_for(lock, timeout, [&] { return !results_.empty(); });
  }

 private:
  bool stopped() const {
    return stopping_.load(std::memory_order_relaxed) || stop_flag().load(std::memory_order_relaxed);
  }

  void run() {
#if defined(_OPENMP)
#pragma omp parallel num_threads(threads_)
#endif
    {
#if defined(_OPENMP)
      const int thread = omp_get_thread_num();
#else
      const int thread = 0;
#endif
      for (;;) {
        Range range;
        Finished done;
        {
          std::unique_lock lock(mutex_);
          work_.wait(lock, [&] { return stopping_.load() || closed_ || !queue_.empty(); });
          if (stopping_.load() || queue_.empty()) break;
          range = queue_.front().range;
          done.text = std::move(queue_.front().text);
          queue_.pop_front();
          ++running_;
        }
        done.first = range.first;
        const Clock::time_point start = Clock::now();
        for (std::size_t i = range.first; i < range.first + range.count; ++i) {
          if (stopped()) break;
          const std::size_t text_before = done.text.size();
          std::optional<RowFailure> failure;
          try {
            inject_row_fault(i);
            if (rows_.timing) {
              const double begin = thread_cpu_microseconds();
              rows_.compute(i, thread, done.text);
              done.row_us.push_back(thread_cpu_microseconds() - begin);
            } else {
              rows_.compute(i, thread, done.text);
            }
          } catch (const invalid_input& bad) {
            failure = RowFailure{i, true, bad.what()};
          } catch (const std::exception& error) {
            failure = RowFailure{i, false, error.what()};
          } catch (...) {
            failure = RowFailure{i, false, "unknown exception"};
          }
          if (failure && rows_.failed_row) {
            // Recorded in its place (whatever the row wrote before it threw is dropped), and
            // the sweep goes on.
            done.text.resize(text_before);
            done.text += rows_.failed_row(i, failure->message);
            if (rows_.timing) done.row_us.push_back(-std::numeric_limits<double>::infinity());
            if (!done.first_failed) done.first_failed = std::move(failure);
            ++done.failed_rows;
          } else if (failure) {
            done.failure = std::move(failure);
            break;
          }
          ++done.count;
        }
        done.seconds = seconds_since(start);
        {
          const std::lock_guard lock(mutex_);
          results_.push_back(std::move(done));
          --running_;
        }
        done_.notify_all();
      }
    }
    {
      const std::lock_guard lock(mutex_);
      exited_ = true;
    }
    done_.notify_all();
  }

  const SweepRows& rows_;
  const int threads_;
  mutable std::mutex mutex_;
  std::condition_variable work_, done_;
  struct Queued {
    Range range;
    std::string text;  ///< room for the chunk's rows
  };
  std::deque<Queued> queue_;
  std::vector<Finished> results_;
  std::vector<std::string> spare_texts_;
  std::size_t spare_bytes_ = 0;
  bool closed_ = false, exited_ = false;
  std::atomic<bool> stopping_{false};
  int running_ = 0;
  std::thread thread_;
};

// ---------------------------------------------------------------- rank 0: schedule and write

/// Hands out chunks of rows in index order (see sweep.hpp: sizes and window). The next row to
/// hand out is rank 0's own counter, or a cell in rank 0's memory that every rank advances
/// (distribute.hpp: open_shared_cells): then each rank's coordinator takes its chunks itself,
/// sized from its own rows' timings, and no rank waits for rank 0 to answer a request.
class Scheduler {
 public:
  /// `kept(i)`: row i is in the output already (resumed); `shared_next`: the shared cell, or null.
  Scheduler(std::size_t count, std::size_t window, int threads,
            std::function<bool(std::size_t)> kept, std::uint64_t* shared_next = nullptr)
      : count_(count), window_(window), threads_(static_cast<std::size_t>(threads)),
        target_seconds_(std::max(chunk_target_seconds,
                                 chunk_target_per_thread * static_cast<double>(threads))),
        kept_(std::move(kept)), shared_next_(shared_next) {}

  /// The next chunk, or nothing when every row is handed out or the window is full.
  std::optional<Range> next(std::size_t first_unwritten) {
    for (;;) {
      const std::size_t claimed = load();
      std::size_t first = claimed;
      while (first < count_ && kept_(first)) ++first;
      const std::size_t limit = std::min(count_, first_unwritten + window_);
      if (first >= limit) return std::nullopt;
      const std::size_t remaining = count_ - first;
      // Until a row's cost is known: chunks of 1, 2, 4, ... rows (a probe that keeps the first
      // ranks busy while the first timings come in, without betting on a row's cost).
      std::size_t size = timed_rows_ == 0 ? probe_rows_
                         : static_cast<std::size_t>(std::max(
                               1.0, target_seconds_ * static_cast<double>(timed_rows_) /
                                        std::max(seconds_, 1e-12)));
      // Towards the end: a quarter of the remaining rows per thread, but not below ~0.2 ms of
      // rows (each chunk costs its coordinators ~20-40 us; below that the last chunks of a
      // 20,000-row double sweep were 1-row chunks, ~40 of them, 2% of its time).
      const std::size_t tail_size = std::max<std::size_t>(
          remaining / (4 * threads_),
          timed_rows_ == 0 ? 1
                           : static_cast<std::size_t>(chunk_floor_seconds *
                                                      static_cast<double>(timed_rows_) /
                                                      std::max(seconds_, 1e-12)));
      size = std::min({size, std::max<std::size_t>(1, tail_size), max_chunk_rows,
                       std::max<std::size_t>(1, window_ / (4 * threads_)), limit - first});
      for (std::size_t k = 1; k < size; ++k)
        if (kept_(first + k)) {
          size = k;
          break;
        }
      if (!advance(claimed, first + size)) continue;  // another rank took rows meanwhile
      if (timed_rows_ == 0) probe_rows_ = std::min<std::size_t>(2 * probe_rows_, max_chunk_rows);
      return Range{first, size};
    }
  }
  bool exhausted() const {
    std::size_t first = load();
    while (first < count_ && kept_(first)) ++first;
    return first >= count_;
  }
  /// No row is handed out any more, by any rank (the sweep closes).
  void stop() {
    if (shared_next_) std::atomic_ref<std::uint64_t>(*shared_next_).store(count_);
    else next_ = count_;
  }
  void record(std::size_t rows, double seconds) {
    timed_rows_ += rows;
    seconds_ += seconds;
  }

 private:
  std::size_t load() const {
    if (!shared_next_) return next_;
    return static_cast<std::size_t>(std::atomic_ref<std::uint64_t>(*shared_next_).load());
  }
  bool advance(std::size_t from, std::size_t to) {
    if (!shared_next_) {
      next_ = to;
      return true;
    }
    std::uint64_t expected = from;
    return std::atomic_ref<std::uint64_t>(*shared_next_).compare_exchange_strong(expected, to);
  }

  const std::size_t count_, window_, threads_;
  const double target_seconds_;
  const std::function<bool(std::size_t)> kept_;
  std::uint64_t* const shared_next_;
  std::size_t next_ = 0, timed_rows_ = 0, probe_rows_ = 1;
  double seconds_ = 0;
};

/// Rows that may wait in the reorder buffer (see sweep.hpp: window); `threads`: of the job.
/// Rank 0 decides it (the other ranks learn it from rank 0). PENDAVG_SWEEP_WINDOW_ROWS=K, for
/// tests, makes it K rows (at least 1).
std::size_t reorder_window(const SweepRows& rows, int threads) {
  if (const char* forced = std::getenv("PENDAVG_SWEEP_WINDOW_ROWS"); forced && *forced)
    return std::max<std::size_t>(1, std::strtoull(forced, nullptr, 10));
  const auto total_threads = static_cast<std::size_t>(threads);
  return std::max({(reorder_budget_bytes + reorder_budget_per_thread * total_threads) /
                       std::max<std::size_t>(rows.row_bytes, 1),
                   16 * total_threads, std::size_t(64)});
}

/// The cells of a one-node job (distribute.hpp: open_shared_cells), each on a cache line of its
/// own (the index counts 8-byte cells): the next row to hand out (every rank advances it), the
/// first row not yet written (rank 0 moves it; the window starts there), how the sweep closed
/// (Closed), and the window in rows (rank 0's, set before any chunk).
enum SharedCell : int { cell_next = 0, cell_unwritten = 8, cell_closed = 16, cell_window = 24,
                        cell_count = 32 };
/// The value of cell_closed. Rank 0 and a rank that got a signal each claim the close with a
/// compare-and-swap from `not_closed`, so that a complete sweep's quiet end (nothing to stop, nothing
/// said back) and a signal exclude each other: every message sent to rank 0 is received.
enum Closed : std::uint64_t {
  not_closed = 0,
  closed_stopping = 1,  ///< rank 0 closed the sweep (signal or failure): stop, say finished
  closed_complete = 2,  ///< rank 0 wrote every row: nothing to stop; wait for tag_done
  closed_by_signal = 3  ///< a rank got SIGINT/SIGTERM; its tag_stopping is on its way
};
std::atomic_ref<std::uint64_t> shared_cell(std::uint64_t* cells, SharedCell cell) {
  static_assert(std::atomic_ref<std::uint64_t>::is_always_lock_free,
                "the cells are shared between processes: their atomics must not take a lock");
  return std::atomic_ref<std::uint64_t>(cells[cell]);
}

/// Kept rows as bits (row i: bit i % 8 of byte i / 8), for the ranks that take their own chunks.
bool kept_bit(const std::string& bits, std::size_t i) {
  return !bits.empty() && ((static_cast<unsigned char>(bits[i / 8]) >> (i % 8)) & 1u) != 0;
}

/// Rank 0's reorder buffer: rows go to the output in index order.
class OrderedWriter {
 public:
  /// `recycle` gets every written chunk's text.
  OrderedWriter(SweepOutput& output, std::size_t count,
                std::function<void(std::string&&)> recycle)
      : output_(output), count_(count), recycle_(std::move(recycle)) {}
  void add(Finished&& rows) {
    if (rows.count > 0) waiting_.emplace(rows.first, std::move(rows));
  }
  /// Writes every row that is next in order.
  void advance() {
    while (position_ < count_) {
      if (output_.kept(position_)) {
        output_.write_kept(position_++);
        ++written_;
        continue;
      }
      const auto it = waiting_.begin();
      if (it == waiting_.end() || it->first != position_) return;
      Finished& rows = it->second;
      output_.write_rows(rows.first, rows.count, rows.text, rows.row_us);
      position_ += rows.count;
      written_ += rows.count;
      recycle_(std::move(rows.text));
      waiting_.erase(it);
    }
  }
  /// After an interruption: every row there is, in order, past the missing ones.
  void drain() {
    for (;;) {
      advance();
      if (position_ >= count_) return;
      const std::size_t next_waiting = waiting_.empty() ? count_ : waiting_.begin()->first;
      ++position_;
      while (position_ < next_waiting && !output_.kept(position_)) ++position_;
    }
  }
  std::size_t position() const { return position_; }
  std::size_t written() const { return written_; }
  bool complete() const { return position_ >= count_; }

 private:
  SweepOutput& output_;
  const std::size_t count_;
  std::function<void(std::string&&)> recycle_;
  std::size_t position_ = 0, written_ = 0;
  std::map<std::size_t, Finished> waiting_;
};

/// "[name] k/count unit" on stderr every 2 s once the sweep has run 2 s, and at the end.
class Progress {
 public:
  Progress(const SweepRows& rows) : name_(rows.progress), unit_(rows.unit), count_(rows.count) {}
  void report(std::size_t done, bool last = false) {
    if (name_.empty()) return;
    const double elapsed = seconds_since(start_);
    if ((elapsed >= 2 && elapsed - last_ >= 2) || (last && reported_)) {
      std::fprintf(stderr, "[%s] %zu/%zu %s\n", name_.c_str(), done, count_, unit_.c_str());
      last_ = elapsed;
      reported_ = true;
    }
  }

 private:
  std::string name_, unit_;
  std::size_t count_;
  Clock::time_point start_ = Clock::now();
  double last_ = 0;
  bool reported_ = false;
};

/// Poll interval of a coordinator that talks to other ranks: 0.25 ms while messages come, up to
/// 1 ms (rank 0, when it answers requests) or 4 ms (the others, unless their threads wait for
/// work; rank 0 when the ranks take chunks from shared cells, as it then answers nothing) while
/// nothing happens, so that a coordinator costs little CPU beside the compute threads
/// of its core (the ~40 ms of work queued per thread hide the latency); 50 us while a long
/// message is arriving (the receiver copies it: see distribute.hpp). A rank whose long result
/// is on its way out needs no fast polls: waking every 50 us made its compute thread ~20%
/// slower per row (a 2-rank double sweep).
/// At the ends of a sweep (no row left to start on this rank, or closing) with its own threads
/// idle the core is free: for the first spin_seconds of that the coordinator polls without
/// sleeping (yielding the core at each turn, for other ranks that share it), then every 50 us.
/// There every poll of the closing counts: a sleep of 50 us lets an idle core halt, and took
/// 140 us on this machine's VM (the kernel's 50 us timer slack, then ~40 us to wake the vCPU),
/// at each step. Idle threads in mid-sweep (a full window, a grant awaited) are polled every
/// 50 us: their rows are elsewhere, maybe on this core.
class PollInterval {
 public:
  static constexpr double spin_seconds = 0.02;
  /// `alone`: no other rank; `longest`: the longest interval (us).
  PollInterval(bool alone, long longest) : alone_(alone), longest_(longest) {}
  /// `active`: something happened, or an answer is awaited by a thread without work; `idle`: this
  /// rank's compute threads have nothing to do; `ending`: no row is left to start here, or the
  /// sweep is closing. Zero: look again at once.
  std::chrono::microseconds next(bool active, bool idle, bool ending) {
    if (alone_) return std::chrono::microseconds(50000);  // only results and signals to see
    if (!(idle && ending)) {
      was_idle_ = false;
    } else {
      const Clock::time_point now = Clock::now();
      if (!was_idle_) idle_since_ = now;
      was_idle_ = true;
      if (now - idle_since_ < std::chrono::duration<double>(spin_seconds))
        return std::chrono::microseconds(0);
    }
    // A long message arriving moves while the receiver calls MPI: poll at 50 us until it is in.
    if (receives_pending() || idle) return std::chrono::microseconds(50);
    current_ = active ? 250 : std::min(longest_, current_ * 2);
    return std::chrono::microseconds(current_);
  }

 private:
  bool alone_;
  long longest_, current_ = 250;
  bool was_idle_ = false;
  Clock::time_point idle_since_{};  ///< since when the threads are idle at an end (was_idle_)
};

struct Peer {
  std::size_t wanted = 0;
  bool told_exhausted = false, finished = false, abandoned = false;
  std::size_t rows = 0, chunks = 0;  ///< computed by this rank (the work distribution)
  double seconds = 0;                ///< wall time of its chunks, summed over its threads
};

/// PENDAVG_SWEEP_REPORT=1: one line on stderr after a sweep (rank 0) with its wall time, the
/// coordinator's CPU time and message count, and each rank's rows and busy time -- what
/// tests/bench/mpi_scaling.sh reads.
void report_distribution(const SweepOutcome& outcome, const std::vector<Peer>& peers,
                         std::size_t messages, double coordinator_cpu_seconds, bool shared) {
  const char* wanted = std::getenv("PENDAVG_SWEEP_REPORT");
  if (!wanted || std::string_view(wanted) != "1") return;
  std::string ranks_text;
  for (std::size_t r = 0; r < peers.size(); ++r) {
    if (r > 0) ranks_text += ' ';
    ranks_text += std::to_string(peers[r].rows);
    ranks_text += '/';
    ranks_text += std::to_string(peers[r].chunks);
    ranks_text += '/';
    ranks_text += std::to_string(peers[r].seconds);
  }
  std::fprintf(stderr,
               "pendavg: sweep: rows=%zu computed=%zu ranks=%zu threads=%d seconds=%.6f "
               "coordinator_cpu_seconds=%.6f messages=%zu chunks_from=%s "
               "per_rank(rows/chunks/busy_s)=%s\n",
               outcome.count, outcome.computed, peers.size(), outcome.threads, outcome.seconds,
               coordinator_cpu_seconds, messages, shared ? "shared_memory" : "rank_0",
               ranks_text.c_str());
}

double thread_cpu_seconds() { return 1e-6 * thread_cpu_microseconds(); }

/// Rank 0's side of one sweep: its main thread schedules chunks (to its own compute team and to
/// the other ranks), receives the finished rows and writes them in order; run() loops over
/// these steps until every row is written, or a signal or a failing row closes the sweep.
class RootSweep {
 public:
  /// `cells`: the shared cells of a one-node job (SharedCell), or null.
  RootSweep(const SweepRows& rows, SweepOutput& output, std::uint64_t* cells)
      : rows_(rows), output_(output), size_(ranks()), cells_(cells),
        scheduler_(rows.count, reorder_window(rows, rows.threads * size_), rows.threads * size_,
                   [&output](std::size_t i) { return output.kept(i); },
                   cells ? &cells[cell_next] : nullptr),
        // written texts serve this rank's later chunks, then the other ranks' next results
        writer_(output, rows.count,
                [this](std::string&& text) {
                  if (!team_.recycle(text)) recycle_received(std::move(text));
                }),
        // with shared cells nobody waits for rank 0's answers: up to 4 ms between polls, as the
        // other ranks (fewer wake-ups on a core that also computes: 77-digit sweep -4%)
        progress_(rows), poll_(size_ == 1, cells ? 4000 : 1000),
        peers_(static_cast<std::size_t>(size_)), team_(rows, rows.threads) {
    outcome_.count = rows.count;
    outcome_.threads = rows.threads * size_;
  }

  SweepOutcome run(const std::function<void(const SweepOutcome&)>& finish) {
    for (;;) {
      bool active = collect();
      if (!closing_ && stop_flag().load()) {
        outcome_.interrupted = true;
        close(rows_.grace_seconds);
      }
      if (!closing_ && failure_) close(rows_.grace_seconds);
      if (!closing_) active = hand_out() || active;
      write_ready();
      progress_.report(outcome_.computed + output_.kept_count());
      if (!closing_ && writer_.complete()) close(0);
      if (closing_ && closed()) break;
      sends_pending();
      // With nothing of its own to compute (the last rows are elsewhere, or closing) the core
      // is free: notice the last results and the peers' goodbyes at once.
      const bool idle = team_.idle();
      team_.wait(poll_.next((active && !cells_) || closing_ || idle, idle,
                            closing_ || scheduler_.exhausted()));
    }
    release_peers();
    release_shared_cells();  // freed at the job's end (distribute.hpp)
    return conclude(finish);
  }

 private:
  /// Finished rows from rank `source` (0: this rank's team) go to the writer.
  void accept(Finished&& rows_done, int source) {
    Peer& from = peers_[static_cast<std::size_t>(source)];
    from.rows += rows_done.count;
    from.chunks += 1;
    from.seconds += rows_done.seconds;
    outcome_.computed += rows_done.count;
    scheduler_.record(rows_done.count + (rows_done.failure ? 1 : 0), rows_done.seconds);
    if (rows_done.failure && (!failure_ || rows_done.failure->row < failure_->row))
      failure_ = rows_done.failure;
    outcome_.failed_rows += rows_done.failed_rows;
    if (rows_done.first_failed &&
        (!first_failed_ || rows_done.first_failed->row < first_failed_->row))
      first_failed_ = std::move(rows_done.first_failed);
    writer_.add(std::move(rows_done));
  }

  /// The end: complete, interrupted or failed. No more rows start anywhere; running rows get
  /// `grace` seconds.
  void close(double grace) {
    if (closing_) return;
    closing_ = true;
    team_.stop();
    scheduler_.stop();  // other ranks that take their own chunks take no more
    deadline_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                   std::chrono::duration<double>(grace));
    // Every row written, and the other ranks took their chunks from the cells: each of them has
    // sent all it computed and has no row left, so it needs no stop and says nothing more (it
    // ends at tag_done) -- unless one of them claimed the close for a signal first. Otherwise
    // the others stop (and start no rows: the cell says so) and say when they have finished.
    bool quiet_end = false;
    if (cells_) {
      std::atomic_ref<std::uint64_t> closed = shared_cell(cells_, cell_closed);
      std::uint64_t expected = not_closed;
      quiet_end = writer_.complete() && !failure_ && !outcome_.interrupted &&
                  closed.compare_exchange_strong(expected, closed_complete);
      if (!quiet_end) closed.store(closed_stopping);
    }
    for (int r = 1; r < size_; ++r) {
      if (quiet_end) peers_[static_cast<std::size_t>(r)].finished = true;
      else post(r, tag_stop, {});
    }
  }

  /// This rank's finished rows and every message from the other ranks; true when anything came.
  bool collect() {
    bool active = false;
    for (Finished& f : team_.take()) {
      accept(std::move(f), 0);
      active = true;
    }
    // Requests go ahead of long results still arriving (the grant is on its way sooner).
    while (std::optional<Message> message = receive(tag_request)) {
      active = true;
      ++messages_;
      Peer& peer = peers_[static_cast<std::size_t>(message->source)];
      switch (message->tag) {
        case tag_request: peer.wanted += Unpacker(message->payload).get<std::uint64_t>(); break;
        case tag_result:
          accept(unpack_finished(std::move(message->payload)), message->source);
          break;
        case tag_stopping:
          outcome_.interrupted = true;
          close(rows_.grace_seconds);
          break;
        case tag_finished:
          peer.finished = true;
          peer.abandoned = Unpacker(message->payload).get<std::uint8_t>() != 0;
          break;
        default: break;
      }
    }
    return active;
  }

  /// Chunks to this rank's team and to every rank that asked (or must learn that the rows are
  /// exhausted); true when any went out.
  bool hand_out() {
    bool active = false;
    for (std::size_t k = team_.wanted(); k > 0; --k) {
      const std::optional<Range> chunk = scheduler_.next(writer_.position());
      if (!chunk) break;
      team_.add(*chunk);
      active = true;
    }
    // With shared cells the other ranks take their chunks themselves.
    for (int r = 1; r < size_ && !cells_; ++r) {
      Peer& peer = peers_[static_cast<std::size_t>(r)];
      if (peer.wanted == 0 && !(scheduler_.exhausted() && !peer.told_exhausted)) continue;
      std::vector<Range> chunks;
      for (; peer.wanted > 0; --peer.wanted) {
        const std::optional<Range> chunk = scheduler_.next(writer_.position());
        if (!chunk) break;
        chunks.push_back(*chunk);
      }
      const bool exhausted = scheduler_.exhausted();
      if (chunks.empty() && !(exhausted && !peer.told_exhausted)) continue;
      Packer grant;
      grant.put<std::uint64_t>(chunks.size());
      for (const Range& chunk : chunks)
        grant.put<std::uint64_t>(chunk.first).put<std::uint64_t>(chunk.count);
      grant.put<std::uint8_t>(exhausted);
      peer.told_exhausted = exhausted;
      if (exhausted) peer.wanted = 0;
      post(r, tag_grant, grant.take());
      active = true;
    }
    if (scheduler_.exhausted()) team_.close();
    return active;
  }

  /// Writes every row that is next in order; an output that cannot be written fails the sweep.
  void write_ready() {
    try {
      writer_.advance();
      if (cells_ && writer_.position() != published_)
        shared_cell(cells_, cell_unwritten).store(published_ = writer_.position());
    } catch (const invalid_input& bad) {  // e.g. the output file cannot be written
      if (!failure_) failure_ = RowFailure{rows_.count, true, bad.what()};
    } catch (const std::exception& error) {
      if (!failure_) failure_ = RowFailure{rows_.count, false, error.what()};
    }
  }

  /// While closing: true once every other rank finished and this rank's rows ended (or their
  /// grace ran out); takes this rank's last rows.
  bool closed() {
    const bool peers_finished =
        std::all_of(peers_.begin() + 1, peers_.end(), [](const Peer& p) { return p.finished; });
    if (!peers_finished || !(team_.idle() || Clock::now() >= deadline_)) return false;
    for (Finished& f : team_.take()) accept(std::move(f), 0);
    return true;
  }

  /// Tells every other rank that the sweep is over and waits until the messages are out.
  void release_peers() {
    for (int r = 1; r < size_; ++r) post(r, tag_done, {});
    while (sends_pending()) std::this_thread::sleep_for(std::chrono::microseconds(50));
  }

  /// Writes what is left (after an interruption: every row there is, past the missing ones),
  /// fills the outcome and lets `finish` complete the output. When rows had to be abandoned the
  /// process ends here.
  SweepOutcome conclude(const std::function<void(const SweepOutcome&)>& finish) {
    const bool abandoned = !team_.idle() || std::any_of(peers_.begin(), peers_.end(),
                                                        [](const Peer& p) { return p.abandoned; });
    if (!failure_) {
      try {
        if (outcome_.interrupted) writer_.drain();
        else writer_.advance();
      } catch (const invalid_input& bad) {
        failure_ = RowFailure{rows_.count, true, bad.what()};
      } catch (const std::exception& error) {
        failure_ = RowFailure{rows_.count, false, error.what()};
      }
    }
    outcome_.written = writer_.written();
    outcome_.seconds = seconds_since(start_);
    if (failure_) {
      outcome_.failed = true;
      outcome_.failed_row = failure_->row;
      outcome_.failure = failure_->message;
      outcome_.bad_input = failure_->bad_input;
    }
    if (first_failed_) {
      outcome_.first_failed_row = first_failed_->row;
      outcome_.first_failed_reason = first_failed_->message;
    }
    progress_.report(outcome_.computed + output_.kept_count(), true);
    report_distribution(outcome_, peers_, messages_, thread_cpu_seconds() - start_cpu_,
                        cells_ != nullptr);
    if (!abandoned) {
      finish(outcome_);
      return outcome_;
    }
    // Rows are still running: complete the output, then end the process (their threads use what
    // the caller's stack holds).
    int code = 0;
    try {
      finish(outcome_);
    } catch (...) {
      code = report_failure(std::current_exception());
    }
    exit_process(code);
  }

  const Clock::time_point start_ = Clock::now();
  const double start_cpu_ = thread_cpu_seconds();
  const SweepRows& rows_;
  SweepOutput& output_;
  const int size_;
  std::uint64_t* const cells_;
  std::size_t published_ = 0;  ///< the first unwritten row as the cells last said
  SweepOutcome outcome_;
  Scheduler scheduler_;
  OrderedWriter writer_;
  Progress progress_;
  PollInterval poll_;
  std::vector<Peer> peers_;
  std::optional<RowFailure> failure_;
  std::optional<RowFailure> first_failed_;  ///< the first row written as a failed row
  bool closing_ = false;
  Clock::time_point deadline_{};
  std::size_t messages_ = 0;
  ComputeTeam team_;  // last: its threads stop (destructor) before the state above goes
};

/// A rank other than 0. `cells`: the shared cells (it takes its own chunks), or null (it asks
/// rank 0 for them); `kept`: the rows kept from a resumed file, as bits (empty: none).
SweepOutcome run_worker(const SweepRows& rows, std::uint64_t* cells, const std::string& kept) {
  SweepOutcome outcome;
  outcome.count = rows.count;
  outcome.threads = rows.threads * ranks();
  ComputeTeam team(rows, rows.threads);
  PollInterval poll(false, 4000);
  Scheduler scheduler(
      rows.count,
      cells ? static_cast<std::size_t>(shared_cell(cells, cell_window).load())
            : reorder_window(rows, rows.threads * ranks()),
      rows.threads * ranks(), [&kept](std::size_t i) { return kept_bit(kept, i); },
      cells ? &cells[cell_next] : nullptr);
  bool requested = false, exhausted = false, stopping = false, told = false;
  bool finished_sent = false, done = false;
  std::vector<std::string> sent;
  Clock::time_point deadline{};
  const auto stop = [&](double grace) {
    if (stopping) return;
    stopping = true;
    team.stop();
    deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>(grace));
  };
  while (!done) {
    bool active = false;
    // Grants first: a request for more then goes out ahead of the rows just finished.
    while (std::optional<Message> message = receive()) {
      active = true;
      if (message->tag == tag_grant) {
        Unpacker grant(message->payload);
        const auto n = grant.get<std::uint64_t>();
        for (std::uint64_t k = 0; k < n; ++k) {
          Range range;
          range.first = grant.get<std::uint64_t>();
          range.count = grant.get<std::uint64_t>();
          if (!stopping) team.add(range);
        }
        exhausted = exhausted || grant.get<std::uint8_t>() != 0;
        requested = false;
      } else if (message->tag == tag_stop) {
        stop(rows.grace_seconds);
      } else if (message->tag == tag_done) {
        done = true;
      }
    }
    for (Finished& f : team.take()) {
      outcome.computed += f.count;
      scheduler.record(f.count + (f.failure ? 1 : 0), f.seconds);
      // A request for more goes ahead of the rows: a short message rank 0 answers at once, where
      // a long one arrives only when all of it is through.
      if (!cells && !stopping && !exhausted && !requested) {
        if (const std::size_t wanted = team.wanted(); wanted > 0) {
          post(0, tag_request, Packer().put<std::uint64_t>(wanted).take());
          requested = true;
        }
      }
      post(0, tag_result, pack_finished(std::move(f)));
      active = true;
    }
    if (!told && !finished_sent && stop_flag().load()) {
      told = true;
      // With the cells the signal claims the close, unless rank 0 closed a complete sweep
      // first: then nothing runs here any more and nothing is said (rank 0 listens no more).
      std::uint64_t closed = not_closed;
      if (!cells || shared_cell(cells, cell_closed).compare_exchange_strong(closed, closed_by_signal) ||
          closed != closed_complete) {
        post(0, tag_stopping, {});
        stop(rows.grace_seconds);
      }
    }
    if (!stopping && cells) {
      const std::uint64_t closed = shared_cell(cells, cell_closed).load();
      if (closed == closed_stopping || closed == closed_by_signal)
        stop(rows.grace_seconds);  // rank 0's tag_stop follows
    }
    if (!stopping && cells) {  // take chunks from the shared cells
      exhausted = exhausted || scheduler.exhausted();
      if (exhausted) team.close();
      for (std::size_t k = exhausted ? 0 : team.wanted(); k > 0; --k) {
        const std::size_t unwritten = shared_cell(cells, cell_unwritten).load();
        const std::optional<Range> chunk = scheduler.next(unwritten);
        if (!chunk) break;
        team.add(*chunk);
        active = true;
      }
      // Threads without work wait for the window to move: look again soon.
      requested = !exhausted && team.wanted() > 0;
    } else if (!stopping) {
      if (exhausted) {
        team.close();
      } else if (!requested) {
        if (const std::size_t wanted = team.wanted(); wanted > 0) {
          post(0, tag_request, Packer().put<std::uint64_t>(wanted).take());
          requested = true;
        }
      }
    }
    if (stopping && !finished_sent && (team.idle() || Clock::now() >= deadline)) {
      for (Finished& f : team.take()) {
        outcome.computed += f.count;
        post(0, tag_result, pack_finished(std::move(f)));
      }
      post(0, tag_finished, Packer().put<std::uint8_t>(!team.idle()).take());
      finished_sent = true;
    }
    // The sent rows' memory serves later chunks (fresh memory costs a page fault every 4 kB).
    sent.clear();
    sends_pending(&sent);
    for (std::string& bytes : sent) team.recycle(bytes);
    // Waiting with idle threads (for a grant, or for the end once the rows are exhausted)
    // counts as active: the answer is noticed at once, and no computation is disturbed; so does
    // a thread without work (with the cells: the window is full). With the cells nothing else
    // needs a quick look (the threads wake this loop when a chunk is done, and rank 0 has no
    // answer to give): up to 4 ms between polls, as rank 0's. Each poll disturbs the compute
    // thread of this core: polls at 0.25-1 ms after every chunk made rank 1's rows ~5% slower
    // than alone (a 2-rank double sweep, thread CPU time per row).
    if (!done)
      team.wait(poll.next((active && !cells) || (cells && requested) ||
                              (team.idle() && (requested || exhausted || stopping)),
                          team.idle(), exhausted || stopping));
  }
  release_shared_cells();  // freed at the job's end (distribute.hpp)
  while (sends_pending()) std::this_thread::sleep_for(std::chrono::microseconds(50));
  if (!team.idle()) exit_process(0);  // abandoned rows (rank 0 reports)
  return outcome;
}

}  // namespace

// Weak: the test build's definition (tests/cli/row_faults.cpp) replaces it at link time.
[[gnu::weak]] void inject_row_fault(std::size_t) {}

SweepOutcome run_sweep(const SweepRows& rows, SweepOutput* output,
                       const std::function<void(const SweepOutcome&)>& finish) {
  // For tests, PENDAVG_TEST_FAIL_ON_RANK=K[:sweep]: a failure on rank K alone (K = all: on
  // every rank), just before the sweep's first collective step (or, with ":sweep", once the
  // sweep has begun).
  const auto fail_here = [](bool begun) {
    const char* failing = std::getenv("PENDAVG_TEST_FAIL_ON_RANK");
    if (!failing || !*failing) return;
    const std::string_view which(failing);
    if (!which.starts_with("all") && std::atoi(failing) != rank()) return;
    if (begun == (which.find(":sweep") != std::string_view::npos))
      throw std::runtime_error("a failure injected on this rank (PENDAVG_TEST_FAIL_ON_RANK)");
  };
  fail_here(false);
  // Collective: shared cells when every rank reaches rank 0's memory; then every rank needs
  // rank 0's window and the kept rows (bits; empty when there are none). The broadcast also
  // orders rank 0's store of the window before the other ranks' first look.
  std::uint64_t* const cells = open_shared_cells(cell_count);
  // The cells are let go on this rank alone (freeing them is collective, at the job's end: see
  // distribute.hpp), at the end of its sweep or when an exception leaves it (the other ranks may
  // still be sweeping, and this rank must get on to report its failure); twice does nothing.
  struct ReleaseCells {
    ~ReleaseCells() { release_shared_cells(); }
  } release_cells;
  std::string kept;
  if (cells) {
    if (is_root()) {
      shared_cell(cells, cell_window).store(reorder_window(rows, rows.threads * ranks()));
      if (output->kept_count() > 0) {
        kept.assign((rows.count + 7) / 8, '\0');
        for (std::size_t i = 0; i < rows.count; ++i)
          if (output->kept(i)) kept[i / 8] = static_cast<char>(kept[i / 8] | (1 << (i % 8)));
      }
    }
    kept = broadcast_from_root(std::move(kept));
  }
  fail_here(true);
  if (is_root()) return RootSweep(rows, *output, cells).run(finish);
  return run_worker(rows, cells, kept);
}

void rethrow_failure(const SweepOutcome& outcome,
                     const std::function<std::string(std::size_t row)>& context) {
  if (!outcome.failed) return;
  const std::string message = outcome.failed_row < outcome.count
                                  ? context(outcome.failed_row) + outcome.failure
                                  : outcome.failure;
  if (outcome.bad_input) throw invalid_input(message);
  throw std::runtime_error(message);
}

std::size_t first_failing_row(std::size_t count, int threads,
                              const std::function<void(std::size_t index, int thread)>& check,
                              const std::string& progress, const std::string& unit) {
  const auto size = static_cast<std::size_t>(ranks());
  const auto me = static_cast<std::size_t>(rank());
  const std::size_t begin = count / size * me + std::min(me, count % size);
  const std::size_t end = begin + count / size + (me < count % size ? 1 : 0);
  std::atomic<std::size_t> first{count};
  // A long check (1e8 points take minutes) says how far it is, as the sweep does: rank 0's
  // first thread prints its rank's rows checked every 2 s once it has run 2 s.
  std::atomic<std::size_t> checked{0};
  const Clock::time_point start = Clock::now();
  double last_report = 0;
  const auto report = [&] {
    const double elapsed = seconds_since(start);
    if (elapsed < 2 || elapsed - last_report < 2) return;
    last_report = elapsed;
    std::fprintf(stderr, "[%s] checking the %s: %zu/%zu%s\n", progress.c_str(), unit.c_str(),
                 checked.load(std::memory_order_relaxed), end - begin,
                 size > 1 ? " (rank 0's share)" : "");
  };
#if defined(_OPENMP)
#pragma omp parallel for num_threads(threads) schedule(dynamic, 64)
#endif
  for (std::ptrdiff_t i = static_cast<std::ptrdiff_t>(begin); i < static_cast<std::ptrdiff_t>(end);
       ++i) {
    const auto index = static_cast<std::size_t>(i);
    if (index > first.load(std::memory_order_relaxed)) continue;
    if (stop_flag().load(std::memory_order_relaxed)) continue;  // stopped: no row will run
    try {
#if defined(_OPENMP)
      check(index, omp_get_thread_num());
#else
      check(index, 0);
#endif
    } catch (...) {
      std::size_t seen = first.load();
      while (index < seen && !first.compare_exchange_weak(seen, index)) {
      }
    }
    checked.fetch_add(1, std::memory_order_relaxed);
#if defined(_OPENMP)
    const bool reporter = omp_get_thread_num() == 0;
#else
    const bool reporter = true;
#endif
    if (reporter && me == 0 && !progress.empty()) report();
  }
  (void)threads;
  return static_cast<std::size_t>(min_over_ranks(first.load()));
}

std::string utc_timestamp() {
  std::time_t now = std::time(nullptr);
  if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH"); epoch && *epoch) {
    char* end = nullptr;
    const long long seconds = std::strtoll(epoch, &end, 10);
    if (end && *end == '\0' && seconds >= 0) now = static_cast<std::time_t>(seconds);
  }
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

}  // namespace pendavg::cli
