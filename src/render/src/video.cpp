#include "magvine/render/video.hpp"

#include <unistd.h>

#include <atomic>
#include <string_view>
#include <cmath>
#include <system_error>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"

namespace magvine::render {
namespace {

std::atomic<int> g_serial{0};

/// `<dir>/.<name>.partial-<pid>-<n><ext>`: beside the target (same file system, so the rename is atomic) and with
/// the extension OpenCV picks the container by.
std::filesystem::path partial_name(const std::filesystem::path& target) {
  std::string name(1, '.');  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on a chain of operator+
  name.append(target.stem().string());
  name.append(".partial-");
  name.append(std::to_string(::getpid()));
  name.push_back('-');
  name.append(std::to_string(g_serial++));
  name.append(target.extension().string());
  return target.parent_path() / name;
}

}  // namespace

struct VideoFile::Writer {
  cv::VideoWriter writer;
};

VideoFile::VideoFile(const std::filesystem::path& stem, double fps, int width, int height, Container container)
    : m_width(width), m_height(height) {
  const std::string who = stem.string() + ".mp4";
  if (!(fps > 0.0 && std::isfinite(fps))) throw InputError(who, 0, "fps", "must be > 0");
  if (width < 2 || height < 2) throw InputError(who, 0, "size", "a video needs at least 2 × 2 px");
  m_writer = new Writer;
  struct Choice {
    const char* ext;
    const char* codec;
  };
  for (const Choice c : {Choice{".mp4", "mp4v"}, Choice{".avi", "MJPG"}}) {
    if (container == Container::kAvi && std::string_view(c.ext) == ".mp4") continue;
    std::filesystem::path target = stem;
    target += c.ext;
    const std::filesystem::path temp = partial_name(target);
    const int fourcc = cv::VideoWriter::fourcc(c.codec[0], c.codec[1], c.codec[2], c.codec[3]);
    if (m_writer->writer.open(temp.string(), fourcc, fps, cv::Size(width, height), true)) {
      m_final = target;
      m_temp = temp;
      m_codec = c.codec;
      return;
    }
    std::error_code ec;
    std::filesystem::remove(temp, ec);
  }
  delete m_writer;
  m_writer = nullptr;
  throw InputError(who, 0, "", "OpenCV can open neither an MP4 (mp4v) nor an AVI (MJPG) writer here");
}

VideoFile::~VideoFile() {
  if (m_writer != nullptr) {
    m_writer->writer.release();
    delete m_writer;
  }
  if (!m_finished && !m_temp.empty()) {
    std::error_code ec;
    std::filesystem::remove(m_temp, ec);
  }
}

void VideoFile::write(const cv::Mat& frame) {
  if (m_finished || m_writer == nullptr) throw InputError(m_final.string(), 0, "", "the video is already finished");
  if (frame.type() != CV_8UC3 || frame.cols != m_width || frame.rows != m_height) {
    throw InputError(m_final.string(), 0, "frame",
                     "expected " + std::to_string(m_width) + " × " + std::to_string(m_height) + " BGR, got " +
                         std::to_string(frame.cols) + " × " + std::to_string(frame.rows));
  }
  m_writer->writer.write(frame);
  ++m_frames;
}

std::filesystem::path VideoFile::finish() {
  if (m_finished) return m_final;
  if (m_frames == 0) throw InputError(m_final.string(), 0, "", "a video needs at least one frame");
  m_writer->writer.release();
  std::error_code ec;
  std::filesystem::rename(m_temp, m_final, ec);
  if (ec) throw InputError(m_final.string(), 0, "", "cannot rename the finished video: " + ec.message());
  m_finished = true;
  return m_final;
}

std::string encode_png(const cv::Mat& image, const std::string& what) {
  std::vector<std::uint8_t> bytes;
  if (image.empty() || !cv::imencode(".png", image, bytes)) throw InputError(what, 0, "", "cannot encode the image as PNG");
  return std::string(bytes.begin(), bytes.end());
}

void write_png(const std::filesystem::path& file, const cv::Mat& image) {
  write_file_atomically(file, encode_png(image, file.string()));
}

cv::Mat depth_to_u16(const cv::Mat& depth_m, double range_m) {
  if (depth_m.type() != CV_32F) throw InputError("depth", 0, "", "a depth map must be CV_32F metres");
  if (!(range_m > 0.0 && std::isfinite(range_m))) throw InputError("depth", 0, "range", "must be > 0");
  cv::Mat out(depth_m.rows, depth_m.cols, CV_16U);
  const double scale = 65535.0 / range_m;
  for (int y = 0; y < depth_m.rows; ++y) {
    const auto* in = depth_m.ptr<float>(y);
    auto* o = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < depth_m.cols; ++x) {
      const double level = in[x] > 0.0f ? std::round(std::min(65535.0, in[x] * scale)) : 0.0;
      o[x] = static_cast<std::uint16_t>(std::max(level, in[x] > 0.0f ? 1.0 : 0.0));  // a hit never reads as "none"
    }
  }
  return out;
}

}  // namespace magvine::render
