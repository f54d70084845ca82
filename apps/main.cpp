// rubble: Contact Dynamics for gravitational aggregates. Subcommands live in cmd_<name>.cpp.
#include <cstdlib>
#include <exception>
#include <new>
#include <iostream>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "apps/commands.hpp"
#include "core/hdf5_io.hpp"

int main(int argc, char** argv) {
  // Before any HDF5 call: no library clean-up at exit, which crashes on a file whose close failed
  // (disk full); every file is closed by its owner first (core/hdf5_io.hpp).
  rubble::hdf5::skip_library_cleanup_at_exit();
#if defined(__GLIBC__)
  // glibc gives the top of its heap back to the system only past a trim threshold, and raises that
  // threshold to the size of every large block freed (its "dynamic mmap threshold"): a run's
  // contact list and solver copy, tens of MB each step, left as much free heap resident. A fixed
  // 1 MiB threshold returns it as it is freed: the peak resident memory of 1e5 settling spheres
  // falls by a fifth (bench/RESULTS.md, "Memory per grain"). `rubble run` raises both thresholds
  // again for small scenes (cmd_run.cpp, serve_step_blocks_from_heap). Results do not depend on
  // either.
  mallopt(M_TRIM_THRESHOLD, 1 << 20);
#endif
  CLI::App app{"rubble: Contact Dynamics (Moreau-Jean + NLGS) for rubble-pile asteroids"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "rubble " RUBBLE_VERSION);
  rubble::apps::register_run_command(app);
  rubble::apps::register_export_command(app);
  rubble::apps::register_pack_command(app);
  rubble::apps::register_gravity_command(app);
  rubble::apps::register_post_command(app);
  rubble::apps::register_fclib_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    // A subcommand's own exit code (2 bad input, 3 numerical failure, 128+signal ...): the
    // subcommand has already reported the problem.
    return e.get_exit_code();
  } catch (const CLI::ParseError& e) {
    // CLI11 prints usage errors; bad arguments are bad input.
    const int code = app.exit(e);
    return code == 0 ? 0 : rubble::apps::exit_bad_input;
  } catch (const std::bad_alloc&) {
    std::cerr << "rubble: error: out of memory: the input needs more memory than this process may use "
                 "(physical memory, cgroup or ulimit)\n";
    return rubble::apps::exit_failure;
  } catch (const std::exception& e) {
    std::cerr << "rubble: error: " << e.what() << "\n";
    return rubble::apps::exit_failure;
  }
  return rubble::apps::exit_ok;
}
