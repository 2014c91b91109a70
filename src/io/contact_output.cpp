#include "subslip/io/contact_output.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "subslip/history/contact_history.hpp"
#include "subslip/io/case_group.hpp"
#include "subslip/io/law_block.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::io {

using driver::ContactSummary;

namespace {

struct ContactFieldSpec {
  std::size_t columns;  // 0: 1-D
  h5::Type type;
  std::string unit;
  std::string description;
  std::string components = {};  // the meaning of the columns ("" for 1-D series)
};

ContactFieldSpec field_spec(ContactField f, const Units& u) {
  const std::string one(kDimensionless);
  switch (f) {
    case ContactField::time:
      return {0, h5::Type::float64, u.time, "time since the start of the loading history"};
    case ContactField::slip:
      return {2, h5::Type::float64, u.length, "tangential sliding displacement u_t (x, y)", "x y"};
    case ContactField::slip_path:
      return {0, h5::Type::float64, u.length, "accumulated sliding distance, integral of |du_t|"};
    case ContactField::traction:
      return {3, h5::Type::float64, u.stress,
              "contact traction: tangential x, tangential y, normal f_n (compression positive)",
              "x y n"};
    case ContactField::ratio:
      return {0, h5::Type::float64, one, "contact stress ratio f_t / f_n"};
    case ContactField::mu:
      return {0, h5::Type::float64, one, "friction coefficient mu"};
    case ContactField::r:
      return {0, h5::Type::float64, one, "dynamic loading friction-yield ratio r = f_t / (mu f_n)"};
    case ContactField::r_s:
      return {0, h5::Type::float64, one, "subloading friction-yield ratio r_s"};
    case ContactField::vp_slip:
      return {0, h5::Type::float64, u.length,
              "accumulated viscoplastic sliding, integral of |du_vp|"};
    case ContactField::vp_rate:
      return {0, h5::Type::float64, u.velocity(),
              "viscoplastic sliding rate over the last increment"};
    case ContactField::segment:
      return {0, h5::Type::int32, "index", "loading segment of the state (-1: the initial state)"};
  }
  return {0, h5::Type::float64, one, ""};
}

// Rows gathered in memory between HDF5 writes (when no flush comes first).
constexpr std::size_t kBlockRows = 256;

// Chunks of about one case's length (bounded): one chunk holds a typical run.
std::size_t chunk_rows_for(const ContactCase& c) {
  return std::clamp<std::size_t>(output_count(c.segments), 16, 4096);
}

void write_parameters(const h5::Group& g, const ContactCase& c, const Units& u) {
  const auto& p = c.model.law;
  const std::string_view one = kDimensionless;
  // The law's constants from its table: each block's choice, then its numbers (a
  // rate-independent contact has no overstress constants).
  for (const auto& b : law::kLawBlocks) {
    if (b.choice) g.set_attribute(std::string(b.choice_attribute), b.choice(p));
    for (const auto& k : law::kLawParameters) {
      if (k.block != b.block) continue;
      if (k.rate_dependent_only && p.overstress.form == law::OverstressForm::rate_independent)
        continue;
      set_with_unit(g, std::string(k.name), k.value(p), law_unit_name(k.unit, false, u));
    }
  }
  set_with_unit(g, "alpha_n", c.model.stiffness.alpha_n, u.stiffness());
  set_with_unit(g, "alpha_t", c.model.stiffness.alpha_t, u.stiffness());
  set_with_unit(g, "normal_traction", c.model.initial_normal_traction, u.stress);
  set_with_unit(g, "initial_mu", c.model.initial_law_state.mu, one);
  g.set_attribute("integrator",
                  c.integrator.method == contact::Method::implicit ? "implicit" : "forward_euler");
  // What the steps are solved to (with a tolerance, tied to it unless the scene names its own).
  g.set_attribute("residual_tolerance", history::effective_residual_tolerance(c.integrator));
  g.set_attribute("tolerance", c.integrator.tolerance);  // 0: fixed increments
  g.set_attribute("order", c.integrator.order);          // 1: backward Euler's estimate
  g.set_attribute("max_cutbacks", c.integrator.max_cutbacks);
}

}  // namespace

// ---------------------------------------------------------------- ContactCaseWriter

