// Checkpoint files: the streamed atomic write, the retention of old ones, listing and loading
// (checkpoint.hpp); the bytes themselves are checkpoint_format.cpp's and checkpoint_codec.hpp's.
#include "simulation/checkpoint.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <fmt/format.h>
#include <utility>

#include "simulation/checkpoint_codec.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

using namespace checkpoint_codec;

[[noreturn]] void io_error(const fs::path& path, const std::string& what) {
  throw std::runtime_error(fmt::format("{}: {}: {}", path.string(), what, std::strerror(errno)));
}

/// Streams bytes to a new file through a fixed 1 MiB buffer, keeping the CRC-64 of everything
/// written so far: a checkpoint then costs 1 MiB of memory instead of a copy of its payload (the
/// payload is ~300 bytes a contact, hundreds of MB for 10^5 grains). Closes the file if
/// destroyed before finish() (an exception on the way).
class FileSink {
 public:
  explicit FileSink(const fs::path& path) : path_(path), buffer_(std::size_t{1} << 20) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) io_error(path, "cannot create the checkpoint file");
  }
  FileSink(const FileSink&) = delete;
  FileSink& operator=(const FileSink&) = delete;
  ~FileSink() {
    if (fd_ >= 0) ::close(fd_);
  }
  void append(const std::byte* p, std::size_t n) {
    while (n > 0) {
      const std::size_t room = std::min(n, buffer_.size() - used_);
      std::memcpy(buffer_.data() + used_, p, room);
      used_ += room;
      p += room;
      n -= room;
      if (used_ == buffer_.size()) flush();
    }
  }
  /// Writes what is buffered, then the CRC-64 of every byte written (not covered by itself), and
  /// fsyncs and closes the file, so that after the rename the data are on disk before the name is.
  void finish() {
    flush();
    const std::uint64_t crc = crc_;
    write_all(reinterpret_cast<const std::byte*>(&crc), sizeof crc);
    const int fd = std::exchange(fd_, -1);
    if (::fsync(fd) != 0) {
      const int saved = errno;
      ::close(fd);
      errno = saved;
      io_error(path_, "cannot fsync the checkpoint file");
    }
    if (::close(fd) != 0) io_error(path_, "cannot close the checkpoint file");
  }

 private:
  void flush() {
    crc_ = crc64(std::span<const std::byte>(buffer_.data(), used_), crc_);
    write_all(buffer_.data(), used_);
    used_ = 0;
  }
  void write_all(const std::byte* p, std::size_t n) {
    std::size_t written = 0;
    while (written < n) {
      const ssize_t k = ::write(fd_, p + written, n - written);
      if (k < 0) {
        if (errno == EINTR) continue;
        io_error(path_, "cannot write the checkpoint file");
      }
      written += static_cast<std::size_t>(k);
    }
  }
  const fs::path& path_;
  std::vector<std::byte> buffer_;
  std::size_t used_ = 0;
  std::uint64_t crc_ = 0;
  int fd_ = -1;
};

/// fsync of a folder makes a rename inside it durable (POSIX leaves it otherwise unspecified).
void sync_folder(const fs::path& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) io_error(folder, "cannot open the checkpoint folder");
  const int status = ::fsync(fd);
  ::close(fd);
  if (status != 0 && errno != EINVAL) io_error(folder, "cannot fsync the checkpoint folder");
}

bool is_checkpoint_name(const std::string& name) {
  return name.size() == 5 + 12 + 5 && name.starts_with("step-") && name.ends_with(".ckpt") &&
         std::all_of(name.begin() + 5, name.begin() + 17, [](char c) { return c >= '0' && c <= '9'; });
}

/// The checkpoint streamed to `file` (header, payload, CRC), fsynced and closed.
void write_checkpoint_file(const fs::path& file, const CheckpointView& checkpoint) {
  const std::uint64_t payload_bytes = payload_size(checkpoint);
  FileSink sink(file);
  Writer out(sink);
  put_header(out, payload_bytes);
  put_payload(out, checkpoint);
  sink.finish();
}

}  // namespace

fs::path checkpoint_folder(const fs::path& output_directory) { return output_directory / "checkpoints"; }

fs::path write_checkpoint(const fs::path& folder, const Checkpoint& checkpoint, int keep, std::int64_t keep_every) {
  return write_checkpoint(folder, checkpoint_view(checkpoint), keep, keep_every);
}

std::int64_t checkpoint_step(const fs::path& file) {
  const std::string name = file.filename().string();
  if (!is_checkpoint_name(name)) return -1;
  return std::stoll(name.substr(5, 12));
}

std::vector<fs::path> set_aside_checkpoints_after(const fs::path& folder, std::int64_t step) {
  std::vector<fs::path> moved;
  for (const fs::path& file : list_checkpoints(folder)) {
    if (checkpoint_step(file) <= step) continue;
    fs::path aside = file;
    aside += ".superseded";
    std::error_code error;
    fs::rename(file, aside, error);
    if (!error) moved.push_back(aside);
  }
  return moved;
}

