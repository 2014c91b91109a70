#include "subslip/io/checkpoint.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace subslip::io {

namespace {

using crystal::Mat3;

constexpr const char* kSlots[2] = {"a", "b"};
constexpr int kMaxFree = 9;  // free components of L

// The macro numbers of a slot's `values`, in order; a name per number (matrices row-major).
std::vector<std::string> value_names() {
  std::vector<std::string> names = {"time", "segment_time", "next_step", "wall_seconds",
                                    "trend_step"};
  auto matrix = [&](const std::string& what) {
    for (int i = 1; i <= 3; ++i)
      for (int j = 1; j <= 3; ++j) names.push_back(what + "_" + std::to_string(10 * i + j));
  };
  for (const char* m : {"L", "F", "strain", "stress", "segment_start_stress"}) matrix(m);
  for (int k = 1; k <= kMaxFree; ++k) names.push_back("free_L_" + std::to_string(k));
  for (int k = 1; k <= kMaxFree; ++k) names.push_back("free_L_trend_" + std::to_string(k));
  for (int k = 1; k <= kMaxFree; ++k) names.emplace_back("free_L_path_" + std::to_string(k));
  for (int k = 1; k <= kMaxFree; ++k) {
    // (Appended, not "literal" + std::to_string(k): GCC 12's -Warray-bounds misreads that
    // temporary's copy at -O3.)
    std::string name = "free_strain_correction_";
    name += std::to_string(k);
    names.push_back(std::move(name));
  }
  // (emplace_back: GCC 12's -Warray-bounds misreads push_back of this literal at -O2.)
  names.emplace_back("last_output_time");
  for (const char* m :
       {"last_output_L", "last_output_F", "last_output_strain", "last_output_stress"})
    matrix(m);
  return names;
}

const std::vector<std::string> kCounterNames = {"segment",
                                                "increment",
                                                "macro_segment",
                                                "free_count",
                                                "rows",
                                                "last_output_segment",
                                                "increments",
                                                "substeps",
                                                "grain_steps",
                                                "grain_solves",
                                                "newton_iterations",
                                                "cutbacks",
                                                "rejected",
                                                "mixed_iterations",
                                                "case",
                                                "grain_count",
                                                "values_per_grain"};

void put(std::vector<double>& v, const Mat3& m) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v.push_back(m(i, j));
}

Mat3 take(const double*& p) {
  Mat3 m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = *p++;
  return m;
}

std::vector<double> pack_values(const crystal::AggregateCheckpoint& c,
                                const crystal::MacroState& last) {
  std::vector<double> v = {c.macro.time, c.position.segment_time, c.position.next_step,
                           c.stats.wall_seconds, c.trend_step};
  put(v, c.macro.velocity_gradient);
  put(v, c.macro.deformation_gradient);
  put(v, c.macro.strain);
  put(v, c.macro.stress);
  put(v, c.segment_start_stress);
  for (const Eigen::VectorXd* free : c.free_vectors())
    for (int k = 0; k < kMaxFree; ++k) v.push_back(k < free->size() ? (*free)(k) : std::nan(""));
  v.push_back(last.time);
  put(v, last.velocity_gradient);
  put(v, last.deformation_gradient);
  put(v, last.strain);
  put(v, last.stress);
  return v;
}

std::vector<long long> pack_counters(std::size_t case_index, const crystal::AggregateCheckpoint& c,
                                     std::size_t rows, const crystal::MacroState& last,
                                     std::size_t grain_count) {
  const auto& s = c.stats;
  return {c.position.segment,
          c.position.increment,
          c.macro.segment,
          c.free_velocity_gradient.size(),
          static_cast<long long>(rows),
          last.segment,
          s.increments,
          s.substeps,
          s.grain_steps,
          s.grain_solves,
          s.newton_iterations,
          s.cutbacks,
          s.rejected,
          s.mixed_iterations,
          static_cast<long long>(case_index),
          static_cast<long long>(grain_count),
          c.values_per_grain};
}

