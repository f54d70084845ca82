// Tests of core/huge_pages.cpp: which part of a range is advised, and that the advice leaves the
// memory as it was.
#include "core/huge_pages.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace rubble {
namespace {

constexpr std::size_t huge_page = std::size_t{2} << 20;

TEST(HugePages, SmallRangesAndNullAreLeftAlone) {
  std::vector<char> small(huge_pages_from_bytes - 1);
  EXPECT_EQ(advise_huge_pages(small.data(), small.size()), 0u);
  EXPECT_EQ(advise_huge_pages(nullptr, 64u << 20), 0u);
}

// A 20 MiB block: the advice covers exactly its 2 MiB-aligned interior (at least 8 of its 10 huge
// pages) where the kernel has transparent huge pages, and the contents written before it and
// after it are intact.
TEST(HugePages, AdvisesTheAlignedInteriorAndKeepsTheContents) {
  std::vector<std::uint32_t> block((20u << 20) / sizeof(std::uint32_t));
  for (std::size_t i = 0; i < block.size(); i += 1024) block[i] = static_cast<std::uint32_t>(i);
  const std::size_t bytes = block.size() * sizeof(std::uint32_t);
  const std::size_t advised = advise_huge_pages(block.data(), bytes);
  if (std::filesystem::exists("/sys/kernel/mm/transparent_hugepage/enabled")) {
    const auto begin = reinterpret_cast<std::uintptr_t>(block.data());
    const std::uintptr_t first = (begin + huge_page - 1) / huge_page * huge_page;
    const std::uintptr_t last = (begin + bytes) / huge_page * huge_page;
    EXPECT_EQ(advised, last - first);
    EXPECT_GE(advised, 8 * huge_page);
  } else {
    EXPECT_EQ(advised, 0u) << "no transparent huge pages here: nothing can be advised";
  }
  for (std::size_t i = 0; i < block.size(); i += 1024) block[i + 1] = 1;
  for (std::size_t i = 0; i < block.size(); i += 1024) {
    ASSERT_EQ(block[i], static_cast<std::uint32_t>(i));
    ASSERT_EQ(block[i + 1], 1u);
  }
}

}  // namespace
}  // namespace rubble
