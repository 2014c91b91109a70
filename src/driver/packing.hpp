// Internal to the driver: the values ranks exchange, flattened to doubles (integers bit for
// bit) for MPI, and per-grain fields held as arrays.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/grain_fields_table.hpp"
#include "subslip/driver/crystal_sink.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::driver {

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
  void put(const CrystalSummary& s) {
    put(s.final_state);
    put_integer(s.axis.first);
    put_integer(s.axis.second);
    for (double v : {s.final_von_mises_stress, s.final_von_mises_strain, s.grain_steps_per_second,
                     s.newton_per_grain_solve})
      put(v);
    put(s.stats);
  }
  // Everything of a checkpoint but its grains.
  void put(const crystal::AggregateCheckpoint& c) {
    put_integer(c.position.segment);
    put_integer(c.position.increment);
    put(c.position.segment_time);
    put(c.position.next_step);
    put(c.trend_step);
    put(c.macro);
    put(c.segment_start_stress);
    put_integer(c.free_velocity_gradient.size());
    for (const Eigen::VectorXd* free : c.free_vectors())
      for (int k = 0; k < free->size(); ++k) put((*free)(k));
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
  void get(CrystalSummary& s) {
    get(s.final_state);
    s.axis.first = static_cast<int>(integer());
    s.axis.second = static_cast<int>(integer());
    for (double* v : {&s.final_von_mises_stress, &s.final_von_mises_strain,
                      &s.grain_steps_per_second, &s.newton_per_grain_solve})
      *v = real();
    get(s.stats);
  }
  // The next n values.
  std::span<const double> take(std::size_t n) {
    const auto span = std::span<const double>(values_).subspan(next_, n);
    next_ += n;
    return span;
  }
  // A checkpoint but its grains; returns the number of its grain values.
  std::size_t get(crystal::AggregateCheckpoint& c) {
    c.position.segment = static_cast<int>(integer());
    c.position.increment = integer();
    c.position.segment_time = real();
    c.position.next_step = real();
    c.trend_step = real();
    get(c.macro);
    get(c.segment_start_stress);
    const auto free_count = integer();
    for (Eigen::VectorXd* free : c.free_vectors()) {
      free->resize(free_count);
      for (int k = 0; k < free->size(); ++k) (*free)(k) = real();
    }
    get(c.stats);
    c.values_per_grain = static_cast<int>(integer());
    return static_cast<std::size_t>(integer());
  }

 private:
  const std::vector<double>& values_;
  std::size_t next_ = 0;
};

// The per-grain fields of one state, as arrays (crystal::GrainFields row layout), in the order
// of the field table (crystal/grain_fields_table.hpp): one flat block of values() numbers.
class FieldArrays final : public crystal::GrainFields {
 public:
  FieldArrays(int grains, int slips) : grains_(grains), slips_(slips) {
    values_.resize(static_cast<std::size_t>(grains) * width());
  }
  // Every field of `fields`.
  explicit FieldArrays(const crystal::GrainFields& fields)
      : FieldArrays(fields.grain_count(), fields.slip_count()) {
    for (crystal::GrainField f : crystal::kAllGrainFields) fields.values(f, at(f));
  }
  // Values per grain over all fields.
  std::size_t width() const {
    std::size_t w = 0;
    for (crystal::GrainField f : crystal::kAllGrainFields) w += field_width(f);
    return w;
  }
  // Values per grain of one field.
  std::size_t field_width(crystal::GrainField f) const {
    return crystal::given_width(f, static_cast<std::size_t>(slips_));
  }
  std::vector<double>& values() { return values_; }
  const std::vector<double>& values() const { return values_; }

  int grain_count() const override { return grains_; }
  int slip_count() const override { return slips_; }
  void values(crystal::GrainField f, double* out) const override { copy(f, out); }

 private:
  // Where field f starts: the fields before it, each grains x its width.
  std::size_t offset(crystal::GrainField f) const {
    std::size_t o = 0;
    for (crystal::GrainField e : crystal::kAllGrainFields) {
      if (e == f) break;
      o += field_width(e) * static_cast<std::size_t>(grains_);
    }
    return o;
  }
  std::size_t size(crystal::GrainField f) const {
    return field_width(f) * static_cast<std::size_t>(grains_);
  }
  double* at(crystal::GrainField f) { return values_.data() + offset(f); }
  void copy(crystal::GrainField f, double* out) const {
    std::copy_n(values_.data() + offset(f), size(f), out);
  }
  int grains_, slips_;
  std::vector<double> values_;
};

// Every rank's block of fields gathered on the root, in grain order (collective; `total`: the
// aggregate's grains). Field by field: each is rows of its own width.
inline FieldArrays gathered_fields(const parallel::Team& team, const crystal::GrainFields& mine,
                                   std::size_t total) {
  const FieldArrays block(mine);
  const int slips = mine.slip_count();
  FieldArrays all(team.is_root() ? static_cast<int>(total) : 0, slips);
  std::size_t from = 0, to = 0;
  for (crystal::GrainField f : crystal::kAllGrainFields) {
    const std::size_t width = block.field_width(f);
    const std::size_t mine_count = static_cast<std::size_t>(block.grain_count()) * width;
    const std::size_t all_count = team.is_root() ? total * width : 0;
    team.gather_rows(std::span<const double>(block.values()).subspan(from, mine_count),
                     std::span<double>(all.values()).subspan(to, all_count), width);
    from += mine_count;
    to += all_count;
  }
  return all;
}

}  // namespace subslip::driver
