// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep.cpp -- the sweep engine (see sweep.hpp): on every rank a coordinator (the main
// thread: takes chunks, sends or writes finished rows) and a team of compute threads.
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

/// Rows waiting to be written: 32 MB, and 128 kB more per compute thread of the job (the rows in
/// flight grow with the threads: 160 MB at 1000).
constexpr std::size_t reorder_budget_bytes = 32u << 20;
constexpr std::size_t reorder_budget_per_thread = 128u << 10;
constexpr std::size_t max_chunk_rows = 1u << 14;
/// A thread's next chunk is taken when its running chunk is expected to end within this time
/// (its rows so far give the estimate): long enough to cover the coordinator's wake-up and one
/// fetch from rank 0, short enough that a chunk taken ahead cannot unbalance the ranks. (Taking
/// chunks ahead from the start made a rank hold a fifth of a sweep while another went idle.)
constexpr auto take_ahead = std::chrono::milliseconds(1);
/// How often a coordinator looks for messages and at the stop counter when nothing wakes it (a
/// finished chunk does): rank 0 receives rows, the others only watch for a stop.
constexpr std::chrono::microseconds root_poll{2000}, rank_poll{10000};
/// Rank 0's poll once its own rows are done and it only waits for the others' last rows: its
/// core is idle then, and the sweep ends as soon as they arrive.
constexpr std::chrono::microseconds root_poll_idle{100};
/// How long a running chunk keeps its finished rows (ComputeTeam::compute): 1 s, or 1 ms per
/// compute thread of the job, so that rank 0 gets at most ~1000 such handovers a second.
Clock::duration handover_period(std::size_t threads) {
  return std::chrono::duration_cast<Clock::duration>(
      std::chrono::milliseconds(std::max<std::size_t>(1000, threads)));
}
/// The stop counter's bits.
constexpr std::uint64_t stop_signal = 1, stop_row_failed = 2, stop_rank_failed = 4;

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
  std::string text;
  std::vector<double> row_us;
  /// The first row that failed: row first + count, which ended these rows (SweepRows::failed_row
  /// unset), or the first of the rows written as failed rows (set).
  std::optional<RowFailure> failure;
  std::size_t failed_rows = 0;  ///< rows among these written as failed rows
};

// ---------------------------------------------------------------- wire format

/// A rows message: the rows' text as it is (moved, not copied), the times, the failure's
/// message, then a Tail that says how long each part is (messages stay within one job: one
/// binary, one byte order).
struct Tail {
  std::uint64_t first, count, failed_rows, times;
  std::uint64_t failure_kind, failure_row, failure_length;  ///< kind: 0 none, 2 bad input
};

std::string pack_finished(Finished&& f) {
  const RowFailure failure = f.failure.value_or(RowFailure{});
  const Tail tail{f.first, f.count, f.failed_rows, f.row_us.size(),
                  f.failure ? 1u + failure.bad_input : 0u, failure.row, failure.message.size()};
  std::string bytes = std::move(f.text);
  bytes.append(reinterpret_cast<const char*>(f.row_us.data()), f.row_us.size() * sizeof(double));
  bytes += failure.message;
  return bytes.append(reinterpret_cast<const char*>(&tail), sizeof tail);
}

