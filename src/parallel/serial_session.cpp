// The Session of a build without MPI (src/parallel/mpi/ replaces this file in an MPI build).
#include <cstdio>
#include <cstdlib>

#include "subslip/parallel/team.hpp"

namespace subslip::parallel {

Session::Session(int&, char**&) {
  if (launched_ranks() <= 1) return;
  const char* rank = std::getenv("OMPI_COMM_WORLD_RANK");
  if (rank == nullptr) rank = std::getenv("PMI_RANK");
  if (rank == nullptr || std::atoi(rank) == 0) {
    std::fprintf(stderr,
                 "subslip: error: this subslip was built without MPI (SUBSLIP_WITH_MPI): run it "
                 "without mpirun, or build it with Open MPI (libopenmpi-dev)\n");
  }
  std::exit(2);
}
Session::~Session() = default;

}  // namespace subslip::parallel
