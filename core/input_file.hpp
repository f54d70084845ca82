#pragma once
// Reading an input file whole (a scene, a polyhedron mesh) with a cap on its size. A special file
// (/dev/zero, a FIFO, a terminal, a socket) or a link to one never ends or blocks: it is refused
// before it is read; so is a regular file larger than the cap, so that a wrong path never makes
// rubble read gigabytes into memory. The caps are documented in docs/scene-file.md ("Limits").
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/input_error.hpp"

namespace rubble {

/// An input file that cannot be read: missing, a folder, a special file, larger than the cap,
/// or an I/O error. what() names the file and the reason (without a "file:line:" prefix).
struct InputFileError : InputError {
  /// Builds what() = "FILE: reason".
  InputFileError(const std::string& file, std::string why) : InputError(file + ": " + why), reason(std::move(why)) {}
  std::string reason;  ///< what is wrong, without the file name
};

/// Largest scene file read, bytes (256 MiB: 10^6 grains written one by one take ~150 MB).
inline constexpr std::uintmax_t max_scene_file_bytes = 256ull << 20;
/// Largest polyhedron mesh file read, bytes (64 MiB: the vertex cap, 10^6 vertices, takes ~40 MB as OFF with its
/// faces).
inline constexpr std::uintmax_t max_mesh_file_bytes = 64ull << 20;

/// Reads `path` whole. It must be a regular file (links are followed) of at most `max_bytes`;
/// `what` names its kind in messages ("scene file", "polyhedron file"). Throws InputFileError.
std::string read_input_file(const std::filesystem::path& path, std::uintmax_t max_bytes, const std::string& what);

}  // namespace rubble
