#pragma once
/// Batches split over machines (docs/cluster.md): a shard is one machine's share of a batch of numbered items (the
/// trials of `magvine trials`, the starts of `magvine design`), the items whose index ≡ I (mod N). Each shard writes
/// shard.json; a merge checks that the shards are one batch, each once, and joins them into what one machine writes.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace magvine::scene {

/// Shard `index` of `count`: the items whose index ≡ index (mod count).
struct Shard {
  int index = 0;
  int count = 1;
};
/// The most shards a batch may have.
inline constexpr int kMaxShards = 100000;

/// "I/N" (digits only, 0 ≤ I < N ≤ kMaxShards) as a Shard; InputError naming `option` otherwise.
Shard parse_shard(const std::string& text, const char* option = "--shard");

/// The indices of a batch of `items` that are the shard's, ascending. InputError when the shard is not I/N.
std::vector<int> shard_items(std::size_t items, const Shard& shard);

/// What ties shards to one batch besides their options: a 64-bit FNV-1a hash (Fowler, Noll, Vo) of the scene file's
/// bytes and magvine's version (another version may give other results). Files the scene names (a mesh, a graph, a
/// segmentation) are not hashed. InputError when the file cannot be read.
std::uint64_t scene_fingerprint(const std::filesystem::path& scene_file);

}  // namespace magvine::scene
