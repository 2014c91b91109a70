// The team of an MPI build: MPI_COMM_WORLD. Compiled only with SUBSLIP_WITH_MPI (it replaces
// src/parallel/serial_session.cpp).
#include <mpi.h>

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <stdexcept>

#include "subslip/parallel/team.hpp"

namespace subslip::parallel {

namespace {

int as_int(std::size_t n) {
  if (n > static_cast<std::size_t>(INT_MAX))
    throw std::length_error("MPI message of more than INT_MAX values");
  return static_cast<int>(n);
}

class WorldTeam final : public Team {
 public:
  WorldTeam() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }

  void sum(std::span<ExactSum> sums) const override {
    if (size_ == 1) return;
    std::vector<std::int64_t> words(sums.size() * ExactSum::kWords);
    auto out = words.begin();
    for (auto& s : sums) {
      s.normalize();
      out = std::copy(s.words().begin(), s.words().end(), out);
    }
    sum(words);
    auto in = words.begin();
    for (auto& s : sums) {
      std::copy(in, in + ExactSum::kWords, s.words().begin());
      in += ExactSum::kWords;
      s.normalize();
    }
  }
  void sum(std::span<std::int64_t> v) const override {
    MPI_Allreduce(MPI_IN_PLACE, v.data(), as_int(v.size()), MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  }
  void max(std::span<double> v) const override {
    MPI_Allreduce(MPI_IN_PLACE, v.data(), as_int(v.size()), MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  }
  void min(std::span<std::int64_t> v) const override {
    MPI_Allreduce(MPI_IN_PLACE, v.data(), as_int(v.size()), MPI_INT64_T, MPI_MIN, MPI_COMM_WORLD);
  }
  std::vector<double> all_gather(std::span<const double> mine) const override {
    std::vector<double> all(mine.size() * static_cast<std::size_t>(size_));
    MPI_Allgather(mine.data(), as_int(mine.size()), MPI_DOUBLE, all.data(), as_int(mine.size()),
                  MPI_DOUBLE, MPI_COMM_WORLD);
    return all;
  }
  void broadcast(std::vector<double>& values, int root) const override {
    auto n = static_cast<std::int64_t>(values.size());
    MPI_Bcast(&n, 1, MPI_INT64_T, root, MPI_COMM_WORLD);
    values.resize(static_cast<std::size_t>(n));
    MPI_Bcast(values.data(), as_int(values.size()), MPI_DOUBLE, root, MPI_COMM_WORLD);
  }
  void broadcast(std::string& text, int root) const override {
    auto n = static_cast<std::int64_t>(text.size());
    MPI_Bcast(&n, 1, MPI_INT64_T, root, MPI_COMM_WORLD);
    text.resize(static_cast<std::size_t>(n));
    MPI_Bcast(text.data(), as_int(text.size()), MPI_CHAR, root, MPI_COMM_WORLD);
  }
  void gather_rows(std::span<const double> mine, std::span<double> all,
                   std::size_t) const override {
    const std::vector<int> counts = value_counts(mine.size());
    MPI_Gatherv(mine.data(), as_int(mine.size()), MPI_DOUBLE, all.data(), counts.data(),
                offsets(counts).data(), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  }
  void scatter_rows(std::span<const double> all, std::span<double> mine,
                    std::size_t) const override {
    const std::vector<int> counts = value_counts(mine.size());
    MPI_Scatterv(all.data(), counts.data(), offsets(counts).data(), MPI_DOUBLE, mine.data(),
                 as_int(mine.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  }
  std::vector<double> exchange(std::span<const double> values, std::span<const std::size_t> to,
                               std::span<const std::size_t> from) const override {
    std::size_t received = 0;
    for (std::size_t n : from) received += n;
    std::vector<double> out(received);
    std::vector<MPI_Request> requests;
    requests.reserve(2 * static_cast<std::size_t>(size_));
    // Non-blocking both ways: ranks that send each other large blocks would wait forever in
    // blocking sends.
    const auto post = [&](std::span<const std::size_t> counts, auto&& each) {
      std::size_t at = 0;
      for (int q = 0; q < size_; ++q) {
        const std::size_t n = counts[static_cast<std::size_t>(q)];
        if (n > 0) each(q, at, as_int(n), requests.emplace_back());
        at += n;
      }
    };
    post(from, [&](int q, std::size_t at, int n, MPI_Request& r) {
      MPI_Irecv(out.data() + at, n, MPI_DOUBLE, q, kExchangeTag, MPI_COMM_WORLD, &r);
    });
    post(to, [&](int q, std::size_t at, int n, MPI_Request& r) {
      MPI_Isend(values.data() + at, n, MPI_DOUBLE, q, kExchangeTag, MPI_COMM_WORLD, &r);
    });
    MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
    return out;
  }
  void send(std::span<const double> values, int to) const override {
    MPI_Send(values.data(), as_int(values.size()), MPI_DOUBLE, to, kTag, MPI_COMM_WORLD);
  }
  std::vector<double> receive(int from) const override {
    MPI_Status status;
    MPI_Probe(from, kTag, MPI_COMM_WORLD, &status);
    int count = 0;
    MPI_Get_count(&status, MPI_DOUBLE, &count);
    std::vector<double> values(static_cast<std::size_t>(count));
    MPI_Recv(values.data(), count, MPI_DOUBLE, from, kTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    return values;
  }
  [[noreturn]] void abort(int exit_code) const override {
    MPI_Abort(MPI_COMM_WORLD, exit_code);
    std::abort();  // (MPI_Abort does not return)
  }
  const void* mpi_communicator() const override { return &world_; }

 private:
  // Every rank's count of values, on every rank.
  std::vector<int> value_counts(std::size_t mine) const {
    std::vector<int> counts(static_cast<std::size_t>(size_));
    const int n = as_int(mine);
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
    return counts;
  }
  static std::vector<int> offsets(const std::vector<int>& counts) {
    std::vector<int> at(counts.size(), 0);
    long long sum = 0;
    for (std::size_t r = 0; r < counts.size(); ++r) {
      at[r] = as_int(static_cast<std::size_t>(sum));
      sum += counts[r];
    }
    return at;
  }
  static constexpr int kTag = 18;          // send and receive
  static constexpr int kExchangeTag = 19;  // exchange
  int rank_ = 0, size_ = 1;
  MPI_Comm world_ = MPI_COMM_WORLD;
};

}  // namespace

Session::Session(int& argc, char**& argv) {
  // Started without a launcher, this is a run of one process that needs no MPI at all: an MPI
  // singleton would spawn Open MPI's daemon (a third of a second) and change nothing else.
  if (!launched_by_mpi()) return;
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (!initialised) {
    // Only the main thread calls MPI (OpenMP threads compute grains between collectives).
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  }
  owned_ = std::make_unique<WorldTeam>();
  team_ = owned_.get();
}

Session::~Session() {
  if (!owned_) return;
  int finalised = 0;
  MPI_Finalized(&finalised);
  if (!finalised) MPI_Finalize();
}

}  // namespace subslip::parallel