Finished unpack_finished(std::string&& bytes) {
  Tail tail{};
  std::size_t end = bytes.size();
  const auto take = [&](std::uint64_t size) {  // the parts, from the end
    if (size > end) throw std::runtime_error("sweep: truncated message");
    end -= static_cast<std::size_t>(size);
    return std::string_view(bytes).substr(end, static_cast<std::size_t>(size));
  };
  std::memcpy(&tail, take(sizeof tail).data(), sizeof tail);
  Finished f{tail.first, tail.count, {}, std::vector<double>(tail.times), {}, tail.failed_rows};
  if (const std::string_view message = take(tail.failure_length); tail.failure_kind != 0)
    f.failure = RowFailure{tail.failure_row, tail.failure_kind == 2, std::string(message)};
  const std::string_view times = take(tail.times * sizeof(double));
  if (!times.empty()) std::memcpy(f.row_us.data(), times.data(), times.size());
  bytes.resize(end);
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
  /// `handover`: how long a running chunk keeps its finished rows before it hands them over.
  ComputeTeam(const SweepRows& rows, int threads, Clock::duration handover)
      : rows_(rows), threads_(threads), handover_(handover) {
    thread_ = std::thread([this] { run(); });
  }
  ~ComputeTeam() {
    stop();
    close();
    // Idle threads leave at once; threads in abandoned rows are left to the process' exit.
    if (running() > 0) thread_.detach();
    else thread_.join();
  }
  ComputeTeam(const ComputeTeam&) = delete;
  ComputeTeam& operator=(const ComputeTeam&) = delete;

  void add(Range range) {
    {
      const std::lock_guard lock(mutex_);
      queue_.push_back(range);
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
  /// Chunks wanted: one for every thread that is idle or about to be (its chunk ends within
  /// take_ahead), less those queued.
  std::size_t wanted() const {
    const std::lock_guard lock(mutex_);
    const std::size_t have = queue_.size() + static_cast<std::size_t>(running_ - ending_);
    const auto target = static_cast<std::size_t>(threads_);
    return have < target ? target - have : 0;
  }
  /// No row is running and none will start (queue empty, or stopping). Every finished row is
  /// then in take()'s results.
  bool idle() const {
    const std::lock_guard lock(mutex_);
    return running_ == 0 && (queue_.empty() || stopping_.load());
  }
  /// The threads' CPU time in the rows they finished.
  double busy_seconds() const { return 1e-6 * static_cast<double>(busy_us_.load()); }
  std::vector<Finished> take() {
    const std::lock_guard lock(mutex_);
    return std::exchange(results_, {});
  }
  /// Waits until a result is ready, a thread wants its next chunk, or `timeout` passed.
  void wait(std::chrono::microseconds timeout) {
    std::unique_lock lock(mutex_);
    done_.wait_for(lock, timeout,
                   [&] { return !results_.empty() || std::exchange(asked_, false); });
  }

 private:
  int running() const {
    const std::lock_guard lock(mutex_);
    return running_;
  }
  bool stopped() const {
    return stopping_.load(std::memory_order_relaxed) || stop_flag().load(std::memory_order_relaxed);
  }

  /// Rows range.first.. until the range ends, a stop, or a row that fails (without failed_row),
  /// into results_: at the end, and every `handover_` while the chunk runs (the first chunks
  /// are long, a 1/(8T) share of the sweep each: their rows reach rank 0's file as they are
  /// finished, and a run killed outright does not lose them).
  void compute(Range range, int thread) {
    Finished done;
    done.first = range.first;
    done.text.reserve(std::min(range.count * rows_.row_bytes, reorder_budget_bytes));
    const double cpu_begun = thread_cpu_microseconds();
    const Clock::time_point begun = Clock::now();
    Clock::time_point handed = begun;
    bool ending = false;
    const std::size_t end = range.first + range.count;
    for (std::size_t i = range.first; i < end && !stopped(); ++i) {
      const auto done_rows = static_cast<long>(i - range.first), left = static_cast<long>(end - i);
      if (!ending && done_rows > 0 && (Clock::now() - begun) * left < take_ahead * done_rows) {
        ending = true;  // the rows left will take less than take_ahead at this pace
        {
          const std::lock_guard lock(mutex_);
          ++ending_;
          asked_ = true;
        }
        done_.notify_all();
      }
      const std::size_t text_before = done.text.size();
      std::optional<RowFailure> failure;
      try {
        inject_row_fault(i);
        const double begin = rows_.timing ? thread_cpu_microseconds() : 0;
        rows_.compute(i, thread, done.text);
        if (rows_.timing) done.row_us.push_back(thread_cpu_microseconds() - begin);
      } catch (const invalid_input& bad) {
        failure = RowFailure{i, true, bad.what()};
      } catch (const std::exception& error) {
        failure = RowFailure{i, false, error.what()};
      } catch (...) {
        failure = RowFailure{i, false, "unknown exception"};
      }
      if (failure && !rows_.failed_row) {
        done.failure = std::move(failure);
        break;
      }
      if (failure) {
        // Recorded in its place (whatever the row wrote before it threw is dropped), and the
        // sweep goes on.
        done.text.resize(text_before);
        done.text += rows_.failed_row(i, failure->message);
        if (rows_.timing) done.row_us.push_back(-std::numeric_limits<double>::infinity());
        if (!done.failure) done.failure = std::move(failure);
        ++done.failed_rows;
      }
      ++done.count;
      if (i + 1 < end && Clock::now() - handed >= handover_) {
        deliver(std::exchange(done, Finished{}), false);
        done.first = i + 1;
        handed = Clock::now();
      }
    }
    busy_us_.fetch_add(static_cast<std::uint64_t>(thread_cpu_microseconds() - cpu_begun));
    deliver(std::move(done), true, ending);
  }

  void deliver(Finished&& done, bool last, bool ending = false) {
    {
      const std::lock_guard lock(mutex_);
      results_.push_back(std::move(done));
      if (last) --running_;
      if (ending) --ending_;
    }
    done_.notify_all();
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
        {
          std::unique_lock lock(mutex_);
          work_.wait(lock, [&] { return stopping_.load() || closed_ || !queue_.empty(); });
          if (stopping_.load() || queue_.empty()) break;
          range = queue_.front();
          queue_.pop_front();
          ++running_;
        }
        compute(range, thread);
      }
    }
  }

  const SweepRows& rows_;
  const int threads_;
  const Clock::duration handover_;
  mutable std::mutex mutex_;
  std::condition_variable work_, done_;
  std::deque<Range> queue_;
  std::vector<Finished> results_;
  bool closed_ = false, asked_ = false;
  std::atomic<bool> stopping_{false};
  std::atomic<std::uint64_t> busy_us_{0};
  int running_ = 0, ending_ = 0;  ///< chunks running; those of them about to end
  std::thread thread_;
};

