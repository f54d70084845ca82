#pragma once
// FCLib local frictional-contact problems on disk (Acary, Brémond, Dubois et al., "FCLIB: a
// collection of discrete 3D frictional contact problems"; layout of FCLib 3.0 local problems):
//   /fclib_local/W/{m,n,nz,nzmax,p,i,x}   sparse W; nz = -2 compressed row, -1 compressed column,
//                                           nz >= 0 triplet (i = rows, p = columns, nz entries)
//   /fclib_local/vectors/{q,mu}           q (3 nc), mu (nc)
//   /fclib_local/spacedim                 3
// and a solution file with the datasets `r` and `u` (3 nc each).
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/input_error.hpp"
#include "nlgs_solver/local_problem.hpp"

namespace rubble {

/// A file that cannot be read or written as an FCLib problem; the message names the file and
/// the dataset and says what was expected. An InputError (core/input_error.hpp); a solution that
/// cannot be written throws it too, so `rubble fclib` catches it around the write itself (exit 4).
struct FclibFileError : InputError {
  using InputError::InputError;
};

/// How W is stored in a file (the `nz` field).
enum class SparseStorage {
  compressed_row,     ///< nz = -2: p = row pointers (m + 1), i = column indices
  compressed_column,  ///< nz = -1: p = column pointers (n + 1), i = row indices
  triplet,            ///< nz >= 0: i = row, p = column of each of the nz entries
};

/// What an FCLib file holds besides the problem itself.
struct FclibFileInfo {
  std::string title;                                      ///< /fclib_local/info/title ("" when absent)
  std::string description;                                ///< /fclib_local/info/description ("" when absent)
  SparseStorage storage = SparseStorage::compressed_row;  ///< how W was stored
};

/// Reads the local problem of an FCLib file; W is converted to CSR with entries of a row sorted
/// by column (duplicates of a triplet file are summed). Checks sizes (m = n = 3 nc = |q|,
/// |mu| = nc, spacedim = 3), index ranges and finiteness; throws FclibFileError otherwise.
LocalProblem read_fclib_local(const std::filesystem::path& file, FclibFileInfo* info = nullptr);

/// Writes a problem as an FCLib local problem (spacedim 3, info/title) with W in `storage`.
/// Overwrites the file. Throws FclibFileError when the file cannot be written.
void write_fclib_local(const std::filesystem::path& file, const LocalProblem& problem,
                       SparseStorage storage = SparseStorage::compressed_row, const std::string& title = "");

/// Writes a solution: datasets `r` and `u` (float64, 3 nc each). Overwrites the file.
void write_fclib_solution(const std::filesystem::path& file, const std::vector<double>& r,
                          const std::vector<double>& u);

/// Reads the datasets `r` and `u` of a solution file written by write_fclib_solution.
void read_fclib_solution(const std::filesystem::path& file, std::vector<double>& r, std::vector<double>& u);

}  // namespace rubble
