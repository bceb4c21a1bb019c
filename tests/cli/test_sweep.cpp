// SPDX-License-Identifier: GPL-3.0-or-later
// tests/cli/test_sweep.cpp -- the sweep engine (src/cli/sweep.hpp) without mpirun: its chunk rule,
// and K ranks as threads of this process joined by an in-process SweepLink (the counters as
// atomics, rank 0's messages in a queue), against the serial run: the same output for any rank
// and thread count, resumed rows kept, failed rows in place, a failing row or a stop ending the
// sweep with every finished row written in order.
#include <catch2/catch.hpp>

#include "cli/distribute.hpp"
#include "cli/interrupt.hpp"
#include "cli/sweep.hpp"

#include <atomic>
#include <chrono>
#include <ctime>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace pendavg::cli;

/// What the ranks of a fake job share.
struct FakeJob {
  std::atomic<std::uint64_t> counters[3] = {0, 0, 0};
  std::mutex mutex;
  std::deque<SweepLink::Message> inbox;  ///< rank 0's
};

class FakeLink final : public SweepLink {
 public:
  FakeLink(FakeJob& job, int rank, int ranks) : job_(job), rank_(rank), ranks_(ranks) {}
  int rank() const override { return rank_; }
  int ranks() const override { return ranks_; }
  std::uint64_t fetch(Counter counter, Op op, std::uint64_t operand) override {
    std::atomic<std::uint64_t>& c = job_.counters[counter];
    switch (op) {
      case Op::add: return c.fetch_add(operand);
      case Op::bit_or: return c.fetch_or(operand);
      case Op::replace: return c.exchange(operand);
      case Op::read: break;
    }
    return c.load();
  }
  void send(int tag, std::string payload) override {
    const std::lock_guard lock(job_.mutex);
    job_.inbox.push_back(Message{rank_, tag, std::move(payload)});
  }
  std::optional<Message> receive() override {
    const std::lock_guard lock(job_.mutex);
    if (job_.inbox.empty()) return std::nullopt;
    Message message = std::move(job_.inbox.front());
    job_.inbox.pop_front();
    return message;
  }

 private:
  FakeJob& job_;
  int rank_, ranks_;
};

/// Rank 0's output as one text; rows in `kept` come from "the earlier file".
class TextOutput : public SweepOutput {
 public:
  std::set<std::size_t> kept_rows;
  std::string text;
  std::vector<std::size_t> written;  ///< indices, in the order written
  bool kept(std::size_t i) const override { return kept_rows.contains(i); }
  std::size_t kept_count() const override { return kept_rows.size(); }
  void write_kept(std::size_t i) override {
    text += "kept " + std::to_string(i) + "\n";
    written.push_back(i);
  }
  void write_rows(std::size_t first, std::size_t count, std::string_view rows,
                  std::span<const double>) override {
    text += rows;
    for (std::size_t i = first; i < first + count; ++i) written.push_back(i);
  }
};

/// Row i's text; its cost varies ~100x along the rows (so that chunks finish out of order).
void row_text(std::size_t i, std::string& out) {
  volatile double sink = 0;
  for (std::size_t k = 0; k < 200 * (1 + (i * 7919) % 97); ++k) sink = sink + 1e-9 * double(k);
  out += "row " + std::to_string(i) + "\n";
}

std::string bits_of(const std::set<std::size_t>& kept, std::size_t count) {
  if (kept.empty()) return {};
  std::string bits((count + 7) / 8, '\0');
  for (const std::size_t i : kept) bits[i / 8] = static_cast<char>(bits[i / 8] | (1 << (i % 8)));
  return bits;
}

/// Runs `rows` on `ranks` fake ranks (threads); returns rank 0's outcome.
SweepOutcome run_job(int ranks, const SweepRows& rows, TextOutput& output) {
  FakeJob job;
  SweepOutcome root;
  std::vector<std::thread> others;
  const std::string kept = bits_of(output.kept_rows, rows.count);
  for (int r = 1; r < ranks; ++r)
    others.emplace_back([&, r] {
      FakeLink link(job, r, ranks);
      run_sweep_on(link, rows, nullptr, kept, [](const SweepOutcome&) {});
    });
  FakeLink link(job, 0, ranks);
  root = run_sweep_on(link, rows, &output, kept, [](const SweepOutcome&) {});
  for (std::thread& t : others) t.join();
  return root;
}

SweepRows rows_of(std::size_t count, int threads) {
  SweepRows rows;
  rows.count = count;
  rows.threads = threads;
  rows.row_bytes = std::size_t(1) << 30;  // a reorder window of 64 rows: chunks wait for it
  rows.compute = [](std::size_t i, int, std::string& out) { row_text(i, out); };
  return rows;
}

std::string serial_text(std::size_t count) {
  std::string text;
  for (std::size_t i = 0; i < count; ++i) row_text(i, text);
  return text;
}

}  // namespace

