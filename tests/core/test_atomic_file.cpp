#include "magvine/core/atomic_file.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "magvine/core/error.hpp"

namespace magvine {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("magvine_test_" + name + "_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::size_t count_files(const fs::path& d) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(d)) ++n;
  return n;
}

TEST(AtomicFile, CommitReplacesTarget) {
  const fs::path d = fresh_dir("commit");
  const fs::path f = d / "out.csv";
  write_file_atomically(f, "old\n");
  write_file_atomically(f, "new\n");
  std::ifstream in(f);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), "new\n");
  EXPECT_EQ(count_files(d), 1u);  // no temporary left behind
}

TEST(AtomicFile, AbandonedWriteLeavesNothing) {
  const fs::path d = fresh_dir("abandon");
  const fs::path f = d / "out.csv";
  try {
    AtomicFile out(f);
    out.stream() << "partial";
    throw std::runtime_error("failure mid-write");
  } catch (const std::runtime_error&) {
  }
  EXPECT_FALSE(fs::exists(f));
  EXPECT_EQ(count_files(d), 0u);
}

TEST(AtomicFile, MissingFolderIsInputError) {
  EXPECT_THROW(AtomicFile(fs::path("/nonexistent_magvine_dir/x.csv")), InputError);
}

}  // namespace
}  // namespace magvine