StoredCheckpoint unpack(const std::vector<double>& values, const std::vector<long long>& n,
                        std::vector<double> grains, int values_per_grain, long long sequence) {
  StoredCheckpoint out;
  auto& c = out.state;
  const double* p = values.data();
  c.macro.time = *p++;
  c.position.segment_time = *p++;
  c.position.next_step = *p++;
  c.stats.wall_seconds = *p++;
  c.trend_step = *p++;
  c.macro.velocity_gradient = take(p);
  c.macro.deformation_gradient = take(p);
  c.macro.strain = take(p);
  c.macro.stress = take(p);
  c.segment_start_stress = take(p);
  for (Eigen::VectorXd* free : c.free_vectors()) {
    free->resize(static_cast<int>(n[3]));
    for (int k = 0; k < kMaxFree; ++k, ++p) {
      if (k < n[3]) (*free)(k) = *p;
    }
  }
  out.last_output.time = *p++;
  out.last_output.velocity_gradient = take(p);
  out.last_output.deformation_gradient = take(p);
  out.last_output.strain = take(p);
  out.last_output.stress = take(p);
  c.position.segment = static_cast<int>(n[0]);
  c.position.increment = static_cast<long>(n[1]);
  c.macro.segment = static_cast<int>(n[2]);
  out.rows = static_cast<std::size_t>(n[4]);
  out.last_output.segment = static_cast<int>(n[5]);
  auto& s = c.stats;
  s.increments = n[6];
  s.substeps = n[7];
  s.grain_steps = n[8];
  s.grain_solves = n[9];
  s.newton_iterations = n[10];
  s.cutbacks = n[11];
  s.rejected = n[12];
  s.mixed_iterations = n[13];
  c.values_per_grain = values_per_grain;
  c.grains = std::move(grains);
  out.sequence = sequence;
  return out;
}

long long read_sequence(const h5::Group& slot) {
  const auto v = slot.open_dataset("sequence").read_ints();
  return v.empty() ? -1 : v.front();
}

void write_sequence(const h5::Group& slot, long long value) {
  const long long v[1] = {value};
  slot.open_dataset("sequence").write(v);
}

}  // namespace

void CheckpointStore::create(const h5::Group& parent, std::size_t capacity) {
  const h5::Group g = parent.create_group("checkpoint");
  g.set_attribute("description",
                  "the running crystal case's state, two slots written alternately; the one "
                  "with the larger sequence >= 1 is the latest complete checkpoint (-1: being "
                  "written)");
  g.set_attribute("capacity", static_cast<long long>(capacity));
  const auto names = value_names();
  for (const char* name : kSlots) {
    const h5::Group slot = g.create_group(name);
    const std::size_t grain_shape[1] = {std::max<std::size_t>(capacity, 1)};
    slot.create_fixed("grains", grain_shape, h5::Type::float64,
                      "per grain (grain_count x values_per_grain, row-major): stress (lattice "
                      "frame, Mandel) 6, orientation g (row-major) 9, then mu, r_s, slip, slip "
                      "rate, slip-rate trend (1/s^2), its change (1/s^3) (N each); the rest unused")
        .set_attribute("stress_scaling",
                       "Mandel: 11 22 33 sqrt(2)*23 sqrt(2)*13 sqrt(2)*12 (lattice frame)");
    const std::size_t value_shape[1] = {names.size()};
    slot.create_fixed("values", value_shape, h5::Type::float64, "macro state, see names")
        .set_attribute("names", names);
    const std::size_t counter_shape[1] = {kCounterNames.size()};
    slot.create_fixed("counters", counter_shape, h5::Type::int64, "position and counters")
        .set_attribute("names", kCounterNames);
    slot.create_fixed("sequence", {}, h5::Type::int64, "checkpoint number; -1 while written");
    write_sequence(slot, -1);
  }
}

CheckpointStore::CheckpointStore(const h5::Group& parent)
    : store_(parent.open_group("checkpoint")) {}

std::size_t CheckpointStore::capacity() const {
  return static_cast<std::size_t>(store_.attribute_int("capacity"));
}

