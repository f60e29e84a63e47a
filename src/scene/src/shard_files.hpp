#pragma once
// shard.json, the file every shard writes (trials and design starts alike; magvine/scene/shards.hpp), and its reader.

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "magvine/scene/shards.hpp"

namespace magvine::scene::detail {

/// The kind of a batch's shards: its marker key in shard.json, the key of its items, and the words of its messages.
struct ShardKind {
  std::string marker;   ///< "magvine_trials_shard": the key that says what the file is
  std::string command;  ///< "trials merge": where a merge's own errors come from
  std::string writer;   ///< "magvine trials --shard I/N": what writes such a shard
  std::string items;    ///< "trials": the key of the items' array (each item has an "index")
  std::string item;     ///< "trial"
  /// Keys of shard.json that must be equal in every shard of a batch, and how to say that they differ ("--repeats").
  /// The scene's fingerprint (scene_fnv1a) and the shard count are always among them.
  std::vector<std::pair<std::string, std::string>> batch_keys;
};

/// shard.json's header: the kind's marker, the scene file, its fingerprint, the shard and the count; the caller adds
/// its batch keys and the items.
nlohmann::json shard_header(const ShardKind& kind, const std::string& scene, std::uint64_t fingerprint,
                            const Shard& shard);

/// An item of a shard and the file it came from (for messages).
struct ShardItem {
  nlohmann::json json;
  std::string file;
};

/// The items of one batch from its shards' folders, in index order. `batch_size` gives the batch's number of items from
/// the first shard.json read (which `first` receives). InputError (one line) when a folder has no shard.json of the
/// kind or a malformed one, the shards belong to different batches, a shard is missing or given twice, an item is not
/// in its shard, or the items are not the batch's, each once.
std::vector<ShardItem> read_shards(const std::vector<std::filesystem::path>& dirs, const ShardKind& kind,
                                   std::size_t (*batch_size)(const nlohmann::json& first), nlohmann::json& first);

}  // namespace magvine::scene::detail
