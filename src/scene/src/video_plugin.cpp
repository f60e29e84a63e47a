// Loads the video plugin (video_plugin.hpp) on first use.

#include "magvine/scene/video_plugin.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "magvine/config.hpp"
#include "magvine/core/error.hpp"

namespace magvine::scene {
namespace {

/// Where the plugin may be, in the order tried.
std::vector<std::filesystem::path> candidates() {
  std::vector<std::filesystem::path> out;
  if (const char* env = std::getenv("MAGVINE_VIDEO_PLUGIN"); env != nullptr && *env != '\0') out.emplace_back(env);
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) out.push_back(exe.parent_path() / "libmagvine_video.so");
#ifdef MAGVINE_VIDEO_PLUGIN_BUILD_PATH
  out.emplace_back(MAGVINE_VIDEO_PLUGIN_BUILD_PATH);
#endif
  return out;
}

/// The loaded plugin, or why it could not be loaded. Process-wide, like the library it stands for: loaded once, never
/// unloaded.
struct Loaded {
  const VideoPlugin* plugin = nullptr;
  std::string problem;
};

Loaded load() {
  Loaded out;
  if (!config::kWithRender) {
    out.problem = "this magvine was built without the render module (cmake -DMAGVINE_WITH_RENDER=ON)";
    return out;
  }
  std::string tried;
  for (const std::filesystem::path& path : candidates()) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
      tried += (tried.empty() ? "" : ", ") + path.string() + " (absent)";
      continue;
    }
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      const char* why = ::dlerror();
      tried += (tried.empty() ? "" : ", ") + path.string() + " (" + (why != nullptr ? why : "cannot load") + ")";
      continue;
    }
    using Entry = const VideoPlugin* (*)();
    const auto entry = reinterpret_cast<Entry>(::dlsym(handle, "magvine_video_plugin"));
    const VideoPlugin* plugin = entry != nullptr ? entry() : nullptr;
    if (plugin == nullptr || plugin->abi != VideoPlugin::kAbi) {
      tried += (tried.empty() ? "" : ", ") + path.string() + " (not this magvine's video plugin)";
      continue;
    }
    out.plugin = plugin;
    return out;
  }
  out.problem =
      "cannot load the video plugin libmagvine_video.so (tried " + tried + "; set MAGVINE_VIDEO_PLUGIN to its path)";
  return out;
}

}  // namespace

bool video_plugin_built() {
  return config::kWithRender;
}

bool preload_video_plugin(bool wanted, const std::string& what) {
  if (!wanted || !video_plugin_built()) return false;
  (void)video_plugin(what);
  return true;
}

const VideoPlugin& video_plugin(const std::string& what) {
  static std::once_flag once;
  static Loaded loaded;
  std::call_once(once, [] { loaded = load(); });
  if (loaded.plugin == nullptr) throw InputError(what, 0, "", loaded.problem);
  return *loaded.plugin;
}

}  // namespace magvine::scene
