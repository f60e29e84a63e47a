#include "magvine/core/atomic_file.hpp"

#include <unistd.h>

#include <atomic>
#include <system_error>

#include "magvine/core/error.hpp"

namespace magvine {

namespace {
std::atomic<unsigned> g_temp_counter{0};  // distinct temporary names for concurrent writers in one process
}

AtomicFile::AtomicFile(std::filesystem::path target) : m_target(std::move(target)) {
  m_temp = m_target;
  m_temp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(g_temp_counter++);
  m_stream.open(m_temp, std::ios::out | std::ios::trunc | std::ios::binary);
  if (!m_stream) {
    throw InputError(m_target.string(), 0, "", "cannot create output file (does the folder exist and is it writable?)");
  }
  m_stream.precision(17);
}

AtomicFile::~AtomicFile() {
  if (!m_committed) {
    m_stream.close();
    std::error_code ec;
    std::filesystem::remove(m_temp, ec);
  }
}

void AtomicFile::commit() {
  m_stream.flush();
  const bool ok = static_cast<bool>(m_stream);
  m_stream.close();
  if (!ok) throw InputError(m_target.string(), 0, "", "write failed (disk full?)");
  std::error_code ec;
  std::filesystem::rename(m_temp, m_target, ec);
  if (ec) throw InputError(m_target.string(), 0, "", "cannot rename temporary file into place: " + ec.message());
  m_committed = true;
}

void create_output_directory(const std::filesystem::path& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir.string(), 0, "", "cannot create output folder: " + ec.message());
}

void write_file_atomically(const std::filesystem::path& target, const std::string& content) {
  AtomicFile f(target);
  f.stream() << content;
  f.commit();
}

}  // namespace magvine
