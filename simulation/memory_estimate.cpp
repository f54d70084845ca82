#include "simulation/memory_estimate.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <fmt/format.h>
#include <fstream>
#include <string>

namespace rubble {
namespace {

/// A limit from a cgroup file ("max" or unreadable: none).
double cgroup_limit(const char* path) {
  std::ifstream in(path);
  std::string text;
  if (!(in >> text) || text == "max") return 0.0;
  try {
    return std::stod(text);
  } catch (const std::exception&) {
    return 0.0;
  }
}

}  // namespace

double scene_memory_estimate(std::uint64_t spheres, std::uint64_t polyhedra) {
  return bytes_per_sphere * static_cast<double>(spheres) + bytes_per_polyhedron * static_cast<double>(polyhedra);
}

double available_memory() {
  double limit = 0.0;
  const auto consider = [&limit](double bytes) {
    // cgroup v1 reports "no limit" as a huge number (2^63 rounded to pages): ignored by the min.
    if (bytes > 0.0) limit = limit > 0.0 ? std::min(limit, bytes) : bytes;
  };
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  if (pages > 0 && page_size > 0) consider(static_cast<double>(pages) * static_cast<double>(page_size));
  // The cgroup's limit, where the cgroup file system shows this process's group at its root (a
  // container's namespace) or at the path /proc/self/cgroup names (v2: "0::/path", v1:
  // "N:memory:/path").
  consider(cgroup_limit("/sys/fs/cgroup/memory.max"));
  consider(cgroup_limit("/sys/fs/cgroup/memory/memory.limit_in_bytes"));
  std::ifstream groups("/proc/self/cgroup");
  for (std::string line; std::getline(groups, line);) {
    const auto colon = line.find(':');
    const auto second = line.find(':', colon + 1);
    if (colon == std::string::npos || second == std::string::npos) continue;
    const std::string controllers = line.substr(colon + 1, second - colon - 1);
    const std::string path = line.substr(second + 1);
    if (path.empty() || path == "/" || path.find("..") != std::string::npos) continue;
    if (controllers.empty()) consider(cgroup_limit(("/sys/fs/cgroup" + path + "/memory.max").c_str()));
    if (controllers == "memory")
      consider(cgroup_limit(("/sys/fs/cgroup/memory" + path + "/memory.limit_in_bytes").c_str()));
  }
  for (const int resource : {RLIMIT_AS, RLIMIT_DATA}) {
    struct rlimit value {};
    if (::getrlimit(resource, &value) == 0 && value.rlim_cur != RLIM_INFINITY)
      consider(static_cast<double>(value.rlim_cur));
  }
  return limit;
}

std::string memory_shortfall(std::uint64_t spheres, std::uint64_t polyhedra) {
  const double needed = scene_memory_estimate(spheres, polyhedra);
  const double available = available_memory();
  if (available <= 0.0 || needed <= available) return "";
  return fmt::format(
      "this scene needs about {:.3g} GB ({} spheres at ~{:.1f} kB and {} polyhedra at ~{:.1f} kB each, "
      "bench/RESULTS.md), more than the {:.3g} GB of memory this process may use (physical memory, cgroup "
      "and ulimit); reduce the grain count",
      needed / 1e9, spheres, bytes_per_sphere / 1024.0, polyhedra, bytes_per_polyhedron / 1024.0, available / 1e9);
}

}  // namespace rubble
