// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep.hpp -- the engine under `table`, `average --cases` and `simulate --replicas`:
// rows 0..count-1, each a pure function of its index, computed on every rank's threads and
// written in index order by rank 0.
//
// Work distribution. The rows still to compute (not kept from a resumed file) are cut into
// chunks by a fixed rule (guided_chunks: a chunk is 1/(8T) of the rows left, T the job's compute
// threads, capped so the reorder buffer stays small), the same on every rank; one counter kept
// by rank 0 (SweepLink: MPI_Fetch_and_op on a window in rank 0's memory) hands out the next
// chunk, so a rank takes work without waiting for rank 0. A thread's next chunk is taken only
// when its running chunk is about to end (within 1 ms at its pace so far): a chunk taken earlier
// would sit in one rank's queue while another rank runs out. Every rank's main thread
// coordinates (takes chunks, sends finished rows to rank 0, which writes them, without waiting
// for rank 0 to receive them) while a team of OpenMP threads computes.
// Order and memory. Rank 0 writes the rows in index order as soon as they are contiguous; rows
// that arrive early wait in a reorder buffer. No chunk starting more than `window` rows past the
// first unwritten row starts (a second counter: rank 0's first unwritten row), so the buffer
// holds O(window) rows: window = (32 MB + 128 kB per compute thread of the job) / row_bytes, at
// least 16 rows per thread: memory is O(threads x row), not O(rows).
// Output. Every row is computed by the same function with one thread, so the output does not
// depend on the rank or thread count, nor on which rank computed which row.
// Interruption. SIGINT/SIGTERM on any rank stop the sweep (a third counter, which every rank
// watches): no new rows start, rows running get `grace_seconds` to finish, then rank 0 writes
// every finished row (in order, the missing ones left out) and the command ends; rows still
// running are abandoned (the process exits at once after its output is complete). A rank that
// fails outside its rows stops the sweep the same way, and names itself. A process killed
// outright (SIGKILL: no handler runs) keeps what rank 0 had written: rows go out as soon as they
// are in order (SweepOutput::flush when rank 0 waits), a running chunk hands its finished rows
// over every second, rows finished ahead of an unfinished one (waiting in the reorder buffer)
// are copied out about every second (SweepOutput::keep_ahead), and --resume takes them all
// from the dead writer's temporaries (sweep_file.hpp).
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// What to compute.
struct SweepRows {
  std::size_t count = 0;      ///< rows 0..count-1
  std::size_t row_bytes = 1;  ///< an upper bound of one row's text (sizes the reorder window)
  int threads = 1;            ///< compute threads per rank
  bool timing = false;        ///< measure every row's thread CPU time (SweepOutput::rows)
  /// After a signal, how long running rows may still finish: half a second, as Open MPI's
  /// mpirun kills the ranks 1 s after it forwarded a SIGTERM (odls_base_sigkill_timeout), and
  /// every rank must have finished and rank 0 written its output before then.
  double grace_seconds = 0.5;
  /// Appends row `index` to `out`; `thread` (0..threads-1) selects the caller's scratch. Throws
  /// (invalid_input for bad input) when the row cannot be computed.
  std::function<void(std::size_t index, int thread, std::string& out)> compute;
  /// "[<progress>] k/count <unit>" on stderr every 2 s once a sweep has run 2 s (empty: none).
  std::string progress, unit = "rows";
  /// A row that throws once the sweep runs (a failure the check before the sweep could not
  /// see): when set, the row's text is this line (a '#' line naming the row and `reason`, so
  /// that a CSV reader skips it and --resume computes the row again), the sweep goes on and the
  /// outcome counts it (SweepOutcome::failed_rows); its time (SweepRows::timing) is -infinity.
  /// Unset: the first failing row stops the sweep (SweepOutcome::failed).
  std::function<std::string(std::size_t index, std::string_view reason)> failed_row;
};

/// Rank 0's side: where the rows go, in index order.
class SweepOutput {
 public:
  virtual ~SweepOutput() = default;
  /// True when row `index` is in the output already (kept from a resumed file): not computed.
  virtual bool kept(std::size_t) const { return false; }
  /// The number of kept rows.
  virtual std::size_t kept_count() const { return 0; }
  /// The next kept row (index order).
  virtual void write_kept(std::size_t) {}
  /// Rows first..first+count-1, computed, as one text; `row_us` their thread CPU times
  /// (SweepRows::timing) or empty.
  virtual void write_rows(std::size_t first, std::size_t count, std::string_view text,
                          std::span<const double> row_us) = 0;
  /// Rank 0 is about to wait: what is buffered goes out, so that a run killed outright
  /// (SIGKILL) leaves every row written so far where --resume finds it.
  virtual void flush() {}
  /// The rows finished ahead of an unfinished one, which wait in rank 0's reorder buffer: their
  /// lines in index order (empty: none wait any more). Kept where --resume finds them should the
  /// process be killed outright; replaces what an earlier call kept.
  virtual void keep_ahead(std::string_view) {}
};