// ---------------------------------------------------------------- rank 0: order and write

/// Rows that may wait in the reorder buffer (see sweep.hpp: window); `threads`: of the job.
std::size_t reorder_window(const SweepRows& rows, std::size_t threads) {
  if (const std::size_t forced = test_window_rows(); forced > 0) return forced;
  return std::max({(reorder_budget_bytes + reorder_budget_per_thread * threads) /
                       std::max<std::size_t>(rows.row_bytes, 1),
                   16 * threads, std::size_t(64)});
}

bool kept_bit(const std::string& bits, std::size_t i) {
  return !bits.empty() && ((static_cast<unsigned char>(bits[i / 8]) >> (i % 8)) & 1u) != 0;
}

/// Rank 0's reorder buffer: rows go to the output in index order.
class OrderedWriter {
 public:
  OrderedWriter(SweepOutput& output, std::size_t count) : output_(output), count_(count) {}
  void add(Finished&& rows) {
    if (rows.count == 0) return;
    waiting_.emplace(rows.first, std::move(rows));
    ahead_changed_ = true;
  }
  /// Writes every row that is next in order, and lets them out of the output's buffer; the rows
  /// that still wait are copied out (keep_ahead) when they changed and the last copy is old.
  void advance() {
    write_next();
    output_.flush();
    keep_ahead();
  }
  /// After an interruption: every row there is, in order, past the missing ones.
  void drain() {
    for (;;) {
      write_next();
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
  void write_next() {
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
      waiting_.erase(it);
    }
  }

  /// A process killed outright loses what only its memory holds: the waiting rows are copied
  /// out every second, or less often when a copy took more than 2% of the time since the last
  /// (the copy rewrites every waiting row: up to the reorder budget).
  void keep_ahead() {
    if (waiting_.empty()) {
      if (ahead_kept_) output_.keep_ahead({});
      ahead_kept_ = ahead_changed_ = false;
      return;
    }
    const Clock::time_point now = Clock::now();
    if (!ahead_changed_ || now - last_copy_ < copy_period_) return;
    std::string text;
    for (const auto& [first, rows] : waiting_) text += rows.text;
    output_.keep_ahead(text);
    ahead_kept_ = true;
    ahead_changed_ = false;
    last_copy_ = Clock::now();
    copy_period_ = std::max<Clock::duration>(std::chrono::seconds(1), 50 * (last_copy_ - now));
  }

  SweepOutput& output_;
  const std::size_t count_;
  std::size_t position_ = 0, written_ = 0;
  std::map<std::size_t, Finished> waiting_;
  bool ahead_kept_ = false, ahead_changed_ = false;
  Clock::time_point last_copy_ = Clock::now();
  Clock::duration copy_period_ = std::chrono::seconds(1);
};

/// "[name] k/count unit" on stderr every 2 s once the sweep has run 2 s, and at the end.
class SweepProgress {
 public:
  explicit SweepProgress(const SweepRows& rows)
      : name_(rows.progress), unit_(rows.unit), count_(rows.count) {}
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

// ---------------------------------------------------------------- one rank's sweep

/// One rank's side of a sweep: takes chunks from the link's counter for its team; rank 0 also
/// receives every rank's finished rows and writes them in order, the others send theirs to it.
/// run() loops until the rows are exhausted (or the sweep stopped) and this rank's rows ended;
/// rank 0 then waits for every other rank's last message.
class RankSweep {
 public:
  RankSweep(SweepLink& link, const SweepRows& rows, SweepOutput* output, const std::string& kept)
      : link_(link), rows_(rows), root_(link.rank() == 0),
        threads_(static_cast<std::size_t>(rows.threads) * static_cast<std::size_t>(link.ranks())),
        window_(reorder_window(rows, threads_)) {
    if (!kept.empty())  // else every row is pending, and pending_ is left empty
      for (std::size_t i = 0; i < rows.count; ++i)
        if (!kept_bit(kept, i)) pending_.push_back(i);
    pending_count_ = kept.empty() ? rows.count : pending_.size();
    bounds_ = guided_chunks(pending_count_, threads_,
                            std::min(max_chunk_rows, std::max<std::size_t>(1, window_ / (4 * threads_))));
    outcome_.count = rows.count;
    outcome_.threads = static_cast<int>(threads_);
    if (root_) {
      writer_.emplace(*output, rows.count);
      rows_per_rank_.assign(static_cast<std::size_t>(link.ranks()), 0);
    }
  }