fs::path write_checkpoint(const fs::path& folder, const CheckpointView& checkpoint, int keep, std::int64_t keep_every) {
  keep = std::max(keep, 1);
  fs::create_directories(folder);
  const std::string name = fmt::format("step-{:012}.ckpt", checkpoint.state.step);
  fs::path final_path = folder / name;
  const fs::path temporary = folder / (name + ".tmp");
  try {
    write_checkpoint_file(temporary, checkpoint);
  } catch (...) {
    // A partial temporary (disk full, I/O error) is never read; removing it gives its space back.
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw;
  }
  if (::rename(temporary.c_str(), final_path.c_str()) != 0)
    io_error(final_path, "cannot rename the checkpoint into place");
  sync_folder(folder);

  // Only now, with the new checkpoint durable, drop the old ones (and stray temporaries).
  // Newest first: the newest `keep` stay; of the older ones, with keep_every > 0, the first
  // (lowest step) of each interval of keep_every steps stays too.
  const std::vector<fs::path> all = list_checkpoints(folder);
  for (std::size_t k = static_cast<std::size_t>(keep); k < all.size(); ++k) {
    if (keep_every > 0) {
      const std::int64_t interval = checkpoint_step(all[k]) / keep_every;
      const bool first_of_interval = k + 1 == all.size() || checkpoint_step(all[k + 1]) / keep_every != interval;
      if (first_of_interval) continue;
    }
    std::error_code ignored;
    fs::remove(all[k], ignored);
  }
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string file = entry.path().filename().string();
    if (file.ends_with(".ckpt.tmp")) {
      std::error_code ignored;
      fs::remove(entry.path(), ignored);
    }
  }
  return final_path;
}

Checkpoint read_checkpoint(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw CheckpointError(file.string() + ": cannot open the checkpoint file");
  // Read at the file's size in one go (growing a vector byte by byte would take twice the memory).
  std::error_code error;
  const std::uintmax_t size = fs::file_size(file, error);
  if (error) throw CheckpointError(file.string() + ": cannot read the checkpoint file: " + error.message());
  std::vector<char> raw(static_cast<std::size_t>(size));
  in.read(raw.data(), static_cast<std::streamsize>(raw.size()));
  if (in.gcount() != static_cast<std::streamsize>(raw.size())) {
    throw CheckpointError(file.string() + ": cannot read the checkpoint file (it changed size while being read)");
  }
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(raw.data()), raw.size());
  return deserialize_checkpoint(bytes, file.string());
}

std::vector<fs::path> list_checkpoints(const fs::path& folder) {
  std::vector<fs::path> files;
  std::error_code error;
  if (!fs::is_directory(folder, error)) return files;
  for (const auto& entry : fs::directory_iterator(folder, error)) {
    if (is_checkpoint_name(entry.path().filename().string())) files.push_back(entry.path());
  }
  // Zero-padded step numbers: names sort by step.
  std::sort(files.begin(), files.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename() > b.filename(); });
  return files;
}

LoadedCheckpoint load_newest_checkpoint(const fs::path& folder) {
  LoadedCheckpoint loaded;
  for (const fs::path& file : list_checkpoints(folder)) {
    try {
      loaded.checkpoint = read_checkpoint(file);
      loaded.file = file;
      return loaded;
    } catch (const CheckpointError& error) {
      loaded.rejected.emplace_back(error.what());
    }
  }
  std::string message = folder.string() + ": no usable checkpoint";
  if (loaded.rejected.empty()) message += " (no step-*.ckpt file)";
  for (const std::string& reason : loaded.rejected) message += "\n  rejected " + reason;
  throw CheckpointError(message);
}

RestWatch save_rest_watch(const RestDetector& detector) {
  RestWatch watch;
  watch.armed = detector.armed;
  watch.window_open = detector.window_start.has_value();
  watch.window_start = detector.window_start.value_or(0.0);
  watch.reference_coordination = detector.reference_coordination;
  watch.reference_pairs = detector.reference_pairs;
  watch.last_failure = static_cast<std::uint8_t>(detector.last_failure);
  watch.last_speed = detector.last_speed;
  watch.last_coordination_change = detector.last_coordination_change;
  watch.last_contact_change = detector.last_contact_change;
  watch.history.assign(detector.history.begin(), detector.history.end());
  watch.decay_window = detector.decay_window;
  return watch;
}

void restore_rest_watch(const RestWatch& watch, RestDetector& detector) {
  detector.armed = watch.armed;
  detector.window_start.reset();
  if (watch.window_open) detector.window_start = watch.window_start;
  detector.reference_coordination = watch.reference_coordination;
  detector.reference_pairs = watch.reference_pairs;
  detector.last_failure = static_cast<RestCondition>(watch.last_failure);
  detector.last_speed = watch.last_speed;
  detector.last_coordination_change = watch.last_coordination_change;
  detector.last_contact_change = watch.last_contact_change;
  detector.history.assign(watch.history.begin(), watch.history.end());
  detector.decay_window = watch.decay_window;
}

}  // namespace rubble
