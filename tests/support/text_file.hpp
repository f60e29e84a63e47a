#pragma once
// The whole of a text file, for tests that edit a bundled scene before loading it.

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace magvine::test {

/// The file's bytes ("" when it cannot be opened: the test then fails on the empty scene).
inline std::string text_of(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace magvine::test