h5::File create_restart_file(const std::filesystem::path& path, const std::string& run_id,
                             std::size_t capacity) {
  std::filesystem::path partial = path;
  partial += ".partial";
  {
    h5::File f = h5::File::create(partial, true);
    const h5::Group root = f.root();
    root.set_attribute("format", kRestartFormat);
    root.set_attribute("format_version", h5::kFormatVersion);
    root.set_attribute("program_version", SUBSLIP_VERSION);
    root.set_attribute("run_id", run_id);
    root.set_attribute("description",
                       "checkpoints of the run whose result file has the same run_id "
                       "(subslip run --restart RESULT continues from them); deleted when the run "
                       "finishes");
    CheckpointStore::create(root, capacity);
    f.close();
  }
  std::filesystem::rename(partial, path);
  return h5::File::open_write(path);
}

std::optional<h5::File> open_restart_file(const std::filesystem::path& path,
                                          const std::string& run_id, const h5::MpiAccess* mpi) {
  std::string id;
  if (!is_restart_file(path, &id) || id != run_id) return std::nullopt;
  return h5::File::open_write(path, mpi);
}

void CheckpointStore::write(std::size_t case_index, const crystal::AggregateCheckpoint& state,
                            std::size_t rows, const crystal::MacroState& last_output,
                            const parallel::Block* grains) {
  if (!continued_) {
    // A restart: continue the numbering, and write over the older slot.
    continued_ = true;
    for (int k = 0; k < 2; ++k) {
      const long long s = read_sequence(store_.open_group(kSlots[k]));
      if (s > sequence_) {
        sequence_ = s;
        next_slot_ = 1 - k;
      }
    }
  }
  const h5::Group slot = store_.open_group(kSlots[next_slot_]);
  write_sequence(slot, -1);  // from here until the end the slot is not a checkpoint
  const auto width = static_cast<std::size_t>(std::max(state.values_per_grain, 1));
  std::size_t grain_count = state.grains.size() / width;
  if (grains != nullptr) {
    slot.open_dataset("grains").write_rows(grains->offset * width, state.grains);
    grain_count = grains->total;
  } else {
    slot.open_dataset("grains").write_prefix(state.grains);
  }
  slot.open_dataset("values").write(pack_values(state, last_output));
  slot.open_dataset("counters")
      .write(pack_counters(case_index, state, rows, last_output, grain_count));
  write_sequence(slot, ++sequence_);
  next_slot_ = 1 - next_slot_;
}

std::optional<StoredCheckpoint> CheckpointStore::latest(std::size_t case_index, int rank,
                                                        int ranks) const {
  int best = -1;
  long long best_sequence = 0;
  for (int k = 0; k < 2; ++k) {
    const long long s = read_sequence(store_.open_group(kSlots[k]));
    if (s > best_sequence) {
      best = k;
      best_sequence = s;
    }
  }
  if (best < 0) return std::nullopt;
  const h5::Group slot = store_.open_group(kSlots[best]);
  const auto values = slot.open_dataset("values").read_doubles();
  const auto counters = slot.open_dataset("counters").read_ints();
  if (values.size() != value_names().size() || counters.size() != kCounterNames.size()) {
    throw h5::Error("HDF5: checkpoint slot '" + std::string(kSlots[best]) + "' has another layout");
  }
  const std::size_t last = kCounterNames.size() - 1;  // case, grain_count, values_per_grain
  if (counters[last - 2] != static_cast<long long>(case_index)) return std::nullopt;
  const auto width = static_cast<std::size_t>(counters[last]);
  const auto grain_count = static_cast<std::size_t>(counters[last - 1]);
  const h5::Dataset stored = slot.open_dataset("grains");
  if (stored.shape().front() < grain_count * width)
    throw h5::Error("HDF5: checkpoint slot '" + std::string(kSlots[best]) + "' is too small");
  const parallel::Block mine = parallel::block_of(grain_count, rank, ranks);
  std::vector<double> grains = stored.read_rows(mine.offset * width, mine.count * width);
  return unpack(values, counters, std::move(grains), static_cast<int>(counters[last]),
                best_sequence);
}

}  // namespace subslip::io
