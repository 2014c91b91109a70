#include "subslip/io/scene_warnings.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <utility>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/grain_fields_table.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/io/orientation_file.hpp"

namespace subslip::io {

namespace {

std::string format(const char* fmt, double a, double b = 0.0, double c = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, a, b, c);
  return buf;
}

// Warnings per case, merged: a sweep gives one line per distinct message listing its cases,
// none when every case has it (a value no swept value touches: naming cases would suggest the
// sweep caused it). A warning about a written value carries its line ("FILE:LINE: KEY: ..."),
// as errors do.
class Collector {
 public:
  void add(const std::string& case_name, std::string message, int line = 0) {
    auto [it, fresh] = index_.try_emplace({line, message}, order_.size());
    if (fresh) order_.push_back({line, std::move(message), {}});
    order_[it->second].cases.push_back(case_name);
  }
  std::vector<std::string> lines(const std::string& file, std::size_t case_count) const {
    std::vector<std::string> out;
    for (const auto& [line, message, cases] : order_) {
      std::string where;
      if (cases.size() < case_count) {
        where = " (case" + std::string(cases.size() == 1 ? " " : "s ");
        for (std::size_t k = 0; k < cases.size(); ++k) where += (k ? ", " : "") + cases[k];
        where += ")";
      }
      std::string text = file;
      if (line > 0) text.append(":").append(std::to_string(line));
      out.push_back(text.append(": ").append(message).append(where));
    }
    return out;
  }