TEST_CASE("guided chunks cover the rows in shrinking chunks, the same for every call", "[sweep]") {
  for (const std::size_t rows : {0, 1, 7, 500, 20000}) {
    for (const std::size_t threads : {1, 2, 1000}) {
      const std::vector<std::size_t> b = guided_chunks(rows, threads, 4000);
      REQUIRE(b.front() == 0);
      REQUIRE(b.back() == rows);
      for (std::size_t k = 0; k + 1 < b.size(); ++k) {
        const std::size_t size = b[k + 1] - b[k], left = rows - b[k];
        CHECK(size >= 1);
        CHECK(size <= 4000);
        CHECK(size <= std::max<std::size_t>(1, left / (8 * threads)));  // the last ones balance
        if (k > 0) CHECK(size <= b[k] - b[k - 1]);                     // never growing
      }
      CHECK(b == guided_chunks(rows, threads, 4000));
    }
  }
  // 20,000 rows on 2 threads: a few hundred chunks (each one fetch and one message).
  CHECK(guided_chunks(20000, 2, 4000).size() < 200);
}

TEST_CASE("a rank takes no chunk ahead of a running chunk that is not about to end", "[sweep]") {
  // Two ranks of one thread. The first chunk's rows take 0.2 s each, the others ~10 us: the rank
  // that runs the first chunk must leave every other row to the other rank, which finishes them
  // long before. A rank that queued chunks ahead (as it once did, two per thread) would sit on
  // rows the other rank could have computed.
  constexpr std::size_t count = 64;
  const std::size_t first_chunk = guided_chunks(count, 2, count)[1];
  REQUIRE(first_chunk > 1);
  std::mutex mutex;
  std::map<std::thread::id, std::set<std::size_t>> rows_of_thread;
  SweepRows rows = rows_of(count, 1);
  rows.compute = [&](std::size_t i, int, std::string& out) {
    if (i < first_chunk) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    row_text(i, out);
    const std::lock_guard lock(mutex);
    rows_of_thread[std::this_thread::get_id()].insert(i);
  };
  TextOutput output;
  const SweepOutcome outcome = run_job(2, rows, output);
  CHECK(output.text == serial_text(count));
  CHECK(outcome.written == count);
  REQUIRE(rows_of_thread.size() == 2);
  for (const auto& [thread, computed] : rows_of_thread) {
    if (!computed.contains(0)) continue;
    INFO("rows of the thread that ran row 0: " << computed.size());
    CHECK(computed.size() == first_chunk);
    CHECK(*computed.rbegin() == first_chunk - 1);
  }
}

TEST_CASE("a sweep on 1, 2 and 3 ranks of 1 or 2 threads writes the serial rows", "[sweep]") {
  constexpr std::size_t count = 700;
  const std::string expected = serial_text(count);
  for (const int ranks : {1, 2, 3}) {
    for (const int threads : {1, 2}) {
      TextOutput output;
      const SweepOutcome outcome = run_job(ranks, rows_of(count, threads), output);
      INFO(ranks << " ranks, " << threads << " threads");
      CHECK(output.text == expected);
      CHECK(outcome.written == count);
      CHECK(outcome.computed == count);
      CHECK_FALSE(outcome.failed);
      CHECK_FALSE(outcome.interrupted);
    }
  }
}

TEST_CASE("the outcome's busy time is every rank's compute threads' CPU time in rows",
          "[sweep]") {
  // Each row measures its own thread CPU time; the outcome (rank 0's) must hold the sum over the
  // three ranks' threads (the others' comes in their last message), plus only the bookkeeping
  // around the rows.
  std::atomic<std::uint64_t> rows_ns{0};
  SweepRows rows = rows_of(300, 2);
  rows.compute = [&](std::size_t i, int, std::string& out) {
    timespec a{}, b{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &a);
    std::string burnt;  // ~20 rows' CPU time
    for (int k = 0; k < 20; ++k) row_text(i, burnt);
    row_text(i, out);
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &b);
    rows_ns += static_cast<std::uint64_t>((b.tv_sec - a.tv_sec) * 1000000000L +
                                          (b.tv_nsec - a.tv_nsec));
  };
  TextOutput output;
  const SweepOutcome outcome = run_job(3, rows, output);
  CHECK(output.text == serial_text(300));
  const double rows_seconds = 1e-9 * static_cast<double>(rows_ns.load());
  CHECK(outcome.threads == 6);
  CHECK(outcome.busy_seconds >= 0.95 * rows_seconds);
  CHECK(outcome.busy_seconds <= 1.2 * rows_seconds + 1e-3);
}

TEST_CASE("a resumed sweep computes only the rows not kept and writes them in place", "[sweep]") {
  constexpr std::size_t count = 300;
  TextOutput output;
  std::string expected;
  for (std::size_t i = 0; i < count; ++i) {
    if (i % 3 == 1 || (i >= 100 && i < 180)) {
      output.kept_rows.insert(i);
      expected += "kept " + std::to_string(i) + "\n";
    } else {
      row_text(i, expected);
    }
  }
  const SweepOutcome outcome = run_job(3, rows_of(count, 1), output);
  CHECK(output.text == expected);
  CHECK(outcome.computed == count - output.kept_rows.size());
  CHECK(outcome.written == count);
}

