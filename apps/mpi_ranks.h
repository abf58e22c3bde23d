// microsim: the command line under an MPI launcher (`mpirun -n P microsim run`, `srun`): the one place that
// touches MPI. Built with MPI when CMake found it (option MICROSIM_MPI; MICROSIM_WITH_MPI), else a run started
// by a launcher is refused (every process would run the whole experiment into the same directory). The
// library sees only experiment::Ranks (src/experiment/ranks.h).
#pragma once

#include "experiment/ranks.h"

#include <memory>
#include <optional>
#include <string>

namespace microsim::app {

// Whether this binary was built with MPI.
bool mpi_compiled_in();

// How an MPI launcher started this process, read from its environment: the variable that names the rank
// (OMPI_COMM_WORLD_RANK: Open MPI's mpirun; PMIX_RANK: PMIx, e.g. `srun --mpi=pmix`; PMI_RANK: MPICH, PMI-2),
// the rank, and the number of processes when the launcher says (OMPI_COMM_WORLD_SIZE, PMI_SIZE; 0: unknown).
// nullopt: not started by a launcher.
struct LaunchedRank {
  std::string variable;
  int rank = 0;
  int size = 0;
};
std::optional<LaunchedRank> mpi_launch();

// MPI for the life of the object (MPI_Init_thread, funneled: only the main thread calls MPI; MPI_Finalize in
// the destructor). Throws UsageError when MPI is not compiled in.
class MpiSession {
public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  experiment::Ranks& ranks();
  // MPI_Abort: every rank of the job ends, mpirun exits with `exit_code`.
  [[noreturn]] void abort(int exit_code);

private:
  std::unique_ptr<experiment::Ranks> ranks_;
};

}  // namespace microsim::app