 private:
  struct Entry {
    int line;
    std::string message;
    std::vector<std::string> cases;
  };
  std::map<std::pair<int, std::string>, std::size_t> index_;
  std::vector<Entry> order_;
};

// ---- magnitudes that look written in another unit

struct MagnitudeKind {
  const char* what;      // "the elastic constants of crystals"
  Dimension dimension;   // of the value
  const char* shown_in;  // the unit the plausible range is stated in
  PlausibleRange WarningLimits::*range;
  // A typical value in SI, for stresses (where Pa, kPa, MPa and GPa get mixed up): the unit
  // suggested is the one that puts the written number nearest to it. 0: no suggestion (a
  // duration or a speed far out of range says little about the unit meant).
  double typical = 0.0;
};

MagnitudeKind kind_of(Magnitude m) {
  switch (m) {
    case Magnitude::elastic_constant:
      return {"the elastic constants of crystals", dimension::stress, "GPa",
              &WarningLimits::elastic_constant, 1e11};
    case Magnitude::tau0:
      return {"the reference stresses (CRSS) of slip systems", dimension::stress, "MPa",
              &WarningLimits::tau0, 1e7};
    case Magnitude::normal_traction:
      return {"the normal tractions of frictional contacts", dimension::stress, "MPa",
              &WarningLimits::normal_traction, 1e6};
    case Magnitude::sliding_speed:
      return {"the sliding speeds of friction tests", dimension::velocity, "m/s",
              &WarningLimits::sliding_speed};
    case Magnitude::strain_rate:
      return {"the strain rates of deformation tests", dimension::per_time, "1/s",
              &WarningLimits::strain_rate};
    case Magnitude::duration:
      return {"the durations of tests", dimension::time, "s", &WarningLimits::duration};
  }
  return {"?", dimension::none, "1", &WarningLimits::duration};
}

std::string number_text(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", x);
  return buf;
}

// The unit of kind `k` in which `number` is plausible and nearest to the typical value, when
// there is one other than `scene_unit`.
std::optional<std::string> likely_unit(double number, const MagnitudeKind& k,
                                       const std::string& scene_unit, PlausibleRange range) {
  if (!(k.typical > 0.0)) return std::nullopt;
  std::optional<std::string> best;
  double best_distance = std::numeric_limits<double>::infinity();
  for (const std::string& name : unit_names_of(k.dimension)) {
    if (name == scene_unit) continue;
    const double si = std::abs(to_si(number, parse_unit(name)->scale));
    if (!(si >= range.lo && si <= range.hi)) continue;
    const double distance = std::abs(std::log10(si / k.typical));
    if (distance < best_distance) {
      best = name;
      best_distance = distance;
    }
  }
  return best;
}

void check_magnitude(Collector& w, const std::string& case_name, const WrittenValue& v,
                     const Units& units, const WarningLimits& limits) {
  const MagnitudeKind k = kind_of(v.kind);
  const PlausibleRange range = limits.*k.range;
  const Unit scene_unit = units.unit(k.dimension);
  const double si = std::abs(to_si(v.value, scene_unit.scale));
  if (si >= range.lo && si <= range.hi) return;
  const Scale shown = parse_unit(k.shown_in)->scale;
  std::string message = v.key + ": " + number_text(v.value) + " " + scene_unit.name;
  if (scene_unit.name != k.shown_in)
    message +=
        " (" + number_text(convert(v.value, scene_unit.scale, shown)) + " " + k.shown_in + ")";
  message += std::string(si < range.lo ? " is below " : " is above ") + k.what + " (" +
             number_text(convert(range.lo, Scale{}, shown)) + " to " +
             number_text(convert(range.hi, Scale{}, shown)) + " " + k.shown_in + ")";
  const auto unit =
      v.bare_number ? likely_unit(*v.bare_number, k, scene_unit.name, range) : std::nullopt;
  if (unit) {
    char written[32];
    std::snprintf(written, sizeof written, "%.15g", *v.bare_number);
    message += ": a number in " + *unit + " in a scene in " + scene_unit.name +
               "? A bare number is in the scene's units; write '" + written + " " + *unit +
               "' if that is meant";
  } else {
    message += ": check the number and its unit (a bare number is in the scene's units)";
  }
  w.add(case_name, message, v.line);
}

void check_magnitudes(Collector& w, const std::string& case_name,
                      const std::vector<WrittenValue>& values, const Units& units,
                      const WarningLimits& limits) {
  // Elastic constants: every one against the upper limit, the largest of the phase against
  // the lower one (C12 or C13 may be small or negative).
  const WrittenValue* stiffest = nullptr;
  for (const WrittenValue& v : values) {
    if (v.kind != Magnitude::elastic_constant) {
      check_magnitude(w, case_name, v, units, limits);
      continue;
    }
    if (!stiffest || std::abs(v.value) > std::abs(stiffest->value)) stiffest = &v;
    const double si = std::abs(to_si(v.value, units.unit(dimension::stress).scale));
    if (si > limits.elastic_constant.hi) check_magnitude(w, case_name, v, units, limits);
  }
  if (stiffest) {
    const double si = std::abs(to_si(stiffest->value, units.unit(dimension::stress).scale));
    if (si < limits.elastic_constant.lo) check_magnitude(w, case_name, *stiffest, units, limits);
  }
}

void check_law(Collector& w, const std::string& case_name, const std::string& key,
               const law::LawParameters& p, const WarningLimits& limits) {
  const auto& o = p.overstress;
  if (o.form == law::OverstressForm::rate_independent) return;
  if (o.form == law::OverstressForm::power && o.n > limits.power_exponent) {
    w.add(case_name, key + ".overstress.n: " +
                         format("n = %g with the power form: the slip rate changes by a factor "
                                "e^(n dr) over dr, so the flow rule is very stiff; expect many "
                                "iterations and cutbacks (the exponential form, or a smaller n)",
                                o.n));
  }
  if (o.r_hat - 1.0 < limits.r_hat_margin) {
    w.add(case_name,
          key + ".overstress.r_hat: " +
              format("r_hat = %.6g leaves only %.3g between the yield ratio 1 and its limit: "
                     "the overstress saturates almost at once and steps are cut back often",
                     o.r_hat, o.r_hat - 1.0));
  }
}

double largest(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

// ---- crystal

crystal::Vec6 mandel_schmid(const crystal::Vec3& s, const crystal::Vec3& m) {
  const crystal::Mat3 p = 0.5 * (s * m.transpose() + m * s.transpose());
  const double r2 = std::sqrt(2.0);
  crystal::Vec6 v;
  v << p(0, 0), p(1, 1), p(2, 2), r2 * p(1, 2), r2 * p(0, 2), r2 * p(0, 1);
  return v;
}

double largest_prescribed_rate(const crystal::LoadSegment& s) {
  double rate = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (!s.free(i, j)) rate = std::max(rate, std::abs(crystal::prescribed_rate(s)(i, j)));
  return rate;
}

const crystal::SlipGroupSettings& settings_of(const crystal::PhaseDescription& d, int group) {
  return d.custom_systems.empty() ? d.family_settings[static_cast<std::size_t>(group)]
                                  : d.custom_settings;
}

std::vector<const crystal::SlipGroupSettings*> distinct_settings(
    const crystal::PhaseDescription& d) {
  std::vector<const crystal::SlipGroupSettings*> out;
  if (!d.custom_systems.empty()) return {&d.custom_settings};
  for (const auto& s : d.family_settings) out.push_back(&s);
  return out;
}

std::string settings_key(const crystal::PhaseDescription& d, std::size_t k) {
  if (!d.custom_systems.empty() || d.families.size() <= 1) return "phase.law";
  return std::string("phase.law (") + std::string(crystal::to_string(d.families[k])) + ")";
}

// Euler angles given in degrees that all lie within 2 pi were most likely written in radians:
// read as degrees, every grain is within 6 degrees of the cube orientation.
void check_euler_units(Collector& w, const CrystalCase& c) {
  const OrientationSource& s = c.orientation_source;
  if (!euler_angles_look_like_radians(s.largest_euler_deg, c.grain_count())) return;
  const std::string where =
      s.kind == "file" ? "orientations.file: " + s.description : std::string("orientations");
  w.add(c.name, where + format(": every Euler angle of the %.0f orientations is within 2 pi "
                               "(largest %.4g), yet they are read as degrees: were they written "
                               "in radians? (convert them: degrees = radians x 180 / pi)",
                               static_cast<double>(c.grain_count()), s.largest_euler_deg));
}

void check_crystal_case(Collector& w, const CrystalCase& c, const Units& units, bool checkpoints,
                        const WarningLimits& limits) {
  check_magnitudes(w, c.name, c.magnitudes, units, limits);
  check_euler_units(w, c);
  const auto& d = c.phase;
  const auto settings = distinct_settings(d);
  for (std::size_t k = 0; k < settings.size(); ++k)
    check_law(w, c.name, settings_key(d, k), settings[k]->law, limits);

  double tau0_min = std::numeric_limits<double>::infinity();
  for (const auto* s : settings) tau0_min = std::min(tau0_min, s->tau0);
  const double c_max = d.stiffness.cwiseAbs().maxCoeff();
  if (c_max / tau0_min > limits.stiffness_over_tau0) {
    w.add(c.name, format("phase: elastic stiffness / tau0 = %.3g (> %.0e): the elastic range "
                         "of a slip system is a strain of ~%.1e, so every increment is almost "
                         "all plastic (stiff Newton, consider smaller increments)",
                         c_max / tau0_min, limits.stiffness_over_tau0, tau0_min / c_max));
  }

  const bool adaptive = c.options.tolerance > 0.0;
  const auto systems = crystal::described_systems(d);
  for (std::size_t k = 0; k < c.segments.size(); ++k) {
    const auto& seg = c.segments[k];
    const double dt = largest(crystal::increment_lengths(seg.duration, seg.increments, seg.growth));
    const double rate = largest_prescribed_rate(seg);
    const std::string key = "loading[" + std::to_string(k) + "]";
    // (1 + 1e-9): a step of exactly the limit, up to rounding, is fine.
    if (!adaptive && rate * dt > limits.strain_increment * (1.0 + 1e-9)) {
      const bool rotation = d.kinematics == crystal::Kinematics::finite_rotation;
      w.add(c.name, key + ": " +
                        format("strain increment per step up to %.3g (> %.0e): ", rate * dt,
                               limits.strain_increment) +
                        (rotation ? "the slip, the deformation gradient and the lattice rotation "
                                    "are"
                                  : "the slip is") +
                        " integrated over each step as one backward-Euler update with constant "
                        "L; use more increments or integrator.tolerance");
    }
    if (c.options.method != crystal::CrystalMethod::forward_euler || rate <= 0.0) continue;
    double limit = std::numeric_limits<double>::infinity();
    for (const auto& sys : systems) {
      const crystal::Vec6 p = mandel_schmid(sys.s, sys.m);
      const auto& st = settings_of(d, sys.group);
      const double a = p.dot(d.stiffness * p);
      limit = std::min(limit, forward_euler_step_limit(st.law, rate, a, st.tau0));
    }
    if (dt > limit) {
      w.add(c.name, key + ": " +
                        format("forward_euler with increments up to %.3g [time], above its "
                               "stability estimate %.3g (steady slip at the loading rate); "
                               "expect cutbacks or failure: use method implicit",
                               dt, limit));
    }
  }

  if (!c.output.grains.empty()) {
    std::size_t values = 0;
    const std::size_t n = systems.size();
    // The values that determine each field: a symmetric tensor (the stress) counts its 6.
    for (GrainField f : c.output.grains)
      values += crystal::info(f).stored == crystal::GrainFieldShape::tensor
                    ? 6
                    : crystal::stored_width(f, n);
    const double bytes = 8.0 * static_cast<double>(values) * static_cast<double>(c.grain_count()) *
                         static_cast<double>(crystal_output_count(c.segments));
    if (bytes > limits.output_bytes) {
      w.add(c.name, format("output.grains: about %.3g GB of per-grain series (%.0f grains x "
                           "%.0f rows); consider fewer fields or output_every",
                           bytes / 1e9, static_cast<double>(c.grain_count()),
                           static_cast<double>(crystal_output_count(c.segments))));
    }
  }

  if (!checkpoints) {
    double increments = 0.0;
    for (const auto& seg : c.segments) increments += seg.increments;
    const double grain_steps = increments * static_cast<double>(c.grain_count());
    if (grain_steps > limits.grain_steps_checkpoint) {
      w.add(c.name, format("checkpoints are off for a long run (%.3g grain-steps, hours): a "
                           "killed run cannot be continued; keep output.checkpoint_every > 0",
                           grain_steps));
    }
  }
}

// ---- contact

void check_contact_case(Collector& w, const ContactCase& c, const Units& units,
                        const WarningLimits& limits) {
  check_magnitudes(w, c.name, c.magnitudes, units, limits);
  check_law(w, c.name, "law", c.model.law, limits);
  if (c.integrator.method != contact::Method::forward_euler) return;
  double fn = c.model.initial_normal_traction;
  for (std::size_t k = 0; k < c.segments.size(); ++k) {
    const auto& seg = c.segments[k];
    if (seg.normal_control == contact::NormalControl::traction && seg.normal_traction > 0.0)
      fn = std::max(fn, seg.normal_traction);
    const double v = seg.velocity.norm();
    if (v <= 0.0 || fn <= 0.0) continue;
    const double dt = largest(contact::increment_lengths(seg));
    const double limit = forward_euler_step_limit(c.model.law, v, c.model.stiffness.alpha_t, fn);
    if (dt > limit) {
      w.add(c.name, "loading[" + std::to_string(k) + "]: " +
                        format("forward_euler with increments up to %.3g [time], above its "
                               "stability estimate %.3g (steady sliding at this speed); expect "
                               "cutbacks or an r >= r_hat failure: use method implicit",
                               dt, limit));
    }
  }
}

}  // namespace

double forward_euler_step_limit(const law::LawParameters& p, double v, double stiffness,
                                double normal_traction) {
  const law::SubloadingFrictionLaw law(p);
  if (law.is_rate_independent() || !(v > 0.0)) return std::numeric_limits<double>::infinity();
  const auto ss = law.steady_state(v);
  const double lambda = law.traction_relaxation_rate(stiffness, ss.r, 1.0, ss.mu, normal_traction);
  return lambda > 0.0 ? 2.0 / lambda : std::numeric_limits<double>::infinity();
}

std::vector<std::string> crystal_scene_warnings(const CrystalScene& scene, bool checkpoints,
                                                const WarningLimits& limits) {
  Collector w;
  for (const auto& c : scene.cases) check_crystal_case(w, c, scene.units, checkpoints, limits);
  return w.lines(scene.file, scene.cases.size());
}

std::vector<std::string> contact_scene_warnings(const ContactScene& scene,
                                                const WarningLimits& limits) {
  Collector w;
  for (const auto& c : scene.cases) check_contact_case(w, c, scene.units, limits);
  return w.lines(scene.file, scene.cases.size());
}

}  // namespace subslip::io
