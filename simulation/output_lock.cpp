#include "simulation/output_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fmt/format.h>
#include <string>
#include <system_error>
#include <utility>

namespace rubble {
namespace {

namespace fs = std::filesystem;

/// The pid written in the lock file, if it holds one (the file is tiny: one line).
std::optional<pid_t> read_owner(int fd) {
  std::array<char, 64> text{};
  const ssize_t n = ::pread(fd, text.data(), text.size() - 1, 0);
  if (n <= 0) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long pid = std::strtol(text.data(), &end, 10);
  if (errno != 0 || end == text.data() || pid <= 0) return std::nullopt;
  return static_cast<pid_t>(pid);
}

std::string system_reason(int error) { return std::system_category().message(error); }

}  // namespace

OutputFolderLock OutputFolderLock::acquire(const fs::path& directory) {
  std::error_code error;
  fs::create_directories(directory, error);
  if (error || !fs::is_directory(directory)) {
    throw OutputFolderError(fmt::format("{}: cannot create the output folder{}", directory.string(),
                                        error ? ": " + error.message() : std::string(" (a file is in the way)")));
  }
  fs::path file = directory / output_lock_name;
  // O_NOFOLLOW: a link planted as the lock file must not make us write a pid into its target.
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) {
    const int e = errno;
    throw OutputFolderError(
        fmt::format("{}: cannot open the output folder's lock file: {}", file.string(), system_reason(e)));
  }
  int status = 0;
  do {
    status = ::flock(fd, LOCK_EX | LOCK_NB);
  } while (status != 0 && errno == EINTR);
  if (status != 0) {
    const int e = errno;
    const std::optional<pid_t> owner = read_owner(fd);
    ::close(fd);
    if (e == EWOULDBLOCK) {
      throw OutputFolderBusy(fmt::format(
          "{}: the output folder is in use by another rubble run ({}; lock file {}). One folder takes one run at "
          "a time: wait for that run to end, stop it, or give another --out",
          directory.string(), owner ? fmt::format("pid {}", *owner) : std::string("pid not yet written"),
          file.string()));
    }
    throw OutputFolderError(fmt::format("{}: cannot lock the output folder: {}", file.string(), system_reason(e)));
  }
  // Ours now. A pid left in the file is that of a run that died holding the lock (the kernel
  // released it): a stale lock, taken over.
  std::optional<pid_t> stale = read_owner(fd);
  if (stale && *stale == ::getpid()) stale.reset();
  const std::string text = fmt::format("{}\n", ::getpid());
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size())) {
    const int e = errno;
    ::close(fd);
    throw OutputFolderError(fmt::format("{}: cannot write the lock file: {}", file.string(), system_reason(e)));
  }
  return OutputFolderLock(std::move(file), fd, stale);
}

OutputFolderLock::OutputFolderLock(OutputFolderLock&& other) noexcept
    : file_(std::move(other.file_)), fd_(std::exchange(other.fd_, -1)), taken_over_from_(other.taken_over_from_) {}

OutputFolderLock& OutputFolderLock::operator=(OutputFolderLock&& other) noexcept {
  if (this != &other) {
    release();
    file_ = std::move(other.file_);
    fd_ = std::exchange(other.fd_, -1);
    taken_over_from_ = other.taken_over_from_;
  }
  return *this;
}

OutputFolderLock::~OutputFolderLock() { release(); }

void OutputFolderLock::release() noexcept {
  if (fd_ < 0) return;
  // Emptied while still locked, so that no later run reads our pid as a stale owner; the
  // close drops the lock.
  [[maybe_unused]] const int ignored = ::ftruncate(fd_, 0);
  ::close(fd_);
  fd_ = -1;
}

}  // namespace rubble
