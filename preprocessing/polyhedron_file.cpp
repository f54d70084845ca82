#include "preprocessing/polyhedron_file.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "core/input_file.hpp"
#include "preprocessing/random_polyhedron.hpp"

namespace rubble {
namespace {

/// A mesh as read, with the line each vertex and face came from.
struct MeshText {
  std::vector<Vec3> vertices;
  std::vector<std::vector<int>> faces;
  std::vector<int> vertex_lines;
  std::vector<int> face_lines;
};

[[noreturn]] void fail(const std::string& path, int line, const std::string& what) {
  throw std::runtime_error(path + ":" + std::to_string(line) + ": " + what);
}

std::vector<std::string> tokens_of(const std::string& line) {
  std::vector<std::string> tokens;
  std::istringstream in(line.substr(0, line.find('#')));  // '#' starts a comment in both formats
  std::string token;
  while (in >> token) tokens.push_back(token);
  return tokens;
}

double parse_number(const std::string& path, int line, const std::string& token) {
  double value = 0.0;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (error != std::errc() || end != token.data() + token.size() || !std::isfinite(value)) {
    fail(path, line, "expected a finite number, got '" + token + "'");
  }
  return value;
}

// The three coordinates at tokens[first..first+2], read one after the other: the first bad word
// of the line is the one reported (arguments of one call are evaluated in an order each compiler
// chooses: GCC and clang named different words).
Vec3 parse_point(const std::string& path, int line, const std::vector<std::string>& tokens, std::size_t first) {
  const double x = parse_number(path, line, tokens[first]);
  const double y = parse_number(path, line, tokens[first + 1]);
  const double z = parse_number(path, line, tokens[first + 2]);
  return {x, y, z};
}

long parse_integer(const std::string& path, int line, const std::string& token) {
  long value = 0;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (error != std::errc() || end != token.data() + token.size())
    fail(path, line, "expected an integer, got '" + token + "'");
  return value;
}

MeshText read_off(const std::string& path, std::istream& in) {
  MeshText mesh;
  std::string text;
  int line = 0;
  std::vector<std::string> pending;  // tokens not yet consumed
  int pending_line = 0;
  // Next non-empty line's tokens.
  auto next_tokens = [&](const char* expected) -> std::vector<std::string> {
    while (std::getline(in, text)) {
      ++line;
      auto tokens = tokens_of(text);
      if (!tokens.empty()) return tokens;
    }
    fail(path, line, std::string("unexpected end of file, expected ") + expected);
  };
  pending = next_tokens("the OFF header");
  pending_line = line;
  if (pending[0] != "OFF") fail(path, pending_line, "expected 'OFF' as the first word, got '" + pending[0] + "'");
  pending.erase(pending.begin());
  if (pending.empty()) {
    pending = next_tokens("the counts 'vertices faces edges'");
    pending_line = line;
  }
  if (pending.size() < 2) fail(path, pending_line, "expected the counts 'vertices faces [edges]'");
  const long nv = parse_integer(path, pending_line, pending[0]);
  const long nf = parse_integer(path, pending_line, pending[1]);
  if (nv < 4 || nv > max_polyhedron_file_vertices) {
    fail(path, pending_line, "vertex count " + std::to_string(nv) + ", expected 4 .. 10^6");
  }
  if (nf < 4 || nf > 2 * max_polyhedron_file_vertices) {
    fail(path, pending_line, "face count " + std::to_string(nf) + ", expected 4 .. 2x10^6");
  }
  for (long i = 0; i < nv; ++i) {
    const auto tokens = next_tokens("a vertex 'x y z'");
    if (tokens.size() < 3)
      fail(path, line, "expected a vertex 'x y z', got " + std::to_string(tokens.size()) + " numbers");
    mesh.vertices.push_back(parse_point(path, line, tokens, 0));
    mesh.vertex_lines.push_back(line);
  }
  for (long f = 0; f < nf; ++f) {
    const auto tokens = next_tokens("a face 'k i1 ... ik'");
    const long k = parse_integer(path, line, tokens[0]);
    if (k < 3 || static_cast<std::size_t>(k) + 1 > tokens.size()) {
      fail(path, line,
           "expected a face 'k i1 ... ik' with k >= 3 indices, got k = " + std::to_string(k) + " and " +
               std::to_string(tokens.size() - 1) + " indices");
    }
    std::vector<int> face;
    for (long j = 1; j <= k; ++j) {
      const long index = parse_integer(path, line, tokens[static_cast<std::size_t>(j)]);
      if (index < 0 || index >= nv) {
        fail(path, line, "vertex index " + std::to_string(index) + " out of range 0.." + std::to_string(nv - 1));
      }
      face.push_back(static_cast<int>(index));
    }
    mesh.faces.push_back(std::move(face));
    mesh.face_lines.push_back(line);
  }
  return mesh;
}

MeshText read_obj(const std::string& path, std::istream& in) {
  MeshText mesh;
  std::string text;
  int line = 0;
  while (std::getline(in, text)) {
    ++line;
    const auto tokens = tokens_of(text);
    if (tokens.empty()) continue;
    if (tokens[0] == "v") {
      if (tokens.size() < 4) fail(path, line, "expected a vertex 'v x y z'");
      if (mesh.vertices.size() == static_cast<std::size_t>(max_polyhedron_file_vertices)) {
        fail(path, line, "more than 10^6 vertices, the limit of a polyhedron file");
      }
      mesh.vertices.push_back(parse_point(path, line, tokens, 1));
      mesh.vertex_lines.push_back(line);
    } else if (tokens[0] == "f") {
      if (tokens.size() < 4) fail(path, line, "expected a face 'f i j k ...' with at least 3 vertices");
      std::vector<int> face;
      for (std::size_t j = 1; j < tokens.size(); ++j) {
        // "i", "i/t", "i/t/n" or "i//n": the vertex index is before the first '/'.
        const long raw = parse_integer(path, line, tokens[j].substr(0, tokens[j].find('/')));
        const long count = static_cast<long>(mesh.vertices.size());
        const long index = raw < 0 ? count + raw : raw - 1;  // OBJ: 1-based, negative = relative
        if (raw == 0 || index < 0 || index >= count) {
          fail(path, line,
               "vertex index " + std::to_string(raw) + " out of range (" + std::to_string(count) +
                   " vertices defined so far; OBJ indices start at 1)");
        }
        face.push_back(static_cast<int>(index));
      }
      mesh.faces.push_back(std::move(face));
      mesh.face_lines.push_back(line);
    }
    // vn, vt, o, g, s, usemtl, mtllib, l, ...: not needed for a rigid convex shape.
  }
  if (mesh.faces.empty()) fail(path, line, "no faces ('f' lines) in the file");
  return mesh;
}

std::string lower_extension(const std::string& path) {
  const auto dot = path.find_last_of('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

ConvexPolyhedron load_polyhedron_file(const std::string& path, const PolyhedronFileOptions& options,
                                      PolyhedronPose* pose) {
  if (!(options.scale > 0.0) || !std::isfinite(options.scale)) fail(path, 0, "scale must be > 0");
  std::istringstream in;
  try {
    // Regular files of at most 64 MiB (core/input_file.hpp): a link to /dev/zero is refused.
    in.str(read_input_file(path, max_mesh_file_bytes, "polyhedron file"));
  } catch (const InputFileError& e) {
    fail(path, 0, e.reason);
  }
  const std::string ext = lower_extension(path);
  MeshText mesh;
  if (ext == "off") {
    mesh = read_off(path, in);
  } else if (ext == "obj") {
    mesh = read_obj(path, in);
  } else {
    fail(path, 0, "unknown mesh format '." + ext + "', expected .off or .obj");
  }
  for (Vec3& v : mesh.vertices) v *= options.scale;

  // Clockwise files (inward normals) are turned around rather than rejected.
  try {
    if (polyhedron_mass_properties(mesh.vertices, mesh.faces).volume < 0.0) {
      for (auto& face : mesh.faces) std::reverse(face.begin(), face.end());
    }
    // Check the mesh as written, so an error can name the line of the face or vertex at fault.
    (void)make_convex_polyhedron(mesh.vertices, mesh.faces);
  } catch (const PolyhedronError& e) {
    int line = mesh.face_lines.empty() ? 1 : mesh.face_lines.front();
    if (e.vertex >= 0) line = mesh.vertex_lines[static_cast<std::size_t>(e.vertex)];
    if (e.face >= 0) line = mesh.face_lines[static_cast<std::size_t>(e.face)];
    fail(path, line, e.what());
  }

  // Merge coplanar faces, drop the vertices left inside a merged face, renumber.
  std::vector<int> interior;
  auto faces = merge_coplanar_faces(mesh.vertices, mesh.faces, options.merge_angle_degrees, interior);
  std::vector<int> renumber(mesh.vertices.size(), -1);
  std::vector<Vec3> vertices;
  for (auto& face : faces) {
    for (int& v : face) {
      if (renumber[static_cast<std::size_t>(v)] < 0) {
        renumber[static_cast<std::size_t>(v)] = static_cast<int>(vertices.size());
        vertices.push_back(mesh.vertices[static_cast<std::size_t>(v)]);
      }
      v = renumber[static_cast<std::size_t>(v)];
    }
  }
  PolyhedronBuildOptions build;
  build.convexity_tolerance = std::max(1e-6, 2.0 * std::sin(options.merge_angle_degrees * 3.14159265358979 / 180.0));
  try {
    return make_convex_polyhedron(std::move(vertices), std::move(faces), build, pose);
  } catch (const PolyhedronError& e) {
    fail(path, mesh.face_lines.empty() ? 1 : mesh.face_lines.front(),
         std::string("after merging coplanar faces: ") + e.what());
  }
}

}  // namespace rubble
