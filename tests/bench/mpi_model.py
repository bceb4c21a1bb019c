#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/bench/mpi_model.py -- a model of pendavg's sweep engine (src/cli/sweep.cpp) on many MPI
ranks, to estimate the parallel efficiency of a 10^6-row 77-digit sweep on 1,000 ranks.

It replays the engine's policy event by event:
  * rank 0's coordinator is one server: every message (a request for chunks, a chunk's rows)
    costs it `message_us`, plus `write_us` per row it writes (formatting is done by the workers;
    this is receiving, the reorder buffer and the write) -- measured on this machine, see below;
  * a message takes `latency_us` on the network, and an idle coordinator notices it after half
    its 0.25 ms poll interval on average;
  * chunks aim at max(20 ms, 50 us x threads of the job) from the mean row cost seen so far, at
    most a quarter of the remaining rows per thread (guided) but not below 0.2 ms of rows, at
    most window / (4 threads), where
    window = (32 MB + 128 kB per thread) / row bytes; every rank keeps 2 chunks per thread
    requested or queued, asking for more in a short message just ahead of its finished rows;
  * rank 0 computes too (its requests and rows skip the network and the per-message cost), its
    threads slowed by the share of its core the coordinator takes (busy time so far / time);
  * the rows' costs are the measured per-row thread CPU times of a 77-digit sweep, repeated in
    sweep order up to the row count (so the cost structure along the sweep is kept).
Efficiency = (sum of row costs) / (ranks x threads x time to the last row written), and with the
fixed costs added: checking every row first (split between the ranks) and the launch of the job
(srun/mpirun and MPI_Init: an assumption, --launch-seconds).

  python3 tests/bench/mpi_model.py ROW_US.csv [--rows 1e6] [--ranks 1000] [--threads 1]
         [--mean-ms M] [--row-bytes 1794] [--message-us 10] [--write-us 2] [--latency-us 5]
         [--launch-seconds 2] [--check-us 5]