  SweepOutcome run(const std::function<void(const SweepOutcome&)>& finish) {
    try {
      inject_rank_fault(true);
      for (;;) {
        for (Finished& f : team_.take()) finished(std::move(f), 0);
        if (root_) receive();
        watch_stop();
        if (!stopping_) feed();
        if (root_) write_ready();
        if (ended()) break;
        team_.wait(root_ ? (exhausted_ && team_.idle() ? root_poll_idle : root_poll)
                         : window_wait_ ? std::chrono::microseconds(1000) : rank_poll);
      }
    } catch (...) {
      // This rank cannot go on: the others stop, and rank 0 writes what was finished. Its rows
      // get their grace; rows still running then would outlive what they use: the process ends.
      link_.fetch(SweepLink::stop, SweepLink::Op::bit_or, stop_rank_failed);
      if (!root_) link_.send(SweepLink::finished, "1");
      begin_stop();
      while (!team_.idle() && Clock::now() < deadline_) team_.wait(rank_poll);
      if (!team_.idle()) exit_process(report_failure(std::current_exception()));
      throw;
    }
    for (Finished& f : team_.take()) finished(std::move(f), 0);
    const bool abandoned = !team_.idle();
    if (!root_) {
      // "<abandoned rows: 1, else 0> <busy seconds>"
      link_.send(SweepLink::finished,
                 (abandoned ? "1 " : "0 ") + std::to_string(team_.busy_seconds()));
      if (abandoned) exit_process(0);  // rank 0 reports
      return outcome_;
    }
    return conclude(finish, abandoned || abandoned_elsewhere_);
  }

 private:
  /// Rows finished on rank `source` (0: this rank's team; rank 0 only for the others).
  void finished(Finished&& f, int source) {
    if (f.failure && !rows_.failed_row && !stopping_) {
      link_.fetch(SweepLink::stop, SweepLink::Op::bit_or, stop_row_failed);
      begin_stop();
    }
    if (!root_) {
      outcome_.computed += f.count;
      link_.send(SweepLink::rows, pack_finished(std::move(f)));
      return;
    }
    rows_per_rank_[static_cast<std::size_t>(source)] += f.count;
    outcome_.computed += f.count;
    outcome_.failed_rows += f.failed_rows;
    // The first failure by index: one that stops the sweep, or the first failed row written.
    std::optional<RowFailure>& first = rows_.failed_row ? first_failed_ : failure_;
    if (f.failure && (!first || f.failure->row < first->row)) first = std::move(f.failure);
    writer_->add(std::move(f));
  }

