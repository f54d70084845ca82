#include "core/huge_pages.hpp"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace rubble {

std::size_t advise_huge_pages(const void* data, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (data == nullptr || bytes < huge_pages_from_bytes) return 0;
  constexpr std::uintptr_t huge_page = std::uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + huge_page - 1) & ~(huge_page - 1);
  const std::uintptr_t last = (begin + bytes) & ~(huge_page - 1);
  if (last <= first) return 0;
  // The range as an offset from `data` (no integer-to-pointer cast). A kernel without transparent
  // huge pages refuses the advice (EINVAL), one set to "never" ignores it: the memory is then used
  // as before.
  char* const advised = const_cast<char*>(static_cast<const char*>(data)) + (first - begin);
  if (madvise(advised, last - first, MADV_HUGEPAGE) != 0) return 0;
  return last - first;
#else
  (void)data;
  (void)bytes;
  return 0;
#endif
}

}  // namespace rubble
