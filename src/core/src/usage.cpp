#include "magvine/core/usage.hpp"

#include <array>
#include <atomic>
#include <cstddef>

namespace magvine::usage {
namespace {

std::array<std::atomic<std::uint64_t>, static_cast<std::size_t>(Component::kCount)> g_counts{};

}  // namespace

void note(Component c) { g_counts[static_cast<std::size_t>(c)].fetch_add(1, std::memory_order_relaxed); }

std::uint64_t count(Component c) { return g_counts[static_cast<std::size_t>(c)].load(std::memory_order_relaxed); }

void reset() {
  for (auto& c : g_counts) c.store(0, std::memory_order_relaxed);
}

}  // namespace magvine::usage
