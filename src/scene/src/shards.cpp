// Shards of a batch (magvine/scene/shards.hpp) and shard.json (shard_files.hpp).

#include "magvine/scene/shards.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <fstream>
#include <optional>
#include <string_view>

#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "shard_files.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

Shard parse_shard(const std::string& text, const char* option) {
  Shard shard;
  const std::size_t slash = text.find('/');
  const auto whole = [](std::string_view digits, int& value) {
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    return !digits.empty() && std::isdigit(static_cast<unsigned char>(digits.front())) && error == std::errc() &&
           end == digits.data() + digits.size();
  };
  const std::string_view view(text);
  if (slash == std::string::npos || !whole(view.substr(0, slash), shard.index) ||
      !whole(view.substr(slash + 1), shard.count) || shard.count < 1 || shard.count > kMaxShards ||
      shard.index >= shard.count) {
    throw InputError(option, 0, "",
                     printf_string("must be I/N with 0 <= I < N <= %d, e.g. 0/4 (got '", kMaxShards) + text + "')");
  }
  return shard;
}

std::vector<int> shard_items(std::size_t items, const Shard& shard) {
  if (shard.count < 1 || shard.count > kMaxShards || shard.index < 0 || shard.index >= shard.count) {
    throw InputError("--shard", 0, "", printf_string("%d/%d: must be I/N with 0 <= I < N", shard.index, shard.count));
  }
  std::vector<int> mine;
  for (auto i = static_cast<std::size_t>(shard.index); i < items; i += static_cast<std::size_t>(shard.count)) {
    mine.push_back(static_cast<int>(i));
  }
  return mine;
}

namespace {

/// 64-bit FNV-1a (Fowler, Noll, Vo): a stable hash, the same on every machine and build.
std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 14695981039346656037ULL;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ULL;
  }
  return h;
}

}  // namespace

std::uint64_t scene_fingerprint(const std::filesystem::path& scene_file) {
  return fnv1a(read_text_file(scene_file.string(), "the scene") + "\n" + MAGVINE_VERSION);
}

namespace detail {

nlohmann::json shard_header(const ShardKind& kind, const std::string& scene, std::uint64_t fingerprint,
                            const Shard& shard) {
  nlohmann::json j;
  j[kind.marker] = 1;
  j["scene"] = scene;
  j["scene_fnv1a"] = printf_string("%016llx", static_cast<unsigned long long>(fingerprint));
  j["shard"] = shard.index;
  j["shards"] = shard.count;
  return j;
}

std::vector<ShardItem> read_shards(const std::vector<std::filesystem::path>& dirs, const ShardKind& kind,
                                   std::size_t (*batch_size)(const nlohmann::json& first), nlohmann::json& first) {
  if (dirs.empty()) throw InputError(kind.command, 0, "", "give the shards' folders");
  std::optional<nlohmann::json> head;
  std::string first_dir;
  std::vector<std::string> seen;  // the folder each shard came from
  std::vector<ShardItem> all;
  std::vector<std::pair<std::string, std::string>> keys = {{"scene_fnv1a", "scene file bytes or magvine version"}};
  keys.insert(keys.end(), kind.batch_keys.begin(), kind.batch_keys.end());
  keys.emplace_back("shards", "shard count");
  for (const std::filesystem::path& dir : dirs) {
    const std::filesystem::path file = dir / "shard.json";
    std::ifstream in(file);
    if (!in) throw InputError(file.string(), 0, "", "no shard here (" + kind.writer + " writes shard.json)");
    try {
      const nlohmann::json j = nlohmann::json::parse(in);
      if (!j.contains(kind.marker)) {
        throw InputError(file.string(), 0, "", "not a shard of " + kind.writer + " (no " + kind.marker + ")");
      }
      const int count = j.at("shards").get<int>();
      const int index = j.at("shard").get<int>();
      if (count < 1 || count > kMaxShards || index < 0 || index >= count) {
        throw InputError(file.string(), 0, "shard",
                         printf_string("%d/%d is not a shard I/N, 0 <= I < N", index, count));
      }
      if (!head) {
        head = j;
        first_dir = dir.string();
        seen.assign(static_cast<std::size_t>(count), std::string());
      }
      for (const auto& [key, what] : keys) {
        if (j.at(key) != head->at(key)) {
          throw InputError(file.string(), 0, key, "another batch than " + first_dir + ": not the same " + what);
        }
      }
      std::string& from = seen[static_cast<std::size_t>(index)];
      if (!from.empty()) {
        throw InputError(file.string(), 0, "shard",
                         printf_string("shard %d/%d given twice (also in ", index, count) + from + ")");
      }
      from = dir.string();
      for (const nlohmann::json& item : j.at(kind.items)) {
        const int i = item.at("index").get<int>();
        if (i < 0 || i % count != index) {
          throw InputError(file.string(), 0, kind.items,
                           kind.item + printf_string(" %d is not in shard %d/%d", i, index, count));
        }
        all.push_back({item, file.string()});
      }
    } catch (const nlohmann::json::exception& e) {
      throw InputError(file.string(), 0, "", std::string("not a shard file: ") + e.what());
    }
  }
  for (std::size_t i = 0; i < seen.size(); ++i) {
    if (seen[i].empty())
      throw InputError(kind.command, 0, "", printf_string("shard %zu/%zu is missing", i, seen.size()));
  }
  const auto index_of = [](const ShardItem& item) { return item.json.at("index").get<int>(); };
  std::stable_sort(all.begin(), all.end(),
                   [&](const ShardItem& a, const ShardItem& b) { return index_of(a) < index_of(b); });
  // The whole batch: every index once.
  std::size_t total = 0;
  try {
    total = batch_size(*head);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(first_dir + "/shard.json", 0, "", std::string("not a shard file: ") + e.what());
  }
  bool whole = all.size() == total;
  for (std::size_t i = 0; whole && i < all.size(); ++i) whole = index_of(all[i]) == static_cast<int>(i);
  if (!whole) {
    throw InputError(kind.command, 0, "",
                     printf_string("the shards hold %zu ", all.size()) + kind.items +
                         printf_string(", not the batch's %zu each once", total));
  }
  first = *head;
  return all;
}

}  // namespace detail

}  // namespace magvine::scene
