#include <algorithm>
#include <cstdlib>
#include <stdexcept>

#include "subslip/parallel/team.hpp"

namespace subslip::parallel {

Block block_of(std::size_t total, int rank, int ranks) {
  const auto r = static_cast<std::size_t>(rank), n = static_cast<std::size_t>(ranks);
  const std::size_t base = total / n, extra = total % n;
  return {r * base + std::min(r, extra), base + (r < extra ? 1 : 0), total};
}

namespace {

class SerialTeam final : public Team {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  void sum(std::span<ExactSum>) const override {}
  void sum(std::span<std::int64_t>) const override {}
  void max(std::span<double>) const override {}
  void min(std::span<std::int64_t>) const override {}
  std::vector<double> all_gather(std::span<const double> mine) const override {
    return {mine.begin(), mine.end()};
  }
  void broadcast(std::vector<double>&, int) const override {}
  void broadcast(std::string&, int) const override {}
  void gather_rows(std::span<const double> mine, std::span<double> all,
                   std::size_t) const override {
    std::copy(mine.begin(), mine.end(), all.begin());
  }
  void scatter_rows(std::span<const double> all, std::span<double> mine,
                    std::size_t) const override {
    std::copy(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(mine.size()), mine.begin());
  }
  std::vector<double> exchange(std::span<const double> values, std::span<const std::size_t>,
                               std::span<const std::size_t>) const override {
    return {values.begin(), values.end()};
  }
  // (a team of one has no other rank to talk to)
  void send(std::span<const double>, int) const override {
    throw std::logic_error("serial team: no rank to send to");
  }
  std::vector<double> receive(int) const override {
    throw std::logic_error("serial team: no rank to receive from");
  }
  [[noreturn]] void abort(int exit_code) const override { std::exit(exit_code); }
};

}  // namespace

bool launched_by_mpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(name) != nullptr) return true;
  return false;
}

int launched_ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
    if (const char* value = std::getenv(name)) return std::atoi(value);
  }
  return 0;
}

const Team& serial_team() {
  static const SerialTeam team;
  return team;
}

}  // namespace subslip::parallel
