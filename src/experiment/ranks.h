// experiment: the processes an experiment's rounds are split over (`mpirun -n P microsim run`), seen through a
// small communicator-like interface that the command line passes in (apps/mpi_ranks.h wraps MPI; SingleProcess
// is one process, no MPI). Rank 0 is the root: it plans, decides every round, combines the ranks' parts and
// writes; the other ranks only run the parts of the rounds the root sends them (split_rounds.h). The library
// never initialises MPI, never reads its globals and never aborts: errors are thrown, the caller decides.
#pragma once

#include <string>
#include <vector>

namespace microsim::experiment {

class Ranks {
public:
  virtual ~Ranks() = default;
  virtual int rank() const = 0;  // 0-based; 0 is the root
  virtual int size() const = 0;
  // The root's `message` on every rank (collective: every rank calls it; the others' argument is ignored).
  virtual std::string broadcast(const std::string& message) = 0;
  // Every rank's `part` on the root, in rank order (collective; the other ranks receive an empty vector).
  virtual std::vector<std::string> gather(const std::string& part) = 0;
};

// One process: the root alone.
class SingleProcess final : public Ranks {
public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  std::string broadcast(const std::string& message) override { return message; }
  std::vector<std::string> gather(const std::string& part) override { return {part}; }
};

}  // namespace microsim::experiment