namespace {

// The summary attributes. `with_units`: also their ".unit" siblings (the layout, which writes
// placeholders); the end of the case rewrites the numbers only, in place.
void write_summary(const h5::Group& g, const ContactSummary& summary, const Units& units,
                   bool with_units) {
  const std::string one(kDimensionless);
  const std::pair<const char*, std::string> numbers[] = {
      {"peak_ratio", one},  {"slip_at_peak", units.length},   {"bottom_ratio", one},
      {"final_ratio", one}, {"steady_ratio_analytical", one}, {"steady_speed", units.velocity()},
      {"wall_seconds", "s"}};
  const double values[] = {summary.peak_ratio,
                           summary.slip_at_peak,
                           summary.bottom_ratio,
                           summary.final_ratio,
                           summary.steady_ratio_analytical,
                           summary.steady_speed,
                           summary.stats.wall_seconds};
  for (std::size_t k = 0; k < std::size(values); ++k) {
    g.set_attribute(numbers[k].first, values[k]);
    if (with_units) g.set_attribute(std::string(numbers[k].first) + ".unit", numbers[k].second);
  }
  g.set_attribute("increments", summary.stats.increments);
  g.set_attribute("substeps", summary.stats.substeps);
  g.set_attribute("newton_iterations", summary.stats.iterations);
  g.set_attribute("cutbacks", summary.stats.cutbacks);
  g.set_attribute("rejected_steps", summary.stats.rejected);
}

// What a case's summary attributes hold until it ends.
ContactSummary placeholder_contact_summary() {
  ContactSummary s;
  s.peak_ratio = s.slip_at_peak = s.bottom_ratio = s.final_ratio = ContactSummary::kNone;
  s.steady_ratio_analytical = s.steady_speed = ContactSummary::kNone;
  s.stats.wall_seconds = ContactSummary::kNone;
  return s;
}

}  // namespace

void ContactCaseWriter::lay_out(const h5::Group& cases, const ContactCase& c, int index,
                                const Units& units) {
  const h5::Group group =
      create_case_group(cases, c.name, index, c.overrides, SceneKind::contact, units);
  write_parameters(group, c, units);
  write_summary(group, placeholder_contact_summary(), units, true);
  group.reserve_string_attribute("failed", h5::kFailureMessageBytes);
  const std::size_t chunk_rows = chunk_rows_for(c);
  for (ContactField f : c.fields) {
    const ContactFieldSpec spec = field_spec(f, units);
    const h5::Series series =
        group.create_series({std::string(to_string(f)), spec.columns, spec.type, spec.unit,
                             spec.description, chunk_rows, kBlockRows, output_count(c.segments)});
    if (!spec.components.empty()) series.dataset().set_attribute("components", spec.components);
  }
}

ContactCaseWriter::ContactCaseWriter(const h5::Group& cases, const ContactCase& c, int index,
                                     const Units& units, h5::CaseProgress& progress)
    : group_(cases.open_group(case_group_name(c.name))),
      units_(units),
      progress_(progress),
      index_(static_cast<std::size_t>(index)) {
  progress_.set_rows(index_, 0);  // rows left by a killed run are overwritten from row 0
  for (ContactField f : c.fields) {
    const ContactFieldSpec spec = field_spec(f, units);
    series_[static_cast<std::size_t>(f)].emplace(
        group_.open_series(to_string(f), spec.type, 0, kBlockRows));
  }
}

void ContactCaseWriter::append(const contact::ContactState& s, int segment) {
  for (std::size_t k = 0; k < series_.size(); ++k) {
    if (!series_[k]) continue;
    h5::Series& out = *series_[k];
    switch (kAllContactFields[k]) {
      case ContactField::time:
        out.append(s.time);
        break;
      case ContactField::slip: {
        const double row[2] = {s.slip.x(), s.slip.y()};
        out.append(row);
        break;
      }
      case ContactField::slip_path:
        out.append(s.slip_path);
        break;
      case ContactField::traction: {
        const double row[3] = {s.traction_t.x(), s.traction_t.y(), s.traction_n};
        out.append(row);
        break;
      }
      case ContactField::ratio:
        out.append(s.traction_ratio());
        break;
      case ContactField::mu:
        out.append(s.law.mu);
        break;
      case ContactField::r:
        out.append(s.r);
        break;
      case ContactField::r_s:
        out.append(s.law.r_s);
        break;
      case ContactField::vp_slip:
        out.append(s.vp_slip);
        break;
      case ContactField::vp_rate:
        out.append(s.vp_rate);
        break;
      case ContactField::segment:
        out.append_int(segment);
        break;
    }
  }
}

void ContactCaseWriter::commit() {
  std::size_t rows = 0;
  for (auto& series : series_) {
    if (!series) continue;
    series->commit();
    rows = series->rows();
  }
  progress_.set_rows(index_, rows);  // after the rows it counts are in the file
}

void ContactCaseWriter::close_series() {
  commit();
  for (auto& series : series_) {
    if (series) series->finish();
  }
}

void ContactCaseWriter::finish(const ContactSummary& summary) {
  close_series();
  write_summary(group_, summary, units_, false);
}

void ContactCaseWriter::mark_failed(const ContactSummary& summary, const std::string& why) {
  finish(summary);
  group_.write_reserved_string("failed", why);
}

// ---------------------------------------------------------------- the sink

