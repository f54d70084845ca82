#pragma once
// ParaView output: one set of VTK XML PolyData files (.vtp, binary appended, zlib-compressed) per
// snapshot, and one .pvd collection per kind of object that lists them over time:
//   spheres.pvd    sphere grains as points (vertex cells) with radius/diameter arrays for glyphs
//   polyhedra.pvd  polyhedral grains as their faces (one polygon per face)
//   contacts.pvd   the contact network: one line per contact point, between the two centres
//                  (for a wall contact, from the grain's centre to the contact point)
//   walls.pvd      plane walls as squares, box walls as their 6 faces
// Arrays and their meaning: docs/postprocessing.md. Written with the VTK library; VTK's headers
// stay in vtk_output.cpp.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Settings of the VTK series.
struct VtkSeriesOptions {
  /// h, s: contact forces are written as impulse / h (mean force over the step). 0 writes the
  /// impulses only.
  double time_step = 0.0;
  /// m, side of the square drawn for a plane wall; 0 picks twice the largest distance from the
  /// wall's origin to a grain's far side in each snapshot.
  double plane_size = 0.0;
  /// s, times of the snapshots an earlier session of the same run already wrote into the folder
  /// (a resumed `rubble run`): the series goes on after them, numbering files from their count,
  /// and the .pvd files keep listing them.
  std::vector<double> earlier_times;
};

/// A ParaView time series being written into a folder (created if missing). Files that a model
/// has no use for are not written (no spheres.pvd without sphere grains, no walls.pvd without
/// walls); contacts.pvd is always written (a snapshot may have no contact: an empty file).
/// Errors (folder or file not writable) throw std::runtime_error naming the path.
class VtkSeries {
 public:
  /// Starts a series for `model` in `directory`. The series reads `model` at every write: a run
  /// with [[inflow]] hands over the model of its bodies in play, which gains bodies between writes
  /// (the kinds of grain written follow its shape tables).
  VtkSeries(const std::filesystem::path& directory, const Model& model, const VtkSeriesOptions& options = {});
  VtkSeries(VtkSeries&&) noexcept;             ///< takes over the series
  VtkSeries& operator=(VtkSeries&&) noexcept;  ///< takes over the series
  ~VtkSeries();

  /// Writes the files of one snapshot (KIND_NNNNNN.vtp, NNNNNN counting the calls from 0) and
  /// rewrites the .pvd collections, so that the series opens in ParaView at any time.
  void write(const State& state, const ContactList& contacts);

  /// The .pvd collections written so far (full paths).
  std::vector<std::filesystem::path> collections() const;
  /// Snapshots written.
  std::size_t snapshot_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rubble
