// src/cli/memory.cpp -- see memory.hpp.
#include "memory.hpp"

#include <cstdint>
#include <cstdlib>
#include <string_view>

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
  return true;
#else
  return false;
#endif
}

}  // namespace pendavg::cli
