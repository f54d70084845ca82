// simulation/output_lock: one owner per output folder, stale locks taken over, the lock file's
// content. (Two real processes: tests/apps/one_run_per_folder.sh.)
#include "simulation/output_lock.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace rubble {
namespace {

namespace fs = std::filesystem;

fs::path fresh(const std::string& name) {
  const fs::path folder = fs::temp_directory_path() / ("rubble_test_lock_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(folder);
  return folder;
}

std::string content(const fs::path& file) {
  std::ifstream in(file);
  std::string text;
  std::getline(in, text);
  return text;
}

// flock conflicts between two open file descriptions even within one process, so a second
// acquire here is a second writer; released, the folder is free again and the file is empty.
TEST(OutputFolderLock, OneOwnerAtATimeAndTheOwnersPidInTheFile) {
  const fs::path folder = fresh("owner");
  {
    const OutputFolderLock lock = OutputFolderLock::acquire(folder);
    EXPECT_TRUE(fs::is_directory(folder));
    EXPECT_EQ(content(lock.file()), std::to_string(::getpid()));
    EXPECT_FALSE(lock.taken_over_from().has_value());
    try {
      OutputFolderLock::acquire(folder);
      FAIL() << "a second owner was let in";
    } catch (const OutputFolderBusy& e) {
      EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(::getpid()) + ";"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(fs::file_size(folder / output_lock_name), 0u);
  const OutputFolderLock again = OutputFolderLock::acquire(folder);
  EXPECT_FALSE(again.taken_over_from().has_value());
  fs::remove_all(folder);
}

// A pid left in an unlocked file is a run that died holding the lock: taken over, and named.
TEST(OutputFolderLock, AStaleLockIsTakenOverAndNamed) {
  const fs::path folder = fresh("stale");
  fs::create_directories(folder);
  std::ofstream(folder / output_lock_name) << "999999999\n";
  const OutputFolderLock lock = OutputFolderLock::acquire(folder);
  ASSERT_TRUE(lock.taken_over_from().has_value());
  EXPECT_EQ(*lock.taken_over_from(), 999999999);
  EXPECT_EQ(content(lock.file()), std::to_string(::getpid()));
  fs::remove_all(folder);
}

// A file where the folder should be is not a folder: refused with the reason.
TEST(OutputFolderLock, AFileInTheWayIsAnError) {
  const fs::path path = fresh("file");
  std::ofstream(path) << "not a folder";
  EXPECT_THROW(OutputFolderLock::acquire(path), OutputFolderError);
  fs::remove_all(path);
}

}  // namespace
}  // namespace rubble