  /// Rank 0: every message that has arrived.
  void receive() {
    while (std::optional<SweepLink::Message> message = link_.receive()) {
      if (message->tag == SweepLink::rows) {
        finished(unpack_finished(std::move(message->payload)), message->source);
      } else {
        ++peers_finished_;
        abandoned_elsewhere_ = abandoned_elsewhere_ || message->payload[0] != '0';
        outcome_.busy_seconds += std::strtod(message->payload.c_str() + 1, nullptr);
      }
    }
  }

  /// A signal here stops every rank; a stop anywhere (a signal, a failed row, a failed rank)
  /// stops this one. The counter is read every poll (a few microseconds).
  void watch_stop() {
    if (stopping_) return;
    if (stop_flag().load()) link_.fetch(SweepLink::stop, SweepLink::Op::bit_or, stop_signal);
    if (link_.fetch(SweepLink::stop, SweepLink::Op::read) != 0) begin_stop();
  }

  void begin_stop() {
    stopping_ = true;
    team_.stop();
    deadline_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                   std::chrono::duration<double>(rows_.grace_seconds));
  }

  /// Takes chunks for the team while it wants them and the window allows.
  void feed() {
    window_wait_ = false;
    while (team_.wanted() > 0) {
      if (held_.empty()) {
        if (exhausted_) break;
        const std::uint64_t chunk = link_.fetch(SweepLink::next_chunk, SweepLink::Op::add, 1);
        if (chunk + 1 >= bounds_.size()) {
          exhausted_ = true;
          break;
        }
        hold(bounds_[chunk], bounds_[chunk + 1]);
      }
      const Range next = held_.front();
      if (next.first >= unwritten_ + window_) {
        unwritten_ = root_ ? writer_->position()
                           : link_.fetch(SweepLink::unwritten, SweepLink::Op::read);
        if (next.first >= unwritten_ + window_) {
          window_wait_ = true;
          break;
        }
      }
      team_.add(next);
      held_.pop_front();
    }
    if (exhausted_ && held_.empty()) team_.close();
  }

  /// The rows of pending positions [from, to) as runs of consecutive rows.
  void hold(std::size_t from, std::size_t to) {
    if (pending_.empty()) {
      held_.push_back(Range{from, to - from});
      return;
    }
    for (std::size_t k = from; k < to; ++k) {
      if (!held_.empty() && held_.back().first + held_.back().count == pending_[k])
        ++held_.back().count;
      else
        held_.push_back(Range{pending_[k], 1});
    }
  }

  /// Rank 0: writes the rows that are next in order (an output that cannot be written fails the
  /// sweep) and tells the others where the window starts.
  void write_ready() {
    if (!failure_) {
      try {
        writer_->advance();
      } catch (const invalid_input& bad) {  // e.g. the output file cannot be written
        failure_ = RowFailure{rows_.count, true, bad.what()};
      } catch (const std::exception& error) {
        failure_ = RowFailure{rows_.count, false, error.what()};
      }
      if (failure_ && !stopping_) {
        link_.fetch(SweepLink::stop, SweepLink::Op::bit_or, stop_row_failed);
        begin_stop();
      }
    }
    if (writer_->position() != published_) {
      published_ = writer_->position();
      link_.fetch(SweepLink::unwritten, SweepLink::Op::replace, published_);
    }
    progress_.report(outcome_.computed + (rows_.count - pending_count_));
  }

  /// This rank's rows ended (none left to start, or stopped, and none running or past their
  /// grace); on rank 0 also every other rank's.
  bool ended() {
    const bool no_more = stopping_ || (exhausted_ && held_.empty());
    if (!no_more || !(team_.idle() || (stopping_ && Clock::now() >= deadline_))) return false;
    return !root_ || peers_finished_ == link_.ranks() - 1;
  }

