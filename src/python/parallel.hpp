// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/parallel.hpp -- long computations with the GIL released and Ctrl-C honoured.
//
// Python runs signal handlers only on its main thread, between bytecodes or in
// PyErr_CheckSignals. While a computation runs in C++ the calling thread therefore waits for it
// (GIL released) and every `poll_interval` takes the GIL to call `poll` (which runs the signal
// handlers, progress callbacks, ...). The computation itself never touches Python.
#pragma once

#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <algorithm>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

namespace pendavg::python {

namespace py = pybind11;

inline constexpr std::chrono::milliseconds poll_interval{50};

/// Runs work(t) for t = 0..threads-1 on `threads` new threads while the calling thread waits
/// with the GIL released; every poll_interval it takes the GIL and calls poll(). Returns when all
/// have finished (poll is expected to make the work stop early when it must). Exceptions of
/// `work` are the caller's to catch inside it; an exception of `poll` ends the polling and is
/// rethrown once the work has finished.
inline void run_polling(int threads, const std::function<void(int)>& work,
                        const std::function<void()>& poll) {
  std::mutex mutex;
  std::condition_variable finished;
  int running = threads;
  std::exception_ptr poll_failure;
  {
    py::gil_scoped_release release;
    std::vector<std::thread> pool;
    pool.reserve(static_cast<std::size_t>(threads));
    for (int t = 0; t < threads; ++t)
      pool.emplace_back([&, t] {
        work(t);
        const std::lock_guard<std::mutex> lock(mutex);
        if (--running == 0) finished.notify_all();
      });
    for (;;) {
      std::unique_lock<std::mutex> lock(mutex);
      if (finished.wait_for(lock, poll_interval, [&] { return running == 0; })) break;
      lock.unlock();
      if (poll_failure) continue;
      py::gil_scoped_acquire acquire;
      try {
        poll();
      } catch (...) {
        poll_failure = std::current_exception();
      }
    }
    for (std::thread& thread : pool) thread.join();
  }
  if (poll_failure) std::rethrow_exception(poll_failure);
}

/// Runs `work` (a library call observed through `stop` and `fraction`: DynamicsObserver,
/// RunControl) on a helper thread while this thread polls Python: Ctrl-C sets `stop` (returns
/// true: interrupted by the user; the library then ends with what it finished, or throws
/// pendavg::interrupted, which is raised as KeyboardInterrupt); a progress callback (None for
/// none) gets the fraction done whenever it moved; an exception of the callback (or of a signal
/// handler other than SIGINT's) also sets `stop` and is raised after the run. An exception of
/// `work` is rethrown.
template <class Work>
bool run_interruptible(Work&& work, std::atomic<bool>& stop, const std::atomic<double>& fraction,
                  const py::object& progress) {
  std::exception_ptr failure;
  std::optional<py::error_already_set> python_error;
  bool interrupted = false;
  double reported = -1;
  const auto report = [&] {
    const double f = fraction.load();
    if (progress.is_none() || f == reported || python_error || interrupted) return;
    reported = f;
    try {
      progress(f);
    } catch (py::error_already_set& e) {
      if (e.matches(PyExc_KeyboardInterrupt)) interrupted = true;  // Ctrl-C inside the callback
      else python_error = std::move(e);
      stop = true;
    }
  };
  run_polling(
      1,
      [&](int) {
        try {
          work();
        } catch (...) {
          failure = std::current_exception();
        }
      },
      [&] {
        if (!interrupted && !python_error && PyErr_CheckSignals() != 0) {
          if (PyErr_ExceptionMatches(PyExc_KeyboardInterrupt)) {
            PyErr_Clear();
            interrupted = true;
          } else {
            python_error = py::error_already_set();
          }
          stop = true;
        }
        report();
      });
  if (failure) std::rethrow_exception(failure);
  if (python_error) throw std::move(*python_error);
  report();  // the final fraction
  return interrupted;
}

/// Evaluates point(i, worker) for i = 0..count-1 on `threads` workers (each its own `worker`
/// index for per-thread workspaces), indices handed out in increasing order, while the calling
/// thread polls Python (run_polling). A failing point stops the points after it from starting;
/// the failure of the lowest index is rethrown (with that index), which does not depend on the
/// thread count because every lower index had already started. Ctrl-C (KeyboardInterrupt, or
/// any error a signal handler or the progress callback raises) sets `stop` -- no new point
/// starts, and running ones may end early through RunControl -- and is raised here once the
/// workers have finished. `progress` (None for none) gets the fraction of points done.
class PointFailure : public std::exception {
 public:
  PointFailure(std::size_t index, std::exception_ptr error) : index(index), error(error) {}
  const char* what() const noexcept override { return "point failed"; }
  std::size_t index;
  std::exception_ptr error;
};

template <class Point>
void run_points(std::size_t count, int threads, const Point& point, std::atomic<bool>& stop,
                const py::object& progress) {
  constexpr std::size_t none = std::numeric_limits<std::size_t>::max();
  std::atomic<std::size_t> next{0}, done{0}, first_failure{none};
  std::vector<std::exception_ptr> errors(count);
  const auto work = [&](int worker) {
    for (;;) {
      const std::size_t i = next.fetch_add(1);
      if (i >= count || stop.load(std::memory_order_relaxed) || i > first_failure.load()) return;
      try {
        point(i, worker);
      } catch (...) {
        errors[i] = std::current_exception();
        std::size_t seen = first_failure.load();
        while (i < seen && !first_failure.compare_exchange_weak(seen, i)) {
        }
      }
      ++done;
    }
  };
  std::optional<py::error_already_set> python_error;
  std::size_t reported = none;
  const auto report = [&] {
    const std::size_t d = done.load();
    if (progress.is_none() || python_error || d == reported || count == 0) return;
    reported = d;
    try {
      progress(static_cast<double>(d) / static_cast<double>(count));
    } catch (py::error_already_set& e) {
      python_error = std::move(e);
      stop = true;
    }
  };
  run_polling(std::max(threads, 1), work, [&] {
    if (!python_error && PyErr_CheckSignals() != 0) {
      python_error = py::error_already_set();
      stop = true;
    }
    report();
  });
  if (python_error) throw std::move(*python_error);
  report();
  if (const std::size_t f = first_failure.load(); f != none) throw PointFailure(f, errors[f]);
}

}  // namespace pendavg::python