struct SweepOutcome {
  std::size_t count = 0;     ///< rows of the sweep
  std::size_t written = 0;   ///< rows in the output: computed now or kept
  std::size_t computed = 0;  ///< rows computed in this run
  bool interrupted = false;  ///< a signal stopped the sweep (rows may be missing)
  int threads = 1;           ///< compute threads over all ranks
  double seconds = 0;        ///< wall time of the sweep
  /// The compute threads' CPU time in rows, over all ranks: busy_seconds / (threads x seconds)
  /// is the share of the job's threads the sweep kept busy (what chunking and messages lose).
  double busy_seconds = 0;
  /// A row that could not be computed (the first by index among those seen): the sweep stopped
  /// and nothing should be kept. Rethrown by rethrow_failure().
  bool failed = false;
  std::size_t failed_row = 0;
  std::string failure;
  bool bad_input = false;
  /// Rows written as failed rows (SweepRows::failed_row), and the first of them by index.
  std::size_t failed_rows = 0;
  std::size_t first_failed_row = 0;
  std::string first_failed_reason;
};

/// The sweep completed but some rows failed (each is a '#' line in the output): report_failure
/// prints it as an error and exits with exit_rows_failed.
class rows_failed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
/// The exit status of a sweep that wrote every row it could but has failed rows: distinct from
/// bad input (2), which computed nothing.
inline constexpr int exit_rows_failed = 3;

/// Test hooks. The shipped definitions do nothing; the test build of the command
/// (tests/cli/row_faults.cpp, pendavg_row_faults) replaces them at link time.
/// Called before each row of a sweep is computed: throws for chosen rows (a row that fails late,
/// after the check before the sweep passed it).
void inject_row_fault(std::size_t index);
/// Called on every rank before the sweep's first collective step (`begun` false) and as its
/// sweep begins (true): throws to fail this rank alone.
void inject_rank_fault(bool begun);
/// A reorder window of this many rows instead of the computed one (0: no change).
std::size_t test_window_rows();
/// Called on rank 0 after a sweep with the rows each rank computed.
void report_sweep(const SweepOutcome& outcome, std::span<const std::size_t> rows_per_rank);

/// The chunks of `rows` rows for a job of `threads` compute threads: the boundaries
/// 0 = b_0 < b_1 < ... < b_m = rows of chunk k = rows b_k..b_{k+1}-1. Guided: each chunk is
/// 1/(8 threads) of the rows left (the first chunks keep every thread busy long; the last ones,
/// of one row, balance the end), at most `largest` rows. An eighth, not a half: rows' costs
/// vary along a sweep (77-digit rows at small beta cost 10x those at large beta), and a first
/// chunk of 1/(2T) of the rows can hold more than 1/T of the work. A pure function: every rank
/// computes the same chunks.
std::vector<std::size_t> guided_chunks(std::size_t rows, std::size_t threads, std::size_t largest);

class SweepLink;
/// run_sweep over a given link (every rank of it calls this; the unit tests connect threads):
/// `kept` has bit i % 8 of byte i / 8 set for row i kept from a resumed file (empty: none), the
/// same on every rank.
SweepOutcome run_sweep_on(SweepLink& link, const SweepRows& rows, SweepOutput* output,
                          const std::string& kept,
                          const std::function<void(const SweepOutcome&)>& finish);

/// Runs the sweep on every rank (collective). `output` is used on rank 0 only (null elsewhere).
/// `finish` runs on rank 0 after the last row was written, before anything is released: it
/// completes the output (a footer, the commit of the file). On the other ranks the outcome only
/// says whether the run failed. When rows had to be abandoned the process ends inside this call,
/// after `finish` (exit status 0, or the failure's).
SweepOutcome run_sweep(const SweepRows& rows, SweepOutput* output,
                       const std::function<void(const SweepOutcome&)>& finish);

/// Throws the outcome's failure (invalid_input for bad input, std::runtime_error otherwise),
/// prefixed by `context(row)`; does nothing when the sweep did not fail.
void rethrow_failure(const SweepOutcome& outcome,
                     const std::function<std::string(std::size_t row)>& context);

/// Calls `check(index, thread)` for rows 0..count-1, split between the ranks and their `threads`
/// threads (`thread` in 0..threads-1, for per-thread scratch; collective). Returns the smallest
/// index for which it threw, on every rank, or `count` when none did. Run check(index, 0) again
/// to get the error. Once stop_flag() is set
/// (a signal while a StopOnSignal is alive) the remaining rows are skipped: the sweep that
/// follows will start none of them. `progress` (not empty): "[<progress>] checking the <unit>:
/// k/count" on stderr every 2 s once the check has run 2 s (rank 0's rows under MPI).
std::size_t first_failing_row(std::size_t count, int threads,
                              const std::function<void(std::size_t index, int thread)>& check,
                              const std::string& progress = "", const std::string& unit = "rows");

/// The start time of a run in UTC ("2026-01-02T03:04:05Z"); SOURCE_DATE_EPOCH (seconds since
/// 1970) replaces the clock, for reproducible files.
std::string utc_timestamp();

}  // namespace pendavg::cli
