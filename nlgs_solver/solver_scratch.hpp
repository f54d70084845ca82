#pragma once
// The solver's memory kept from step to step (simulation's StepWorkspace holds one).
#include "nlgs_solver/compact_problem.hpp"

namespace rubble {

/// Arrays that solve_contacts rebuilds every step, kept by the caller so that their memory is
/// reused: the compact copy of a 1 487-grain deposit is ~0.75 MB, which glibc serves by a fresh
/// mmap above its 128 kB threshold, so a step that allocated it anew had the kernel zero-fill
/// ~200 pages (bench/RESULTS.md, "The solver's arrays kept from step to step"). Nothing in it is
/// read before it is written: results do not depend on it.
struct SolverScratch {
  CompactProblem compact;  ///< the sweeps' copy of the problem (gather_compact_problem refills it)
};

}  // namespace rubble
