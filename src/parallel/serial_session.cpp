// The Session of a build without MPI (src/parallel/mpi/ replaces this file in an MPI build).
#include "subslip/parallel/team.hpp"

namespace subslip::parallel {

Session::Session(int&, char**&) {}
Session::~Session() = default;

}  // namespace subslip::parallel