  /// Rank 0: writes what is left (after a stop: every row there is, past the missing ones),
  /// fills the outcome and lets `finish` complete the output. When rows had to be abandoned the
  /// process ends here.
  SweepOutcome conclude(const std::function<void(const SweepOutcome&)>& finish, bool abandoned) {
    const std::uint64_t stop = link_.fetch(SweepLink::stop, SweepLink::Op::read);
    outcome_.interrupted = (stop & (stop_signal | stop_rank_failed)) != 0;
    if (!failure_) {
      try {
        if (stop != 0) writer_->drain();
        else writer_->advance();
      } catch (const invalid_input& bad) {
        failure_ = RowFailure{rows_.count, true, bad.what()};
      } catch (const std::exception& error) {
        failure_ = RowFailure{rows_.count, false, error.what()};
      }
    }
    if (!failure_ && !writer_->complete())
      failure_ = RowFailure{rows_.count, false, "sweep: rows went missing"};
    outcome_.written = writer_->written();
    outcome_.seconds = seconds_since(start_);
    outcome_.busy_seconds += team_.busy_seconds();
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
    progress_.report(outcome_.written, true);
    report_sweep(outcome_, rows_per_rank_);
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
  SweepLink& link_;
  const SweepRows& rows_;
  const bool root_;
  const std::size_t threads_, window_;
  std::vector<std::size_t> pending_;  ///< the rows to compute (not kept), in order; empty: all
  std::size_t pending_count_ = 0;
  std::vector<std::size_t> bounds_;   ///< the chunks, as positions in pending_
  std::deque<Range> held_;            ///< a chunk taken, its runs not yet given to the team
  bool exhausted_ = false, stopping_ = false, window_wait_ = false;
  std::size_t unwritten_ = 0;  ///< the first unwritten row, as last seen
  Clock::time_point deadline_{};
  SweepOutcome outcome_;
  // rank 0
  std::optional<OrderedWriter> writer_;
  SweepProgress progress_{rows_};
  std::vector<std::size_t> rows_per_rank_;
  std::optional<RowFailure> failure_, first_failed_;
  std::size_t published_ = 0;
  int peers_finished_ = 0;
  bool abandoned_elsewhere_ = false;
  // Last: its threads stop before the state above goes.
  ComputeTeam team_{rows_, rows_.threads, handover_period(threads_)};
};

}  // namespace

// Weak: the test build's definitions (tests/cli/row_faults.cpp) replace them at link time.
[[gnu::weak]] void inject_row_fault(std::size_t) {}
[[gnu::weak]] void inject_rank_fault(bool) {}
[[gnu::weak]] std::size_t test_window_rows() { return 0; }
[[gnu::weak]] void report_sweep(const SweepOutcome&, std::span<const std::size_t>) {}

std::vector<std::size_t> guided_chunks(std::size_t rows, std::size_t threads, std::size_t largest) {
  std::vector<std::size_t> bounds{0};
  const std::size_t share = 8 * std::max<std::size_t>(threads, 1);
  for (std::size_t first = 0; first < rows;) {
    const std::size_t size = std::clamp<std::size_t>((rows - first) / share, 1,
                                                     std::max<std::size_t>(largest, 1));
    first += size;
    bounds.push_back(first);
  }
  return bounds;
}

SweepOutcome run_sweep_on(SweepLink& link, const SweepRows& rows, SweepOutput* output,
                          const std::string& kept,
                          const std::function<void(const SweepOutcome&)>& finish) {
  return RankSweep(link, rows, output, kept).run(finish);
}

SweepOutcome run_sweep(const SweepRows& rows, SweepOutput* output,
                       const std::function<void(const SweepOutcome&)>& finish) {
  inject_rank_fault(false);
  const std::unique_ptr<SweepLink> link = open_sweep_link();  // collective
  // Every rank needs the kept rows (bits; empty when there are none).
  std::string kept;
  if (is_root() && output->kept_count() > 0) {
    kept.assign((rows.count + 7) / 8, '\0');
    for (std::size_t i = 0; i < rows.count; ++i)
      if (output->kept(i)) kept[i / 8] = static_cast<char>(kept[i / 8] | (1 << (i % 8)));
  }
  kept = broadcast_from_root(std::move(kept));
  return run_sweep_on(*link, rows, output, kept, finish);
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