namespace {

// The whole layout before any computation (h5_writer.hpp, crash safety).
ContactRunFiles lay_out(const ContactScene& scene, h5::File& file) {
  const h5::Group root = file.root();
  h5::ResultHeader header{"contact",
                          scene.file,
                          scene.text,
                          scene.title,
                          scene.units.entries(),
                          {},
                          scene.compression.gzip_level};
  header.makeup = scene.makeup;
  h5::write_result_header(file, header);
  h5::Group cases = root.create_group("cases");
  std::vector<std::string> names;
  for (const auto& c : scene.cases) names.push_back(case_group_name(c.name));
  cases.set_attribute("names", names);
  for (std::size_t k = 0; k < scene.cases.size(); ++k)
    ContactCaseWriter::lay_out(cases, scene.cases[k], static_cast<int>(k), scene.units);
  h5::CaseProgress progress = h5::CaseProgress::create(root, names.size());
  h5::mark_layout_complete(file);
  return {std::move(cases), std::move(progress)};
}

ContactRunFiles reopen(h5::File& file) {
  h5::mark_running(file);
  const h5::Group root = file.root();
  return {root.open_group("cases"), h5::CaseProgress::open(root)};
}

}  // namespace

ContactResultSink::ContactResultSink(const ContactScene& scene, h5::File& file,
                                     const ContactSinkOptions& options)
    : scene_(scene),
      file_(file),
      options_(options),
      run_(options.restart ? reopen(file) : lay_out(scene, file)) {}

driver::CaseStatus ContactResultSink::status(std::size_t index) const {
  return case_status(run_.progress.state(index));
}

// Read back from the case's summary attributes.
driver::StoredContactCase ContactResultSink::stored_case(std::size_t index) const {
  const h5::Group g = run_.cases.open_group(case_group_name(scene_.cases[index].name));
  auto number = [&](const char* name) {
    return g.has_attribute(name) ? g.attribute_double(name) : ContactSummary::kNone;
  };
  auto count = [&](const char* name) {
    return g.has_attribute(name) ? static_cast<long>(g.attribute_int(name)) : 0L;
  };
  driver::StoredContactCase r;
  r.summary.peak_ratio = number("peak_ratio");
  r.summary.slip_at_peak = number("slip_at_peak");
  r.summary.bottom_ratio = number("bottom_ratio");
  r.summary.final_ratio = number("final_ratio");
  r.summary.steady_ratio_analytical = number("steady_ratio_analytical");
  r.summary.steady_speed = number("steady_speed");
  r.summary.stats.increments = count("increments");
  r.summary.stats.substeps = count("substeps");
  r.summary.stats.iterations = count("newton_iterations");
  r.summary.stats.cutbacks = count("cutbacks");
  r.summary.stats.rejected = count("rejected_steps");
  r.summary.stats.wall_seconds = number("wall_seconds");
  r.failure = h5::failure_message(g);
  return r;
}

void ContactResultSink::begin_case(std::size_t index) {
  index_ = index;
  writer_.emplace(run_.cases, scene_.cases[index], static_cast<int>(index), scene_.units,
                  run_.progress);
  run_.progress.set_state(index, h5::CaseState::running);
  pacer_.emplace(options_.flush_interval, options_.write_cost_ratio);
}

void ContactResultSink::write_state(const contact::ContactState& state, int segment) {
  writer_->append(state, segment);
  if (pacer_->due()) pacer_->commit([&] { writer_->commit(); });
}

void ContactResultSink::write_states(std::span<const driver::ContactRow> rows) {
  for (const auto& row : rows) writer_->append(row.state, row.segment);
}

void ContactResultSink::complete_case(const driver::ContactSummary& summary) {
  writer_->finish(summary);
  end_case(h5::CaseState::completed);
}

void ContactResultSink::fail_case(const driver::ContactSummary& summary, const std::string& why) {
  writer_->mark_failed(summary, why);
  end_case(h5::CaseState::failed);
}

void ContactResultSink::end_case(h5::CaseState state) {
  file_.flush();  // the summary attributes first: the state says they are complete
  run_.progress.set_state(index_, state);
  writer_.reset();
  pacer_.reset();
}

// ---------------------------------------------------------------- the run size

RunSize estimate_contact_run(const ContactScene& scene) {
  constexpr double kCaseOverheadBytes = 32e3;  // attributes, headers, B-trees of a case group
  constexpr double kFinishedCaseBytes = 16e3;  // the same in a finished file (one chunk index)
  RunSize size;
  double largest_case = -1.0;
  for (const auto& c : scene.cases) {
    double values = 0.0;
    for (ContactField f : c.fields)
      values += static_cast<double>(std::max<std::size_t>(field_spec(f, scene.units).columns, 1));
    const double rows = static_cast<double>(output_count(c.segments));
    const double bytes = 8.0 * rows * values + kCaseOverheadBytes;
    size.result_bytes += bytes;
    // The finished file, written before the working one goes: the rows, no reservation.
    size.finish_bytes += 8.0 * rows * values + kFinishedCaseBytes;
    if (bytes <= largest_case) continue;
    largest_case = bytes;
    size.rows = output_count(c.segments);
    std::size_t most = 0;
    for (std::size_t k = 0; k < c.segments.size(); ++k) {
      const std::size_t n = output_count({c.segments[k]}) - 1;
      if (n > most) {
        most = n;
        size.rows_segment = k;
      }
    }
  }
  return size;
}

}  // namespace subslip::io
