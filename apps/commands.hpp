#pragma once
// The `rubble` command line: one subcommand per file (cmd_<name>.cpp), registered in main.cpp.
#include <CLI/CLI.hpp>

#include <string>

namespace rubble::apps {

/// Exit codes shared by every subcommand.
enum ExitCode : int {
  exit_ok = 0,                 ///< success
  exit_failure = 1,            ///< an unexpected error (I/O, internal)
  exit_bad_input = 2,          ///< the input (scene, file, arguments) is invalid
  exit_numerical_failure = 3,  ///< a non-finite or runaway result (run state, field, impulses, metrics)
  exit_output_failure = 4,     ///< the output could not be written (disk full, I/O error); see docs/exit-codes.md
};

/// Writes a scene file's text to `output` ("-": standard output) for the subcommand `command`
/// (pack, export) and says how to run it; exit_output_failure with the reason if it cannot.
int write_scene_text(const std::string& command, const std::string& output, const std::string& text);

/// `rubble run [SCENE] [--out DIR]`: runs a scene (the built-in default without SCENE).
void register_run_command(CLI::App& app);
/// `rubble pack KIND ... -o SCENE.toml`: writes a scene file with an initial packing.
void register_pack_command(CLI::App& app);
/// `rubble gravity IN.h5 ...`: self-gravity of a particle file.
void register_gravity_command(CLI::App& app);
/// `rubble post RUN.h5 ...`: metrics, plots and ParaView files of a run.
void register_post_command(CLI::App& app);
/// `rubble export RUN.h5 [--snapshot K] -o SCENE.toml`: a saved state written as a scene file.
void register_export_command(CLI::App& app);
/// `rubble fclib FILE.hdf5 ...`: solves an FCLib local frictional-contact problem by NLGS.
void register_fclib_command(CLI::App& app);

}  // namespace rubble::apps
