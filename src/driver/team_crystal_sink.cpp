#include "subslip/driver/team_crystal_sink.hpp"

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "packing.hpp"
#include "subslip/driver/sink_error.hpp"

namespace subslip::driver {

namespace {

// Root's packed values on every rank.
std::vector<double> shared(const parallel::Team& team, Packed packed) {
  team.broadcast(packed.values, 0);
  return std::move(packed.values);
}

}  // namespace

TeamCrystalSink::TeamCrystalSink(const parallel::Team& team, CrystalSink* root_sink)
    : team_(team), root_(root_sink) {}

CaseStatus TeamCrystalSink::status(std::size_t index) const {
  Packed p;
  parallel::on_root(team_, [&] { p.put_integer(static_cast<int>(root_->status(index))); });
  return static_cast<CaseStatus>(Unpacked(shared(team_, p)).integer());
}

StoredCrystalCase TeamCrystalSink::stored_case(std::size_t index) const {
  StoredCrystalCase stored;
  Packed p;
  parallel::on_root(team_, [&] {
    stored = root_->stored_case(index);
    p.put(stored.final_state);
    p.put(stored.stats);
  });
  const std::vector<double> values = shared(team_, p);
  Unpacked u(values);
  u.get(stored.final_state);
  u.get(stored.stats);
  team_.broadcast(stored.failure, 0);
  return stored;
}

std::optional<ResumePoint> TeamCrystalSink::latest_checkpoint(std::size_t index) const {
  std::optional<ResumePoint> found;
  Packed p;
  parallel::on_root(team_, [&] {
    found = root_->latest_checkpoint(index);
    p.put_integer(found ? 1 : 0);
    if (!found) return;
    p.put(found->state);
    p.put_integer(static_cast<std::int64_t>(found->rows));
    p.put(found->last_output);
  });
  const std::vector<double> values = shared(team_, p);
  Unpacked u(values);
  if (u.integer() == 0) return std::nullopt;
  ResumePoint point;
  const std::size_t grain_values = u.get(point.state);
  point.rows = static_cast<std::size_t>(u.integer());
  u.get(point.last_output);
  // This rank's block of the grains (the team's blocks of the case's grains).
  const auto width = static_cast<std::size_t>(point.state.values_per_grain);
  const std::size_t grains = width > 0 ? grain_values / width : 0;
  const parallel::Block block = parallel::block_of(grains, team_.rank(), team_.size());
  point.state.grains.resize(block.count * width);
  team_.scatter_rows(
      team_.is_root() ? std::span<const double>(found->state.grains) : std::span<const double>(),
      point.state.grains, width);
  return point;
}

std::size_t TeamCrystalSink::checkpoint_capacity() const {
  Packed p;
  parallel::on_root(
      team_, [&] { p.put_integer(static_cast<std::int64_t>(root_->checkpoint_capacity())); });
  return static_cast<std::size_t>(Unpacked(shared(team_, p)).integer());
}

void TeamCrystalSink::begin_case(std::size_t index, const ResumePoint* resume) {
  // The root's sink continues after the rows of the checkpoint: its grains are not needed.
  parallel::on_root(team_, [&] { root_->begin_case(index, resume); });
}

void TeamCrystalSink::write_state(const crystal::MacroState& state, const GrainBlock& grains) {
  const FieldArrays all = gathered_fields(team_, grains.fields, grains.range.total);
  const GrainRange whole{0, grains.range.total, grains.range.total};
  parallel::on_root(team_, [&] { root_->write_state(state, GrainBlock{whole, all}); });
}

void TeamCrystalSink::write_checkpoint(const CheckpointBlock& checkpoint,
                                       const crystal::MacroState& last_output) {
  const crystal::AggregateCheckpoint& mine = checkpoint.state;
  const auto width = static_cast<std::size_t>(mine.values_per_grain);
  crystal::AggregateCheckpoint whole;
  if (team_.is_root()) {
    whole = mine;  // the scalars are the same on every rank
    whole.grains.resize(checkpoint.range.total * width);
  }
  team_.gather_rows(mine.grains, whole.grains, width);
  const GrainRange range{0, checkpoint.range.total, checkpoint.range.total};
  parallel::on_root(team_, [&] {
    root_->write_checkpoint(CheckpointBlock{range, whole}, last_output);
  });
}

void TeamCrystalSink::complete_case(const CrystalSummary& summary) {
  parallel::on_root(team_, [&] { root_->complete_case(summary); });
}

void TeamCrystalSink::fail_case(const CrystalSummary& summary, const std::string& why) {
  parallel::on_root(team_, [&] { root_->fail_case(summary, why); });
}

void TeamCrystalSink::end_run() {
  parallel::on_root(team_, [&] { root_->end_run(); });
}

}  // namespace subslip::driver