ROW_US.csv is `pendavg average --cases ... --timing-rows` output (row,line,us). --mean-ms M
rescales the costs to a mean of M ms (e.g. 20: the issue's "200^3 points at 77 digits in about
2 days on one core").
"""
import argparse
import csv
import heapq
import itertools
from collections import deque


def simulate(costs, ranks, threads, row_bytes, message_s, row_s, latency_s, poll_s=0.25e-3):
    """Time until every row is written; statistics of the run."""
    n = len(costs)
    prefix = [0.0] + list(itertools.accumulate(costs))
    workers = ranks  # rank 0 computes too
    total_threads = workers * threads
    window = max((32 * 2**20 + 128 * 2**10 * ranks * threads) // row_bytes, 16 * ranks * threads, 64)
    state = {"next": 0, "timed_rows": 0, "timed_s": 0.0, "written": 0, "root_free": 0.0,
             "messages": 0, "root_busy": 0.0, "chunks": 0}
    waiting = {}  # first -> count: finished rows not yet written (reorder buffer)
    pending = deque()  # (worker, wanted) requests the window blocks
    queue = [deque() for _ in range(workers)]
    running = [0] * workers
    requested = [False] * workers
    exhausted = [False] * workers
    events = []
    order = itertools.count()

    def push(t, kind, data):
        heapq.heappush(events, (t, next(order), kind, data))

    def next_chunk():
        s = state
        if s["next"] >= n or s["next"] >= min(n, s["written"] + window):
            return None
        remaining = n - s["next"]
        target = max(0.02, 50e-6 * total_threads)
        size = 1 if s["timed_rows"] == 0 else max(1, int(target * s["timed_rows"] / max(s["timed_s"], 1e-12)))
        floor = 0 if s["timed_rows"] == 0 else int(2e-4 * s["timed_rows"] / max(s["timed_s"], 1e-12))
        size = min(size, max(1, remaining // (4 * total_threads), floor), 1 << 14,
                   max(1, window // (4 * total_threads)), min(n, s["written"] + window) - s["next"])
        first = s["next"]
        s["next"] += size
        s["chunks"] += 1
        return first, size

    def arrive_root(t, message, local=False):
        # FIFO single server; an idle coordinator sees a message after half a poll interval.
        # Rank 0's own requests and rows come without a message (local).
        start = max(t, state["root_free"]) + (poll_s / 2 if t > state["root_free"] and not local else 0.0)
        work = (0.0 if local else message_s) + (message[2] * row_s if message[0] == "result" else 0.0)
        state["root_free"] = start + work
        state["root_busy"] += work
        state["messages"] += 1
        push(state["root_free"], "root", message)

    def grant(worker, wanted, t):
        chunks = []
        while wanted > 0:
            c = next_chunk()
            if c is None:
                break
            chunks.append(c)
            wanted -= 1
        done = state["next"] >= n
        if not chunks and not done:
            pending.append((worker, wanted))
            return
        push(t + (0.0 if worker == 0 else latency_s), "grant", (worker, chunks, done))

    def start_threads(w, t):
        while running[w] < threads and queue[w]:
            first, size = queue[w].popleft()
            running[w] += 1
            duration = prefix[first + size] - prefix[first]
            if w == 0 and t > 0:  # the coordinator's share of rank 0's core
                duration /= 1 - min(0.9, state["root_busy"] / t)
            push(t + duration, "done", (w, first, size))

    def maybe_request(w, t):
        have = len(queue[w]) + running[w]
        if not requested[w] and not exhausted[w] and have < 2 * threads:
            requested[w] = True
            arrive_root(t + (0.0 if w == 0 else latency_s), ("request", w, 2 * threads - have), w == 0)

    for w in range(workers):
        maybe_request(w, 0.0)
    finish = 0.0
    while events:
        t, _, kind, data = heapq.heappop(events)
        if kind == "grant":
            w, chunks, done = data
            queue[w].extend(chunks)
            requested[w] = False
            exhausted[w] = exhausted[w] or done
            start_threads(w, t)
            maybe_request(w, t)
        elif kind == "done":
            w, first, size = data
            running[w] -= 1
            start_threads(w, t)
            maybe_request(w, t)  # a short request goes just ahead of the rows
            arrive_root(t + (0.0 if w == 0 else latency_s),
                        ("result", first, size, prefix[first + size] - prefix[first]), w == 0)
        elif kind == "root":
            if data[0] == "request":
                grant(data[1], data[2], t)
            else:
                _, first, size, seconds = data
                state["timed_rows"] += size
                state["timed_s"] += seconds
                waiting[first] = size
                while state["written"] in waiting:
                    state["written"] += waiting.pop(state["written"])
                if state["written"] >= n:
                    finish = t
                    break
                for _ in range(len(pending)):
                    worker, wanted = pending.popleft()
                    grant(worker, wanted, t)
    return finish, {"window": window, "chunks": state["chunks"], "messages": state["messages"],
                    "root_busy": state["root_busy"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("row_us")
    parser.add_argument("--rows", type=float, default=1e6)
    parser.add_argument("--ranks", type=int, default=1000)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--mean-ms", type=float, default=0.0)
    parser.add_argument("--row-bytes", type=int, default=1794)  # the 77-digit row bound, N = 2
    parser.add_argument("--message-us", type=float, default=10.0)
    parser.add_argument("--write-us", type=float, default=2.0)
    parser.add_argument("--latency-us", type=float, default=5.0)
    parser.add_argument("--launch-seconds", type=float, default=2.0)
    parser.add_argument("--check-us", type=float, default=5.0)
    a = parser.parse_args()
    measured = [float(r["us"]) * 1e-6 for r in csv.DictReader(open(a.row_us))]
    mean = sum(measured) / len(measured)
    rows = int(a.rows)
    target = a.mean_ms * 1e-3 if a.mean_ms > 0 else 0.02
    scenarios = [("measured costs", measured),
                 (f"costs scaled to a mean of {target * 1e3:g} ms", [c * target / mean for c in measured])]
    print(f"model: {rows} rows, {a.ranks} ranks x {a.threads} threads; per-row costs from "
          f"{len(measured)} measured rows (mean {mean * 1e3:.3f} ms, max "
          f"{max(measured) * 1e3:.3f} ms); coordinator {a.message_us} us/message + {a.write_us} "
          f"us/row, latency {a.latency_us} us; launch {a.launch_seconds} s, check {a.check_us} us/row")
    for name, costs in scenarios:
        tiled = [costs[k % len(costs)] for k in range(rows)]
        work = sum(tiled)
        for ranks in (2, a.ranks):
            t, stats = simulate(tiled, ranks, a.threads, a.row_bytes, a.message_us * 1e-6,
                                a.write_us * 1e-6, a.latency_us * 1e-6)
            slots = ranks * a.threads
            sweep_eff = work / (slots * t)
            fixed = rows * a.check_us * 1e-6 / ranks
            with_fixed = work / (slots * (t + fixed + a.launch_seconds))
            print(f"  {name}: {ranks} ranks: sweep {t:.3f} s (ideal {work / slots:.3f} s), "
                  f"efficiency {sweep_eff:.1%} (sweep), {with_fixed:.1%} (with checks and launch); "
                  f"{stats['chunks']} chunks, {stats['messages']} messages, coordinator busy "
                  f"{stats['root_busy'] / t:.0%}, window {stats['window']} rows")


if __name__ == "__main__":
    main()