TEST_CASE("failed rows become their lines in place; a failing row without them fails the sweep",
          "[sweep]") {
  constexpr std::size_t count = 200;
  SweepRows rows = rows_of(count, 1);
  rows.compute = [](std::size_t i, int, std::string& out) {
    out += "partial ";  // dropped when the row throws
    if (i == 17 || i == 150) throw std::runtime_error("bad row " + std::to_string(i));
    out.resize(out.size() - 8);
    row_text(i, out);
  };
  rows.failed_row = [](std::size_t i, std::string_view reason) {
    return "# failed: " + std::to_string(i) + ": " + std::string(reason) + "\n";
  };
  std::string expected;
  for (std::size_t i = 0; i < count; ++i) {
    if (i == 17 || i == 150) expected += "# failed: " + std::to_string(i) + ": bad row " + std::to_string(i) + "\n";
    else row_text(i, expected);
  }
  TextOutput output;
  SweepOutcome outcome = run_job(2, rows, output);
  CHECK(output.text == expected);
  CHECK(outcome.failed_rows == 2);
  CHECK(outcome.first_failed_row == 17);
  CHECK_FALSE(outcome.failed);

  rows.failed_row = nullptr;
  TextOutput stopped;
  outcome = run_job(3, rows, stopped);
  CHECK(outcome.failed);
  CHECK(outcome.failed_row == 17);
  CHECK(outcome.failure == "bad row 17");
}

TEST_CASE("a stop writes every finished row in order, the others left out", "[sweep]") {
  constexpr std::size_t count = 2000;
  SweepRows rows = rows_of(count, 1);
  rows.compute = [](std::size_t i, int, std::string& out) {
    if (i == 400) stop_flag().store(true);  // as SIGTERM would, on whichever rank runs it
    row_text(i, out);
  };
  TextOutput output;
  const SweepOutcome outcome = run_job(2, rows, output);
  stop_flag().store(false);
  CHECK(outcome.interrupted);
  CHECK(outcome.written < count);
  CHECK(outcome.written == output.written.size());
  std::string expected;
  for (std::size_t k = 0; k < output.written.size(); ++k) {
    if (k > 0) CHECK(output.written[k] > output.written[k - 1]);
    row_text(output.written[k], expected);
  }
  CHECK(output.text == expected);
}

TEST_CASE("the ranks an MPI launcher started, from its environment", "[sweep]") {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "SLURM_STEP_NUM_TASKS"}) unsetenv(name);
  CHECK(launched_ranks() == 1);
  setenv("SLURM_NTASKS", "8", 1);  // a batch script's own environment: not a launch of 8
  CHECK(launched_ranks() == 1);
  setenv("SLURM_STEP_NUM_TASKS", "8", 1);  // srun -n 8
  CHECK(launched_ranks() == 8);
  unsetenv("SLURM_STEP_NUM_TASKS");
  setenv("OMPI_COMM_WORLD_SIZE", "3", 1);  // mpirun -n 3
  CHECK(launched_ranks() == 3);
  unsetenv("OMPI_COMM_WORLD_SIZE");
  unsetenv("SLURM_NTASKS");
}

TEST_CASE("a long chunk's finished rows reach the output while it runs, and are flushed at once",
          "[sweep]") {
  // One rank, one thread: the first guided chunk is an eighth of the 96 rows, 12 x >= 0.1 s (the
  // others are fast). A run killed outright keeps only what its output was given and flushed:
  // the chunk hands its finished rows over after 1 s (after its 10th row at the latest), so its
  // first piece written is shorter than the chunk, and every piece is flushed.
  struct Flushed : TextOutput {
    std::string out;                 ///< what flush() let out
    std::vector<std::size_t> pieces;  ///< the rows of each write
    void write_rows(std::size_t first, std::size_t count, std::string_view rows,
                    std::span<const double> us) override {
      TextOutput::write_rows(first, count, rows, us);
      pieces.push_back(count);
    }
    void flush() override { out = text; }
  };
  constexpr std::size_t count = 96;
  const std::size_t first_chunk = guided_chunks(count, 1, count)[1];
  REQUIRE(first_chunk == 12);
  SweepRows rows = rows_of(count, 1);
  rows.compute = [&](std::size_t i, int, std::string& out) {
    if (i < first_chunk) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    row_text(i, out);
  };
  Flushed output;
  const SweepOutcome outcome = run_job(1, rows, output);
  CHECK(output.text == serial_text(count));
  CHECK(output.out == output.text);
  REQUIRE_FALSE(output.pieces.empty());
  CHECK(output.pieces.front() < first_chunk);
  CHECK(outcome.written == count);
}
