#include "mpm_video.hpp"

#include "magvine/config.hpp"
#if MAGVINE_WITH_RENDER
#include "magvine/render/particles.hpp"
#include "magvine/render/video.hpp"
#endif

namespace magvine::scene {

std::filesystem::path write_mpm_video(const MpmVideo& video, const std::vector<std::vector<Vec3>>& frames,
                                      const std::vector<std::uint16_t>& body, double radius,
                                      const std::filesystem::path& stem) {
#if MAGVINE_WITH_RENDER
  const render::ParticleView view = render::frame_particles(
      frames, video.view, video.up, static_cast<double>(video.width) / video.height, radius);
  render::VideoFile file(stem, video.fps, video.width, video.height);
  for (const std::vector<Vec3>& f : frames) file.write(render::draw_particles(f, body, view, video.width, video.height));
  return file.finish();
#else
  (void)video, (void)frames, (void)body, (void)radius, (void)stem;
  return {};
#endif
}

}  // namespace magvine::scene
