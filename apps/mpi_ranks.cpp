// microsim: MPI under `microsim run` (mpi_ranks.h).
#include "mpi_ranks.h"

#include "command.h"

#include "core/errors.h"

#include <fmt/core.h>

#include <climits>
#include <cstdlib>
#include <cstdint>
#include <vector>

#ifdef MICROSIM_WITH_MPI
#include <mpi.h>
#endif

namespace microsim::app {
namespace {

std::optional<int> rank_variable(const char* name) {
  const char* value = std::getenv(name);
  if (value == nullptr || *value == '\0') return std::nullopt;
  char* end = nullptr;
  const long v = std::strtol(value, &end, 10);
  if (*end != '\0' || v < 0 || v > INT_MAX) return std::nullopt;
  return int(v);
}

#ifdef MICROSIM_WITH_MPI
int mpi_count(std::size_t bytes) {
  if (bytes > std::size_t(INT_MAX)) throw InternalError(fmt::format("an MPI message of {} bytes (at most {})", bytes, INT_MAX));
  return int(bytes);
}

// MPI_COMM_WORLD as experiment::Ranks: a broadcast is its length, then its bytes; a gather the lengths, then
// MPI_Gatherv of the bytes in rank order.
class MpiRanks final : public experiment::Ranks {
public:
  MpiRanks() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  std::string broadcast(const std::string& message) override {
    std::uint64_t length = message.size();
    MPI_Bcast(&length, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    std::string received = rank_ == 0 ? message : std::string(std::size_t(length), '\0');
    MPI_Bcast(received.data(), mpi_count(received.size()), MPI_BYTE, 0, MPI_COMM_WORLD);
    return received;
  }
  std::vector<std::string> gather(const std::string& part) override {
    const std::uint64_t length = part.size();
    std::vector<std::uint64_t> lengths(rank_ == 0 ? std::size_t(size_) : 0);
    MPI_Gather(&length, 1, MPI_UINT64_T, lengths.data(), 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    std::vector<int> counts, offsets;
    std::size_t total = 0;
    for (const std::uint64_t n : lengths) {
      offsets.push_back(mpi_count(total));
      counts.push_back(mpi_count(std::size_t(n)));
      total += std::size_t(n);
    }
    std::string all(total, '\0');
    MPI_Gatherv(part.data(), mpi_count(part.size()), MPI_BYTE, all.data(), counts.data(), offsets.data(), MPI_BYTE, 0,
                MPI_COMM_WORLD);
    std::vector<std::string> parts;
    for (std::size_t r = 0; r < lengths.size(); ++r) parts.push_back(all.substr(std::size_t(offsets[r]), std::size_t(counts[r])));
    return parts;
  }

private:
  int rank_ = 0, size_ = 1;
};
#endif

}  // namespace

std::optional<LaunchedRank> mpi_launch() {
  for (const auto& [rank, size] : {std::pair{"OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"},
                                   std::pair{"PMIX_RANK", ""}, std::pair{"PMI_RANK", "PMI_SIZE"}}) {
    const std::optional<int> r = rank_variable(rank);
    if (r) return LaunchedRank{rank, *r, *size ? rank_variable(size).value_or(0) : 0};
  }
  return std::nullopt;
}

#ifdef MICROSIM_WITH_MPI
bool mpi_compiled_in() { return true; }

MpiSession::MpiSession() {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  ranks_ = std::make_unique<MpiRanks>();
}

MpiSession::~MpiSession() { MPI_Finalize(); }

void MpiSession::abort(int exit_code) {
  MPI_Abort(MPI_COMM_WORLD, exit_code);
  std::exit(exit_code);  // MPI_Abort does not return; this is for the compiler
}
#else
bool mpi_compiled_in() { return false; }

MpiSession::MpiSession() { throw UsageError("MPI is not compiled in (CMake found no MPI; MICROSIM_MPI)"); }
MpiSession::~MpiSession() = default;
void MpiSession::abort(int exit_code) { std::exit(exit_code); }
#endif

experiment::Ranks& MpiSession::ranks() { return *ranks_; }

}  // namespace microsim::app
