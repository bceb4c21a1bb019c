// SPDX-License-Identifier: GPL-3.0-or-later
// tests/cli/row_faults.cpp -- the test build of the command (pendavg_row_faults): the same
// objects as pendavg, with these definitions of sweep.hpp's test hooks in place of the shipped
// ones, which do nothing (the shipped command reads none of these variables):
//   PENDAVG_TEST_FAILING_ROWS=I,J,...  those rows (indices from 0) throw when computed: a row
//       that fails late, after the check before the sweep passed it (the shipped command refuses
//       the rows it can foresee failing before any is computed, so no input reproduces this);
//   PENDAVG_TEST_FAIL_ON_RANK=K[:sweep]  rank K (all: every rank) fails just before the sweep's
//       first collective step, or with ":sweep" as its sweep begins;
//   PENDAVG_TEST_SLOW_ROW=I:S  row I sleeps S seconds before it is computed (rows after it finish
//       first and wait in rank 0's reorder buffer);
//   PENDAVG_SWEEP_WINDOW_ROWS=K  a reorder window of K rows (rows wait for the window to move);
//   PENDAVG_SWEEP_REPORT=1  one line on stderr after a sweep: the rows each rank computed.
#include "cli/distribute.hpp"
#include "cli/sweep.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>
#include <chrono>
#include <thread>
#include <vector>

namespace pendavg::cli {

namespace {

std::vector<std::size_t> failing_rows() {
  std::vector<std::size_t> rows;
  const char* list = std::getenv("PENDAVG_TEST_FAILING_ROWS");
  for (const char* p = list ? list : ""; *p != '\0';) {
    char* end = nullptr;
    rows.push_back(std::strtoull(p, &end, 10));
    p = *end == ',' ? end + 1 : end;
    if (end == p && *p != '\0') break;
  }
  std::ranges::sort(rows);
  return rows;
}

std::string_view variable(const char* name) {
  const char* value = std::getenv(name);
  return value ? value : "";
}

}  // namespace

void inject_row_fault(std::size_t index) {
  static const std::string slow(variable("PENDAVG_TEST_SLOW_ROW"));
  if (const std::size_t colon = slow.find(':'); colon != std::string::npos &&
      std::strtoull(slow.c_str(), nullptr, 10) == index)
    std::this_thread::sleep_for(std::chrono::duration<double>(std::atof(slow.c_str() + colon + 1)));
  static const std::vector<std::size_t> rows = failing_rows();
  if (std::ranges::binary_search(rows, index))
    throw std::runtime_error("a failure injected into this row by the test build "
                             "(PENDAVG_TEST_FAILING_ROWS)");
}

void inject_rank_fault(bool begun) {
  const std::string_view which = variable("PENDAVG_TEST_FAIL_ON_RANK");
  if (which.empty()) return;
  if (!which.starts_with("all") && std::atoi(std::string(which).c_str()) != rank()) return;
  if (begun == (which.find(":sweep") != std::string_view::npos))
    throw std::runtime_error("a failure injected on this rank (PENDAVG_TEST_FAIL_ON_RANK)");
}

std::size_t test_window_rows() {
  return std::strtoull(std::string(variable("PENDAVG_SWEEP_WINDOW_ROWS")).c_str(), nullptr, 10);
}

void report_sweep(const SweepOutcome& outcome, std::span<const std::size_t> rows_per_rank) {
  if (variable("PENDAVG_SWEEP_REPORT") != "1") return;
  std::string per_rank;
  for (const std::size_t rows : rows_per_rank) (per_rank += ' ') += std::to_string(rows);
  std::fprintf(stderr, "pendavg: test: sweep of %zu rows, %zu computed, %.6f s; rows per rank:%s; "
               "threads busy %.1f%%\n", outcome.count, outcome.computed, outcome.seconds,
               per_rank.c_str(), 100 * outcome.busy_seconds / (outcome.threads * outcome.seconds));
}

}  // namespace pendavg::cli
