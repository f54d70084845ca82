// polyhedron_check FILE: reads a polyhedron file with preprocessing/polyhedron_file.hpp exactly
// as a scene would, and reports like `rubble run` does: the error on stderr and exit code 2 for
// bad input, a one-line summary and exit 0 otherwise. No `rubble` subcommand reads polyhedron
// files yet (scene files accept spheres only), so the CLI corpus drives this stand-in for the
// polyhedron cases; when scene files gain polyhedra, those cases move to `rubble run`.
#include <exception>
#include <iostream>

#include "preprocessing/polyhedron_file.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: polyhedron_check FILE.off|FILE.obj\n";
    return 2;
  }
  try {
    const rubble::ConvexPolyhedron shape = rubble::load_polyhedron_file(argv[1]);
    std::cout << argv[1] << ": " << shape.vertices.size() << " vertices, " << shape.faces.size() << " faces\n";
  } catch (const std::exception& e) {
    std::cerr << "polyhedron_check: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
