#include "core/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <system_error>

namespace rubble {
namespace {

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "is a folder";
  if (S_ISCHR(mode)) return "is a character device";
  if (S_ISBLK(mode)) return "is a block device";
  if (S_ISFIFO(mode)) return "is a FIFO (named pipe)";
  if (S_ISSOCK(mode)) return "is a socket";
  return "is not a regular file";
}

std::string mib(std::uintmax_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

}  // namespace

std::string read_input_file(const std::filesystem::path& path, std::uintmax_t max_bytes, const std::string& what) {
  const std::string name = path.string();
  const auto fail = [&](const std::string& reason) { return InputFileError(name, reason); };
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer; fstat then tells
  // what was opened (no window between a stat and the open for the path to change).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    const int e = errno;
    throw fail("cannot open the " + what + ": " + std::system_category().message(e));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat info {};
  if (::fstat(fd, &info) != 0) throw fail("cannot read the " + what + ": " + std::system_category().message(errno));
  if (!S_ISREG(info.st_mode)) {
    throw fail(kind_of(info.st_mode) + ", expected a " + what + " (a regular file)");
  }
  const auto size = static_cast<std::uintmax_t>(info.st_size);
  if (size > max_bytes) {
    throw fail("the " + what + " has " + std::to_string(size) + " bytes, more than the limit of " + mib(max_bytes));
  }
  std::string text;
  text.resize(static_cast<std::size_t>(size));
  std::size_t done = 0;
  while (true) {
    if (done == text.size()) {
      // The file may have grown since fstat: read on, within the cap.
      if (text.size() >= max_bytes + 1) break;
      text.resize(std::min<std::uintmax_t>(max_bytes + 1, text.size() + 65536));
    }
    const ssize_t n = ::read(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      throw fail("cannot read the " + what + ": " + std::system_category().message(errno));
    }
    if (n == 0) break;
    done += static_cast<std::size_t>(n);
  }
  if (done > max_bytes) {
    throw fail("the " + what + " has more than " + std::to_string(max_bytes) + " bytes, the limit (" + mib(max_bytes) +
               ")");
  }
  text.resize(done);
  return text;
}

}  // namespace rubble
