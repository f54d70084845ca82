#pragma once
// Transparent huge pages for the large arrays a step builds afresh (the contact list, the
// solver's copy of the problem).
//
// Above 20 000 bodies `rubble run` keeps glibc's 128 KiB mmap threshold (apps/cmd_run.cpp), so
// each of these arrays is a fresh mapping every step, zero-filled by the kernel one 4 KiB page
// at a time on first write: 32 000 page faults a step, a fifth of the CPU, in the 10^5-sphere
// accretion (bench/RESULTS.md). Backed by 2 MiB pages, the same memory costs 512 times fewer
// faults. Nothing else changes: same addresses, same contents, same results.
#include <cstddef>

namespace rubble {

/// Asks the kernel (Linux, madvise MADV_HUGEPAGE) to back the 2 MiB-aligned part of
/// [data, data + bytes) with huge pages when it is first written; call it between the allocation
/// and the first write, over the part that will be written (a huge page is resident whole once
/// any byte of it is written: reserve beyond the data would cost memory). Ranges under `huge_pages_from_bytes` are left
/// alone (their few pages are cheap, and a huge page would make untouched reserve resident). Returns the bytes advised:
/// 0 when none (small range, no aligned 2 MiB page inside, not Linux, or the kernel refused).
std::size_t advise_huge_pages(const void* data, std::size_t bytes);

/// The smallest range advise_huge_pages advises: 8 MiB, four huge pages.
inline constexpr std::size_t huge_pages_from_bytes = std::size_t{8} << 20;

}  // namespace rubble
