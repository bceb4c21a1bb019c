#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/bench/mpi_model.py -- a model of pendavg's sweep engine (src/cli/sweep.cpp) on many MPI
ranks, to estimate the parallel efficiency of a 10^6-row 77-digit sweep on 1,000 ranks.

It replays the engine's policy event by event:
  * the rows are cut into guided chunks (sweep.hpp, guided_chunks: 1/(8T) of the rows left, T
    the job's threads, at most window / (4T) rows, window = (32 MB + 128 kB T) / row bytes);
  * a thread that needs work takes the next chunk from rank 0's counter (MPI_Fetch_and_op): one
    network round trip, `latency_us` each way (taken 1 ms before the running chunk ends, so
    this is hidden unless the round trip is longer);
  * a finished chunk goes to rank 0 in one message; rank 0's coordinator is one server that
    costs `message_us` per message and `write_us` per row (receiving, reordering, writing);
  * the rows' costs are the measured per-row thread CPU times of a 77-digit sweep, repeated in
    sweep order up to the row count (the cost structure along the sweep is kept).
Efficiency = (sum of row costs) / (T x time to the last row written), and with the fixed costs
added: checking every row first (split between the ranks) and the job's launch (srun/mpirun and
MPI_Init: an assumption, --launch-seconds).

  python3 tests/bench/mpi_model.py ROW_US.csv [--rows 1e6] [--ranks 1000] [--threads 1]
         [--mean-ms M] [--row-bytes 1794] [--message-us 10] [--write-us 2] [--latency-us 5]
         [--launch-seconds 2] [--check-us 5]

ROW_US.csv is `pendavg average --cases ... --timing-rows` output (row,line,us). --mean-ms M
rescales the costs to a mean of M ms.
"""
import argparse
import csv
import heapq


def guided_chunks(rows, threads, largest):
    bounds, first = [0], 0
    while first < rows:
        first += min(max((rows - first) // (8 * threads), 1), max(largest, 1))
        bounds.append(first)
    return bounds


def simulate(costs, threads, row_bytes, message_s, row_s, latency_s):
    """Time until the last row is written, for `threads` threads taking guided chunks."""
    rows = len(costs)
    window = max((32 * 2**20 + 128 * 2**10 * threads) // row_bytes, 16 * threads, 64)
    bounds = guided_chunks(rows, threads, min(2**14, max(1, window // (4 * threads))))
    prefix = [0.0]
    for c in costs:
        prefix.append(prefix[-1] + c)
    # Each thread: (time it is free, thread). Taking a chunk costs a round trip, hidden behind
    # the chunk it is computing (it fetched ahead), except for its first one.
    free = [(2 * latency_s, t) for t in range(threads)]
    heapq.heapify(free)
    arrivals = []
    for k in range(len(bounds) - 1):
        start, t = heapq.heappop(free)
        end = start + prefix[bounds[k + 1]] - prefix[bounds[k]]
        arrivals.append((end + latency_s, bounds[k + 1] - bounds[k]))
        heapq.heappush(free, (end, t))
    server = 0.0  # rank 0's coordinator, in order of arrival
    for arrive, count in sorted(arrivals):
        server = max(server, arrive) + message_s + count * row_s
    return server, len(bounds) - 1


def main():
    p = argparse.ArgumentParser()
    p.add_argument("row_us")
    p.add_argument("--rows", type=float, default=1e6)
    p.add_argument("--ranks", type=int, default=1000)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--mean-ms", type=float)
    p.add_argument("--row-bytes", type=int, default=1794)
    p.add_argument("--message-us", type=float, default=10)
    p.add_argument("--write-us", type=float, default=2)
    p.add_argument("--latency-us", type=float, default=5)
    p.add_argument("--launch-seconds", type=float, default=2)
    p.add_argument("--check-us", type=float, default=5)
    a = p.parse_args()
    measured = [float(r["us"]) * 1e-6 for r in csv.DictReader(open(a.row_us))]
    if a.mean_ms:
        scale = a.mean_ms * 1e-3 / (sum(measured) / len(measured))
        measured = [c * scale for c in measured]
    rows = int(a.rows)
    costs = [measured[i % len(measured)] for i in range(rows)]
    threads = a.ranks * a.threads
    work = sum(costs)
    span, chunks = simulate(costs, threads, a.row_bytes, a.message_us * 1e-6, a.write_us * 1e-6,
                            a.latency_us * 1e-6)
    fixed = a.launch_seconds + rows * a.check_us * 1e-6 / threads
    print(f"model: {rows} rows (mean {1e3 * work / rows:.3f} ms, {work / 3600:.2f} CPU hours) on "
          f"{a.ranks} ranks x {a.threads} threads: {chunks} chunks, sweep {span:.1f} s, "
          f"efficiency {work / (threads * span):.1%} (sweep), "
          f"{work / (threads * (span + fixed)):.1%} (with launch {a.launch_seconds} s and check)")


if __name__ == "__main__":
    main()
