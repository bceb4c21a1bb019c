// SPDX-License-Identifier: GPL-3.0-or-later
// engine/dynamics/blocking.hpp -- time averages of correlated samples with Flyvbjerg-Petersen
// blocking error bars (H. Flyvbjerg and H. G. Petersen, J. Chem. Phys. 91, 461 (1989)).
//
// Samples arrive one row of `width` observables at a time. They are summed into blocks of a
// fixed length; the block means are kept (at most max_blocks of them: when full, neighbouring
// blocks are merged and the length doubles, so memory stays bounded for any run length).
// The standard error of the mean is read from the blocking ladder: level k merges 2^k finest
// blocks into M_k blocks and gives SE_k = sqrt(var_k / M_k). For correlated data SE_k grows
// with k until the blocks are longer than the correlation time, then stays flat within its
// noise (relative SE_k / sqrt(2 (M_k - 1))). The reported error is the largest SE_k over the
// levels with at least 32 blocks: on the plateau that is its value plus a little of its noise
// (conservative by ~10%), and it does not stop early on a slowly rising ladder (long-tailed
// correlations, e.g. K_i^(c) of a light first link under Langevin). With fewer than 32 finest
// blocks it is the plain SE of the finest blocks: the run is too short to judge correlations.
// The integrated autocorrelation time follows as tau = n SE^2 / (2 sigma^2) samples, sigma^2
// the per-sample variance (accumulated about the first sample, so nothing cancels).
//
// A statistical estimate, not a bound: tests check its coverage on processes with a known
// variance of the mean (AR(1)).
#pragma once

#include "pendavg/dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

// The dynamics kernels include this header once per instruction set with
// PENDAVG_BLOCKING_NAMESPACE set to their own namespace (src/engine/dynamics/dynamics_kernels.cpp), so that
// each gets its own copy compiled for it.
#ifndef PENDAVG_BLOCKING_NAMESPACE
#define PENDAVG_BLOCKING_NAMESPACE detail
#endif
namespace pendavg::PENDAVG_BLOCKING_NAMESPACE {

/// Standard error of the mean of `means` (equal-length block means) by blocking, and the
/// number of levels examined.
/// Fewer than minimum_blocks finished blocks (a run interrupted early, or too short for its
/// block length) leave the error unknown: NaN, which callers report as such (never 0).
template <class Real>
Real blocking_standard_error(std::vector<Real> means, std::size_t* level_out = nullptr) {
  using std::sqrt;
  constexpr std::size_t minimum_blocks = 16;
  if (means.size() < minimum_blocks) return std::numeric_limits<Real>::quiet_NaN();
  Real largest = 0;
  std::size_t level = 0, chosen = 0;
  // Levels with at least 32 blocks (or the finest one when there are fewer).
  while (means.size() >= 32 || level == 0) {
    const std::size_t m = means.size();
    if (m < 2) break;
    Real mean = 0;
    for (const Real& b : means) mean += b;
    mean /= Real(m);
    Real var = 0;
    for (const Real& b : means) var += (b - mean) * (b - mean);
    var /= Real(m - 1);
    const Real e = sqrt(var / Real(m));
    if (e > largest) {
      largest = e;
      chosen = level;
    }
    std::vector<Real> merged(m / 2);
    for (std::size_t j = 0; j < m / 2; ++j) merged[j] = (means[2 * j] + means[2 * j + 1]) / 2;
    means.swap(merged);
    ++level;
  }
  if (level_out != nullptr) *level_out = chosen;
  return largest;
}

/// Running block means of rows of observables (see the header comment).
template <class Real>
class BlockAverager {
 public:
  BlockAverager(std::size_t width, std::size_t block_length, std::size_t max_blocks)
      : width_(width),
        block_length_(std::max<std::size_t>(1, block_length)),
        max_blocks_(std::max<std::size_t>(16, max_blocks & ~std::size_t(1))),
        current_(width, Real(0)),
        total_(width, Real(0)),
        reference_(width, Real(0)),
        squares_(width, Real(0)),
        shifted_(width, Real(0)),
        means_(width) {}

  void add(const Real* row) {
    if (samples_ == 0)
      for (std::size_t c = 0; c < width_; ++c) reference_[c] = row[c];
    for (std::size_t c = 0; c < width_; ++c) {
      current_[c] += row[c];
      const Real d = row[c] - reference_[c];
      shifted_[c] += d;
      squares_[c] += d * d;
    }
    ++samples_;
    if (++in_block_ == block_length_) close_block();
  }

  std::size_t samples() const { return samples_; }
  std::size_t blocks() const { return means_.empty() ? 0 : means_[0].size(); }
  std::size_t block_length() const { return block_length_; }

  /// Mean of column c over all samples, its blocking standard error, and the integrated
  /// autocorrelation time in units of sample_time.
  TimeAverage<Real> time_average(std::size_t c, const Real& sample_time) const {
    using std::sqrt;
    TimeAverage<Real> out;
    if (samples_ == 0) return out;
    const Real n(static_cast<double>(samples_));
    const Real shift = shifted_[c] / n;
    out.value = reference_[c] + shift;
    out.error = blocking_standard_error(means_[c]);
    const Real variance = (squares_[c] - n * shift * shift) / n;
    if (variance > 0) out.autocorrelation_time = n * out.error * out.error / (2 * variance) * sample_time;
    return out;
  }

  /// Least-squares slope of column c's block means against sample index, times the number of
  /// samples: the change of the column over the run that a linear trend explains.
  Real trend(std::size_t c) const {
    const std::vector<Real>& b = means_[c];
    const std::size_t m = b.size();
    if (m < 2) return Real(0);
    Real tbar = Real(m - 1) / 2, ybar = 0;
    for (const Real& v : b) ybar += v;
    ybar /= Real(m);
    Real sty = 0, stt = 0;
    for (std::size_t j = 0; j < m; ++j) {
      const Real t = Real(j) - tbar;
      sty += t * (b[j] - ybar);
      stt += t * t;
    }
    return sty / stt * Real(m);
  }

 private:
  void close_block() {
    const Real inv = Real(1) / Real(block_length_);
    for (std::size_t c = 0; c < width_; ++c) {
      means_[c].push_back(current_[c] * inv);
      current_[c] = 0;
    }
    in_block_ = 0;
    if (means_[0].size() == max_blocks_) {
      for (std::size_t c = 0; c < width_; ++c) {
        std::vector<Real>& b = means_[c];
        for (std::size_t j = 0; j < b.size() / 2; ++j) b[j] = (b[2 * j] + b[2 * j + 1]) / 2;
        b.resize(b.size() / 2);
      }
      block_length_ *= 2;
    }
  }

  std::size_t width_, block_length_, max_blocks_;
  std::vector<Real> current_, total_, reference_, squares_, shifted_;
  std::vector<std::vector<Real>> means_;
  std::size_t in_block_ = 0, samples_ = 0;
};

}  // namespace pendavg::PENDAVG_BLOCKING_NAMESPACE
