#pragma once
// The one base class of every error in what a user gave rubble: a scene file, an input file, a
// checkpoint, a saved state to branch from, an output folder in use. The command line turns any
// InputError into exit code 2 (docs/exit-codes.md) by catching this base, so a new kind of input
// error only has to derive from it; which standard exception it derives from no longer decides
// the exit code. A std::runtime_error, so that code catching that (pybind11's RuntimeError
// mapping included) sees the same exception as before.
#include <stdexcept>

namespace rubble {

/// Something wrong with the input, found before or while reading it. what() names the input.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace rubble
