#include "subslip/driver/team_crystal_sink.hpp"

#include <bit>
#include <cstdint>
#include <vector>

namespace subslip::driver {

namespace {

using crystal::Mat3;

// The values the root found, flattened to doubles for a broadcast (integers bit for bit).
class Packed {
 public:
  std::vector<double> values;

  void put(double v) { values.push_back(v); }
  void put_integer(std::int64_t v) { values.push_back(std::bit_cast<double>(v)); }
  void put(const Mat3& m) { values.insert(values.end(), m.data(), m.data() + 9); }
  void put(const crystal::MacroState& m) {
    put(m.time);
    put(m.segment_time);
    put_integer(m.segment);
    for (const Mat3* t : {&m.velocity_gradient, &m.deformation_gradient, &m.strain, &m.stress})
      put(*t);
  }
  void put(const crystal::AggregateStats& s) {
    for (long v : {s.increments, s.substeps, s.grain_steps, s.grain_solves, s.newton_iterations,
                   s.cutbacks, s.rejected, s.mixed_iterations})
      put_integer(v);
    put(s.wall_seconds);
  }
  // Everything of a checkpoint but its grains.
  void put(const crystal::AggregateCheckpoint& c) {
    put_integer(c.position.segment);
    put_integer(c.position.increment);
    put(c.position.segment_time);
    put(c.position.next_step);
    put(c.macro);
    put(c.segment_start_stress);
    put_integer(c.free_velocity_gradient.size());
    for (int k = 0; k < c.free_velocity_gradient.size(); ++k) put(c.free_velocity_gradient(k));
    put(c.stats);
    put_integer(c.values_per_grain);
    put_integer(static_cast<std::int64_t>(c.grains.size()));
  }
};

class Unpacked {
 public:
  explicit Unpacked(const std::vector<double>& v) : values_(v) {}

  double real() { return values_.at(next_++); }
  std::int64_t integer() { return std::bit_cast<std::int64_t>(real()); }
  void get(Mat3& m) {
    for (int k = 0; k < 9; ++k) m.data()[k] = real();
  }
  void get(crystal::MacroState& m) {
    m.time = real();
    m.segment_time = real();
    m.segment = static_cast<int>(integer());
    for (Mat3* t : {&m.velocity_gradient, &m.deformation_gradient, &m.strain, &m.stress}) get(*t);
  }
  void get(crystal::AggregateStats& s) {
    for (long* v : {&s.increments, &s.substeps, &s.grain_steps, &s.grain_solves,
                    &s.newton_iterations, &s.cutbacks, &s.rejected, &s.mixed_iterations})
      *v = integer();
    s.wall_seconds = real();
  }
  // A checkpoint but its grains; returns the number of its grain values.
  std::size_t get(crystal::AggregateCheckpoint& c) {
    c.position.segment = static_cast<int>(integer());
    c.position.increment = integer();
    c.position.segment_time = real();
    c.position.next_step = real();
    get(c.macro);
    get(c.segment_start_stress);
    c.free_velocity_gradient.resize(integer());
    for (int k = 0; k < c.free_velocity_gradient.size(); ++k) c.free_velocity_gradient(k) = real();
    get(c.stats);
    c.values_per_grain = static_cast<int>(integer());
    return static_cast<std::size_t>(integer());
  }

 private:
  const std::vector<double>& values_;
  std::size_t next_ = 0;
};

// Root's packed values on every rank.
std::vector<double> shared(const parallel::Team& team, Packed packed) {
  team.broadcast(packed.values, 0);
  return std::move(packed.values);
}

// The per-grain fields of the whole aggregate, gathered on the root from every rank's block.
class GatheredFields final : public crystal::GrainFields {
 public:
  // Collective: every rank passes its block's fields; `grains` is the aggregate's (root only).
  GatheredFields(const parallel::Team& team, const crystal::GrainFields& mine, std::size_t grains)
      : grains_(static_cast<int>(grains)), slips_(mine.slip_count()) {
    const auto gather = [&](std::vector<double>& all, std::size_t width, auto fill) {
      std::vector<double> block(static_cast<std::size_t>(mine.grain_count()) * width);
      (mine.*fill)(block.data());
      if (team.is_root()) all.resize(grains * width);
      team.gather_rows(block, all, width);
    };
    const auto n = static_cast<std::size_t>(slips_);
    gather(stress_, 6, &crystal::GrainFields::stress);
    gather(orientation_, 9, &crystal::GrainFields::orientation);
    gather(slip_, n, &crystal::GrainFields::slip);
    gather(slip_rate_, n, &crystal::GrainFields::slip_rate);
    gather(crss_, n, &crystal::GrainFields::crss);
    gather(ratio_, n, &crystal::GrainFields::ratio);
    gather(subloading_ratio_, n, &crystal::GrainFields::subloading_ratio);
  }
  int grain_count() const override { return grains_; }
  int slip_count() const override { return slips_; }
  void stress(double* out) const override { copy(stress_, out); }
  void orientation(double* out) const override { copy(orientation_, out); }
  void slip(double* out) const override { copy(slip_, out); }
  void slip_rate(double* out) const override { copy(slip_rate_, out); }
  void crss(double* out) const override { copy(crss_, out); }
  void ratio(double* out) const override { copy(ratio_, out); }
  void subloading_ratio(double* out) const override { copy(subloading_ratio_, out); }

 private:
  static void copy(const std::vector<double>& v, double* out) {
    std::copy(v.begin(), v.end(), out);
  }
  int grains_, slips_;
  std::vector<double> stress_, orientation_, slip_, slip_rate_, crss_, ratio_, subloading_ratio_;
};

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
  const GatheredFields all(team_, grains.fields, grains.range.total);
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
