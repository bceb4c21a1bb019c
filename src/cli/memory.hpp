// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/memory.hpp -- how the pendavg process takes memory from the kernel. A sweep allocates
// and frees large buffers all the time (a cases file, each chunk's rows as text, the rows other
// ranks send, the numbers the check keeps); with glibc's defaults each of them is fresh memory
// from the kernel, and each 4 kB page of it costs a page fault when first written. In the VM this
// project is measured on a fault costs ~12 us (the host backs the page: 24 ms for 8 MB, against
// 0.3 ms for the same 8 MB in four 2 MB pages), which made a fifth of a 20,000-row `average
// --cases` run. So the command (main(), before anything else; the library never does this, it
// has no process-wide state) keeps freed memory for reuse and serves large buffers from 2 MB
// pages where the kernel offers them (transparent huge pages in `madvise` mode, the usual
// default).
#pragma once

namespace pendavg::cli {

/// Sets glibc's malloc up for a sweep (on glibc only; elsewhere, and when PENDAVG_MALLOC=default
/// is set, nothing changes): blocks up to 32 MB from the heap rather than from mappings of their
/// own, no memory returned to the kernel below 1 GB of free heap, the heap grown 64 MB at a time,
/// and the main heap's first 64 MB advised for huge pages. Compute threads allocate in arenas of
/// their own (one arena for all made MPFR rows on two threads 40% slower: its lock), so the
/// large buffers they fill -- the rows' text -- are taken by the coordinator (sweep.cpp). GMP's
/// (MPFR's) blocks of up to 512 bytes are recycled per thread (mp_set_memory_functions): in a
/// process with more than one thread glibc locks its arena for most of them (38-digit `--cases`
/// rows 5% faster, a 30-digit N = 3 torus point 6%). Returns true when it changed something.
bool prepare_process_memory();

}  // namespace pendavg::cli