// ---------------------------------------------------------------- CollectiveCrystalSink

namespace subslip::driver {

CollectiveCrystalSink::CollectiveCrystalSink(const parallel::Team& team, CrystalSink& own_sink)
    : team_(team), own_(own_sink) {}

// Runs `work` on every rank, then agrees: when it threw anywhere, every rank throws the error
// of the lowest rank it failed on (a SinkWriteError as one, so that the command line reports it
// as the failed write it is). Collective.
template <class Work>
void CollectiveCrystalSink::together(Work&& work) const {
  std::string what, action, reason;
  bool write_error = false, failed = false;
  try {
    work();
  } catch (const SinkWriteError& e) {
    failed = write_error = true;
    what = e.what();
    action = e.action;
    reason = e.reason;
  } catch (const std::exception& e) {
    failed = true;
    action = e.what();
  }
  std::array<std::int64_t, 1> first{failed ? team_.rank() : team_.size()};
  team_.min(first);
  if (first[0] == team_.size()) return;
  const int owner = static_cast<int>(first[0]);
  std::vector<double> kind{write_error ? 1.0 : 0.0};
  team_.broadcast(kind, owner);
  team_.broadcast(action, owner);
  team_.broadcast(reason, owner);
  if (kind[0] != 0.0) {
    team_.broadcast(what, owner);
    throw SinkWriteError(what, action, reason);
  }
  parallel::stop_every_rank(team_, action, owner);
}

CrystalSummary CollectiveCrystalSink::roots(const CrystalSummary& summary) const {
  Packed p;
  p.put(summary);
  team_.broadcast(p.values, 0);
  CrystalSummary same;
  Unpacked(p.values).get(same);
  return same;
}

CaseStatus CollectiveCrystalSink::status(std::size_t index) const {
  CaseStatus s{};
  together([&] { s = own_.status(index); });
  return s;
}

StoredCrystalCase CollectiveCrystalSink::stored_case(std::size_t index) const {
  StoredCrystalCase stored;
  together([&] { stored = own_.stored_case(index); });
  return stored;
}

std::optional<ResumePoint> CollectiveCrystalSink::latest_checkpoint(std::size_t index) const {
  std::optional<ResumePoint> found;
  together([&] { found = own_.latest_checkpoint(index); });
  return found;
}

std::size_t CollectiveCrystalSink::checkpoint_capacity() const {
  std::size_t capacity = 0;
  together([&] { capacity = own_.checkpoint_capacity(); });
  return capacity;
}

void CollectiveCrystalSink::begin_case(std::size_t index, const ResumePoint* resume) {
  together([&] { own_.begin_case(index, resume); });
}

void CollectiveCrystalSink::write_state(const crystal::MacroState& state,
                                        const GrainBlock& grains) {
  together([&] { own_.write_state(state, grains); });
}

void CollectiveCrystalSink::write_checkpoint(const CheckpointBlock& checkpoint,
                                             const crystal::MacroState& last_output) {
  together([&] { own_.write_checkpoint(checkpoint, last_output); });
}

void CollectiveCrystalSink::complete_case(const CrystalSummary& summary) {
  const CrystalSummary same = roots(summary);
  together([&] { own_.complete_case(same); });
}

void CollectiveCrystalSink::fail_case(const CrystalSummary& summary, const std::string& why) {
  const CrystalSummary same = roots(summary);
  std::string reason = why;
  team_.broadcast(reason, 0);
  together([&] { own_.fail_case(same, reason); });
}

void CollectiveCrystalSink::end_run() {
  together([&] { own_.end_run(); });
}

}  // namespace subslip::driver
