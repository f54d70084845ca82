#pragma once
// One run per output folder. `rubble run` (run_scene) takes an exclusive lock on its output folder
// before it opens, creates or truncates anything there, and holds it until the run file is
// closed; a second writer is refused with the owner's pid instead of truncating the first run's
// run.h5 under it (docs/checkpoints.md, "One run per output folder").
//
// The lock is flock(2) on DIR/rubble.lock, whose content is the owner's pid. The kernel drops a
// flock when its holder dies (SIGKILL, crash, lost process), so a lock left by a dead run is
// never held: the next run takes it over and says whose it was. The file itself is never
// deleted: unlinking a lock file lets a third process create a new file and lock it while a
// second still holds the old inode, and both would think they own the folder. A run that ends
// empties the file instead; an empty (or absent) file means "free".
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <sys/types.h>

#include "core/input_error.hpp"

namespace rubble {

/// The output folder is held by another live process. what() names the folder, the lock file
/// and the owner's pid when it is known. An input error (exit code 2): the folder given is taken.
struct OutputFolderBusy : InputError {
  using InputError::InputError;
};

/// The output folder cannot be created or its lock file cannot be opened (a file in the way,
/// no permission, read-only file system). what() names the path and the system's reason. An input
/// error (exit code 2): it happens before anything is written, on the folder the user named.
struct OutputFolderError : InputError {
  using InputError::InputError;
};

/// Name of the lock file inside an output folder.
inline constexpr const char* output_lock_name = "rubble.lock";

/// An exclusive lock on a run's output folder, held while the object lives (move-only).
class OutputFolderLock {
 public:
  /// Creates `directory` if needed and locks it. Throws OutputFolderBusy when another process
  /// holds the lock, OutputFolderError when the folder or its lock file cannot be made.
  static OutputFolderLock acquire(const std::filesystem::path& directory);

  OutputFolderLock(OutputFolderLock&& other) noexcept;             ///< takes over the lock
  OutputFolderLock& operator=(OutputFolderLock&& other) noexcept;  ///< releases this lock, takes the other
  OutputFolderLock(const OutputFolderLock&) = delete;
  OutputFolderLock& operator=(const OutputFolderLock&) = delete;
  ~OutputFolderLock();  ///< empties the lock file and releases the lock

  /// The lock file (DIR/rubble.lock).
  const std::filesystem::path& file() const { return file_; }
  /// The pid a stale lock named (a run that died without releasing it), when one was taken over.
  std::optional<pid_t> taken_over_from() const { return taken_over_from_; }

 private:
  OutputFolderLock(std::filesystem::path file, int fd, std::optional<pid_t> taken_over_from)
      : file_(std::move(file)), fd_(fd), taken_over_from_(taken_over_from) {}
  void release() noexcept;

  std::filesystem::path file_;
  int fd_ = -1;
  std::optional<pid_t> taken_over_from_;
};

}  // namespace rubble
