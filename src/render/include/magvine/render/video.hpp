#pragma once
/// Video and image files, written atomically (a temporary file beside the target, renamed when complete): a crash
/// or an error never leaves a truncated video or image under the final name.

#include <filesystem>
#include <string>

#include <opencv2/core/mat.hpp>

namespace magvine::render {

/// A video being written: MP4 (mp4v) where OpenCV's FFmpeg backend can write it, else AVI (MJPG), which OpenCV
/// writes without any codec library. The file appears under its final name only at finish().
class VideoFile {
 public:
  /// Which containers to try: MP4 then AVI, or AVI only (what a machine without an MP4 writer gets).
  enum class Container { kMp4OrAvi, kAvi };
  /// `stem`: the target without extension (".mp4" or ".avi" is appended). InputError when neither can be opened,
  /// or for a non-positive fps or size.
  VideoFile(const std::filesystem::path& stem, double fps, int width, int height,
            Container container = Container::kMp4OrAvi);
  VideoFile(const VideoFile&) = delete;
  VideoFile& operator=(const VideoFile&) = delete;
  /// Removes the partial file unless finish() succeeded.
  ~VideoFile();

  /// Appends a CV_8UC3 (BGR) frame of the video's size; InputError otherwise.
  void write(const cv::Mat& frame);
  /// Closes the file and renames it to its final name, which it returns. InputError on failure or with no frames.
  std::filesystem::path finish();

  const std::filesystem::path& path() const { return m_final; }  ///< the final name (.mp4 or .avi)
  std::string codec() const { return m_codec; }                  ///< "mp4v" or "MJPG"
  int frames() const { return m_frames; }

 private:
  struct Writer;
  Writer* m_writer = nullptr;
  std::filesystem::path m_final;
  std::filesystem::path m_temp;
  std::string m_codec;
  int m_width = 0;
  int m_height = 0;
  int m_frames = 0;
  bool m_finished = false;
};

/// The PNG bytes of an image (8- or 16-bit). InputError naming `what` (the file it is for) on failure.
std::string encode_png(const cv::Mat& image, const std::string& what);
/// Writes an image (PNG, 8- or 16-bit) atomically. InputError naming the file on failure.
void write_png(const std::filesystem::path& file, const cv::Mat& image);

/// A z-depth map [m] (CV_32F, 0 = no hit) as 16-bit grey levels: level = round(depth / range · 65535), clamped;
/// 0 stays 0 (no hit). C3VD's convention with range 0.1 m (Bobrow et al., Med. Image Anal. 2023).
cv::Mat depth_to_u16(const cv::Mat& depth_m, double range_m);

}  // namespace magvine::render
