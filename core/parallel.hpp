#pragma once
// Loops over fewer items than this run on one thread: starting an OpenMP team costs microseconds
// (milliseconds on a loaded machine), more than a small scene's whole stage.
#include <cstddef>

namespace rubble {

/// Minimum loop length for which an OpenMP parallel region pays off.
inline constexpr std::ptrdiff_t min_parallel_items = 1024;

}  // namespace rubble
