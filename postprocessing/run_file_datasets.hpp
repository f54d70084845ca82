#pragma once
// The datasets of a run file's /model group, of /run/<name> and of one /snapshots/NNNNNN group,
// written by RunFile (run_file.cpp). Internal to postprocessing/run_file*.cpp; the layout is docs/output-format.md's
// (run_file.hpp is the public API).
#include <filesystem>
#include <string>
#include <string_view>

#include "core/contact.hpp"
#include "core/hdf5_io.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "postprocessing/run_file.hpp"

namespace rubble::run_file_detail {

/// Every numeric dataset of the run file carries HDF5's Fletcher-32 checksum, verified on every
/// read: a flipped byte is reported by the reader instead of read as a wrong number. It is also
/// shuffled and deflated at level 4: snapshots shrink to about a third (docs/output-format.md,
/// "Compression"; levels above 4 gain a few percent for twice the time).
inline constexpr hdf5::Storage storage{true, 4, true};

/// Writes the `units` attribute of dataset `name` of `parent` (docs/output-format.md: SI, "1" for
/// dimensionless numbers, counts and indices).
void units(hid_t parent, const std::string& name, std::string_view value, const std::filesystem::path& file);

/// Writes /run/<name> (a scalar with its units and source, "auto" or "scene"), replacing an
/// existing one. Throws std::invalid_argument for an empty name or one with '/' or '.'.
void write_run_parameter(hid_t run_group, const RunParameter& parameter, const std::filesystem::path& path);

/// Writes /model: the body count attributes, the per-body datasets, then the groups polyhedra,
/// planes, boxes, materials and contact_laws, in this order.
void write_model(hid_t file_id, const Model& model, const std::filesystem::path& file);

/// Writes the bodies' position, orientation (w, x, y, z), velocity and angular velocity into the
/// snapshot group `group`.
void write_state(hid_t group, const State& state, const std::filesystem::path& file);

/// Writes the contact_* datasets of every contact point of the list into the snapshot group `group`;
/// contact_angular_impulse only when `angular_impulses` (a law of the model resists rotation).
void write_contacts(hid_t group, const ContactList& contacts, bool angular_impulses, const std::filesystem::path& file);

/// Whether a run file's /model/contact_laws (the group `model`) has a law with rolling or twisting
/// resistance (false for a file written before those parameters were stored).
bool laws_resist_rotation(hid_t model, const std::filesystem::path& file);

}  // namespace rubble::run_file_detail
