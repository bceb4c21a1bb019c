// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/memory.cpp -- see memory.hpp.
#include "memory.hpp"

#include <cstdint>
#include <cstdlib>
#include <string_view>

#include <gmp.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <new>

#if defined(__GLIBC__)
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>
// mallinfo2 (the free space at the heap's top) came with glibc 2.33; older ones keep the defaults.
#if __GLIBC_PREREQ(2, 33) && defined(MADV_HUGEPAGE) && defined(M_TOP_PAD)
#define PENDAVG_SET_UP_MALLOC 1
#endif
#endif

namespace pendavg::cli {

#if defined(PENDAVG_SET_UP_MALLOC)
namespace {

/// GMP's (and so MPFR's) small blocks -- the limbs of numbers up to ~1000 digits, thousands of
/// them allocated and freed per MPFR row -- recycled per thread. Once a process has a second
/// thread (the sweep's compute team), every malloc and free that misses glibc's small per-thread
/// cache (7 blocks per size) takes the arena's lock: ~3.5% of a 38-digit `--cases` run
/// (measured with glibc.malloc.tcache_count=4000). Classes of 16 bytes up to 512; at most 64
/// blocks per class and thread; a block is kept only when malloc gave it room for its whole
/// class (blocks allocated before the set-up have their exact size).
constexpr std::size_t block_class_bytes = 16, largest_cached_block = 512;
constexpr std::size_t block_classes = largest_cached_block / block_class_bytes;
constexpr std::size_t blocks_per_class = 64;

struct BlockCache {
  void* blocks[block_classes][blocks_per_class];
  std::size_t counts[block_classes] = {};
  ~BlockCache() {
    for (std::size_t c = 0; c < block_classes; ++c)
      for (std::size_t k = 0; k < counts[c]; ++k) std::free(blocks[c][k]);
  }
};
// Taken on a thread's first GMP block (16 kB: not in every thread's static TLS, whose pages a
// new thread would touch), freed when the thread ends; after that its blocks go to free().
thread_local bool block_cache_gone = false;  // trivial: still readable while the thread ends
struct BlockCacheOwner {
  BlockCache* cache = nullptr;
  ~BlockCacheOwner() {
    delete cache;
    cache = nullptr;
    block_cache_gone = true;
  }
};
thread_local BlockCacheOwner block_cache_owner;

BlockCache* block_cache() {
  if (block_cache_gone) return nullptr;
  if (!block_cache_owner.cache) block_cache_owner.cache = new (std::nothrow) BlockCache;
  return block_cache_owner.cache;
}

std::size_t block_class(std::size_t bytes) {
  return (bytes + block_class_bytes - 1) / block_class_bytes - 1;
}

void* allocate_block(std::size_t bytes) {
  if (bytes > 0 && bytes <= largest_cached_block) {
    const std::size_t c = block_class(bytes);
    if (BlockCache* cache = block_cache(); cache && cache->counts[c] > 0)
      return cache->blocks[c][--cache->counts[c]];
    bytes = (c + 1) * block_class_bytes;  // room for the class: the block may serve it later
  }
  void* block = std::malloc(bytes);
  if (!block) {
    std::fputs("pendavg: internal error: out of memory (GMP)\n", stderr);
    std::abort();  // what GMP's own allocator does
  }
  return block;
}

void free_block(void* block, std::size_t bytes) {
  if (block && bytes > 0 && bytes <= largest_cached_block) {
    const std::size_t c = block_class(bytes);
    BlockCache* cache = block_cache();
    if (cache && cache->counts[c] < blocks_per_class &&
        malloc_usable_size(block) >= (c + 1) * block_class_bytes) {
      cache->blocks[c][cache->counts[c]++] = block;
      return;
    }
  }
  std::free(block);
}

void* reallocate_block(void* block, std::size_t old_bytes, std::size_t new_bytes) {
  if (old_bytes > largest_cached_block && new_bytes > largest_cached_block)
    return std::realloc(block, new_bytes);
  void* moved = allocate_block(new_bytes);
  std::memcpy(moved, block, std::min(old_bytes, new_bytes));
  free_block(block, old_bytes);
  return moved;
}

}  // namespace
#endif

bool prepare_process_memory() {
#if defined(PENDAVG_SET_UP_MALLOC)
  if (const char* wanted = std::getenv("PENDAVG_MALLOC");
      wanted && std::string_view(wanted) == "default")
    return false;
  constexpr std::size_t mebibyte = std::size_t(1) << 20;
  constexpr std::size_t heap_step = 64 * mebibyte, huge_page = 2 * mebibyte;
  mallopt(M_MMAP_THRESHOLD, static_cast<int>(32 * mebibyte));
  mallopt(M_TRIM_THRESHOLD, static_cast<int>(1024 * mebibyte));
  mallopt(M_TOP_PAD, static_cast<int>(heap_step));
  // Grow the heap now (a block larger than what is free at its top), then advise its new part.
  const struct mallinfo2 info = mallinfo2();
  void* const block = std::malloc(info.keepcost + mebibyte);
  if (!block) return true;
  const auto begin = reinterpret_cast<std::uintptr_t>(block);
  const auto end = reinterpret_cast<std::uintptr_t>(sbrk(0));
  const std::uintptr_t first = (begin + huge_page - 1) & ~(huge_page - 1);
  if (end > first + huge_page)
    madvise(reinterpret_cast<void*>(first), (end - first) & ~(huge_page - 1), MADV_HUGEPAGE);
  std::free(block);
  mp_set_memory_functions(allocate_block, reallocate_block, free_block);
  return true;
#else
  return false;
#endif
}

}  // namespace pendavg::cli
