#include "core/block_runner.h"

#include <fmt/core.h>

#include <stdexcept>

namespace microsim {

std::string BlockRange::to_string() const { return fmt::format("[{}, {})", begin, end); }

BlockRange selected_blocks(const BlockPlan& plan, const std::optional<BlockRange>& selection) {
  if (!selection) return {0, plan.blocks()};
  if (selection->end > plan.blocks() || selection->begin > selection->end)
    throw std::invalid_argument(
        fmt::format("blocks {} outside the run's [0, {})", selection->to_string(), plan.blocks()));
  return *selection;
}

BlockRange shard_range(std::uint64_t blocks, std::uint64_t k, std::uint64_t n) {
  if (n == 0 || k == 0 || k > n) throw std::invalid_argument(fmt::format("shard {}/{}: need 1 <= K <= N", k, n));
  // Shard k starts at floor((k - 1) blocks / n), computed without overflow.
  auto start = [&](std::uint64_t i) {
    return static_cast<std::uint64_t>((static_cast<unsigned __int128>(blocks) * i) / n);
  };
  return {start(k - 1), start(k)};
}

namespace detail {
std::uint64_t blocks_in_flight(int threads) {
  const int workers = threads > 0 ? threads : tbb::this_task_arena::max_concurrency();
  // Enough tokens that no worker waits for the in-order reduction (a few blocks ahead per worker), few
  // enough that the results in flight stay in cache.
  return 4 * std::uint64_t(std::max(workers, 1));
}
}  // namespace detail

}  // namespace microsim
