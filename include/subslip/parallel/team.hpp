// The processes that share a run (MPI ranks, or one process without MPI) and the few
// collective operations the drivers need of them. The core computes against this interface
// only: it is compiled with or without MPI, and a serial run is a team of one.
//
// Every operation is collective: every rank of the team calls it, in the same order, with the
// same sizes. The results are the same on every rank, and do not depend on the number of ranks
// (sums are exact: parallel/exact_sum.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <exception>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/parallel/exact_sum.hpp"

namespace subslip::parallel {

// Grains [offset, offset + count) of `total`: the share of one rank.
struct Block {
  std::size_t offset = 0;
  std::size_t count = 0;
  std::size_t total = 0;
};

// The contiguous block of `total` items that rank `rank` of `ranks` holds: the first
// total % ranks ranks hold one more.
Block block_of(std::size_t total, int rank, int ranks);

class Team {
 public:
  virtual ~Team() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  bool is_root() const { return rank() == 0; }

  // In place, over the ranks: exact sums, integer sums, maxima, minima.
  virtual void sum(std::span<ExactSum> sums) const = 0;
  virtual void sum(std::span<std::int64_t> values) const = 0;
  virtual void max(std::span<double> values) const = 0;  // (values must not be NaN)
  virtual void min(std::span<std::int64_t> values) const = 0;
  // Every rank's `mine` (the same length on every rank), in rank order, on every rank.
  virtual std::vector<double> all_gather(std::span<const double> mine) const = 0;
  // Root's values on every rank (resized to root's length).
  virtual void broadcast(std::vector<double>& values, int root) const = 0;
  virtual void broadcast(std::string& text, int root) const = 0;
  // Rows of `width` values: every rank's block of rows (rank order) into `all` on root (which
  // holds total x width values; other ranks pass an empty span).
  virtual void gather_rows(std::span<const double> mine, std::span<double> all,
                           std::size_t width) const = 0;
  // The inverse: root's `all` into every rank's block of rows `mine`.
  virtual void scatter_rows(std::span<const double> all, std::span<double> mine,
                            std::size_t width) const = 0;
  // Every rank sends `to[q]` of `values` to rank q, in rank order (values for rank 0 first),
  // and receives `from[q]` values from rank q; returns them in rank order. `from` must match
  // what the others send (each rank knows what it gets from whom).
  virtual std::vector<double> exchange(std::span<const double> values,
                                       std::span<const std::size_t> to,
                                       std::span<const std::size_t> from) const = 0;
  // Point to point (the only non-collective operations): `values` to rank `to`, and what rank
  // `from` sends (of any length).
  virtual void send(std::span<const double> values, int to) const = 0;
  virtual std::vector<double> receive(int from) const = 0;
  // Stops every rank of the run at once (after a failure only one rank knows of): never
  // returns.
  [[noreturn]] virtual void abort(int exit_code) const = 0;
  // The team's MPI communicator (a pointer to its MPI_Comm) for libraries that take one
  // (parallel HDF5); null for a team without MPI.
  virtual const void* mpi_communicator() const { return nullptr; }
};

// A team of one process: every operation is the identity.
const Team& serial_team();

// Thrown on the other ranks when work only the root does (files, checks) failed: the root
// reports the failure, every other rank stops quietly with the same exit status.
struct StoppedByRoot : std::runtime_error {
  StoppedByRoot(const std::string& why, int code) : std::runtime_error(why), exit_code(code) {}
  int exit_code;
};

// The exit status a failure gives (the command line's table); 1 when none is given.
using ExitCodeOf = int (*)(const std::exception_ptr&);

// Set when on_root has told the other ranks of the root's failure, which it then rethrows: the
// other ranks stop by themselves. A failure on the root without it must stop them (abort).
inline bool& root_failure_shared() {
  static bool shared = false;
  return shared;
}

// Stops every rank for `what`, a failure one rank met and has broadcast to all: the root
// throws it (as a shared failure: the others stop by themselves), the others StoppedByRoot.
// Called on every rank.
[[noreturn]] inline void stop_every_rank(const Team& team, const std::string& what) {
  if (!team.is_root()) throw StoppedByRoot(what, 1);
  root_failure_shared() = true;
  throw std::runtime_error(what);
}

// The same for a failure rank `owner` met and broadcast: the message names that rank.
[[noreturn]] inline void stop_every_rank(const Team& team, const std::string& what, int owner) {
  stop_every_rank(team, what + " (MPI rank " + std::to_string(owner) + ")");
}

// Runs `work` on the root only, then tells every rank whether it succeeded: when it threw, the
// root rethrows its exception and every other rank throws StoppedByRoot, so that no rank waits
// in a collective the root never reaches. Collective.
template <class Work>
void on_root(const Team& team, Work&& work, ExitCodeOf exit_code_of = nullptr) {
  std::exception_ptr failure;
  std::vector<double> code{0.0};
  std::string why;
  if (team.is_root()) {
    try {
      work();
    } catch (const std::exception& e) {
      failure = std::current_exception();
      why = e.what();
      code[0] = exit_code_of != nullptr ? exit_code_of(failure) : 1;
    }
  }
  if (team.size() > 1) {
    team.broadcast(code, 0);
    team.broadcast(why, 0);
  }
  if (failure) {
    root_failure_shared() = true;
    std::rethrow_exception(failure);
  }
  if (code[0] != 0.0) throw StoppedByRoot(why, static_cast<int>(code[0]));
}

// Whether an MPI launcher (mpirun, mpiexec, srun) started this process, from the environment it
// sets (OMPI_COMM_WORLD_SIZE, PMI_SIZE, PMIX_RANK), and, if so, as one of how many ranks (0
// when it does not say).
bool launched_by_mpi();
int launched_ranks();

// The run's team for the lifetime of this object: in a build with MPI and a process started
// by an MPI launcher (mpirun, mpiexec, srun), the MPI world (initialised here, finalised in the
// destructor); else the serial team, and MPI is never started (a process started without a
// launcher is a run of one rank, exactly as a build without MPI runs). A build without MPI
// started by a launcher as one of several ranks stops at once (exit 2, the root says why):
// every rank would run the whole job into the same file.
class Session {
 public:
  Session(int& argc, char**& argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  const Team& team() const { return *team_; }

 private:
  std::unique_ptr<Team> owned_;  // the MPI world team (none without MPI)
  const Team* team_ = &serial_team();
};

}  // namespace subslip::parallel
