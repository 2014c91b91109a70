#include "subslip/io/contact_scene.hpp"

#include "subslip/history/contact_history.hpp"
#include "subslip/io/law_block.hpp"
#include "subslip/io/output_points.hpp"
#include "subslip/io/scene_compose.hpp"

#include <algorithm>
#include <cmath>

namespace subslip::io {

namespace {

void parse_contact_block(const CheckedNode& node, contact::ContactModel& model, SceneValues& v) {
  node.allow_keys({"alpha_n", "alpha_t", "normal_traction"});
  InputErrorList errors;
  errors.attempt([&] {
    model.stiffness.alpha_n = v.get(node, "alpha_n", dimension::stiffness, Range::positive());
  });
  errors.attempt([&] {
    model.stiffness.alpha_t = v.get(node, "alpha_t", dimension::stiffness, Range::positive());
  });
  errors.attempt([&] {
    model.initial_normal_traction = v.get_noted(node, "normal_traction", dimension::stress,
                                                Magnitude::normal_traction, Range::positive());
  });
  errors.throw_if_any();
}

void parse_initial(const std::optional<CheckedNode>& node, contact::ContactModel& model) {
  model.initial_law_state.mu = model.law.friction.mu_s;
  model.initial_law_state.r_s = 0.0;
  if (!node) return;
  node->allow_keys({"mu"});
  model.initial_law_state.mu = node->get_double("mu", model.law.friction.mu_s, Range::positive());
}

contact::Vec2 read_vec2(const CheckedNode& node, const Unit& unit) {
  const auto v = node.as_quantities(unit, Range::any(), 2);
  return {v[0], v[1]};
}

// The tangential velocity and duration of a `slide:` block.
void parse_slide(const CheckedNode& node, contact::Segment& seg, SceneValues& v) {
  node.allow_keys({"speed", "direction", "velocity", "distance", "duration"});
  const std::string given = *node.one_of({"speed", "velocity"}, true);
  if (given == "speed") {
    const CheckedNode speed_node = node.required("speed");
    const double speed = v.read(speed_node, dimension::velocity, Range::non_negative());
    if (speed > 0.0) v.note(speed_node, Magnitude::sliding_speed, speed);
    contact::Vec2 direction(1.0, 0.0);
    if (auto d = node.optional("direction")) {
      direction = read_vec2(*d, v.unit(dimension::none));
      // stableNorm: [1e-200, 0] is a direction too, and [1e200, 1e200] does not overflow.
      if (!(direction.stableNorm() > 0.0)) d->fail("direction must be non-zero");
      direction = direction.stableNormalized();
    }
    seg.velocity = speed * direction;
  } else {
    if (auto d = node.optional("direction"))
      d->fail("'direction' goes with 'speed'; a 'velocity' has its own");
    const CheckedNode velocity = node.required("velocity");
    seg.velocity = read_vec2(velocity, v.unit(dimension::velocity));
    const double speed = seg.velocity.stableNorm();
    if (std::isfinite(speed) && speed > 0.0) v.note(velocity, Magnitude::sliding_speed, speed);
  }
  if (!std::isfinite(seg.velocity.norm()))
    node.required(given).fail("the sliding speed overflows double precision");
  if (*node.one_of({"distance", "duration"}, true) == "distance") {
    const CheckedNode distance = node.required("distance");
    const double d = v.read(distance, dimension::length, Range::positive());
    const double speed = seg.velocity.stableNorm();  // norm() underflows below 1e-154
    if (!(speed > 0.0)) distance.fail("a slide at zero speed covers no distance; give a duration");
    seg.duration = d / speed;
    if (!(std::isfinite(seg.duration) && seg.duration > 0.0))
      distance.fail("distance / speed is not a usable duration (over- or underflow)");
  } else {
    seg.duration =
        v.get_noted(node, "duration", dimension::time, Magnitude::duration, Range::positive());
  }
}

// The normal side of a segment; `fn` is f_n at the segment start and becomes f_n at its end.
void parse_normal(const std::optional<CheckedNode>& node, const contact::ContactModel& model,
                  contact::Segment& seg, double& fn, SceneValues& v) {
  seg.normal_control = contact::NormalControl::traction;
  seg.normal_traction = fn;  // default: hold f_n constant
  if (!node) return;
  node->allow_keys({"traction", "velocity"});
  if (*node->one_of({"traction", "velocity"}, true) == "traction") {
    const CheckedNode traction = node->required("traction");
    seg.normal_traction = v.read(traction, dimension::stress);
    if (seg.normal_traction > 0.0)
      v.note(traction, Magnitude::normal_traction, seg.normal_traction);
    fn = seg.normal_traction;
  } else {
    seg.normal_control = contact::NormalControl::velocity;
    seg.normal_velocity = v.get(*node, "velocity", dimension::velocity);
    fn += model.stiffness.alpha_n * seg.normal_velocity * seg.duration;
    if (!std::isfinite(fn))
      node->required("velocity").fail("f_n at the end of the segment overflows double precision");
  }
}

// Increments, growth and output_every, each error reported; the increment lengths are checked
// once the segment's duration (`duration_known`) and the first two are read.
void parse_stepping(const CheckedNode& node, contact::Segment& seg, bool duration_known) {
  InputErrorList errors;
  parse_increments(node, seg, duration_known, errors);
  errors.throw_if_any();
}

contact::Segment parse_segment(const CheckedNode& node, const contact::ContactModel& model,
                               double& fn, SceneValues& v) {
  node.allow_keys({"slide", "hold", "increments", "growth", "output_every", "normal"});
  contact::Segment seg;
  InputErrorList errors;
  const bool motion = errors.attempt([&] {
    if (*node.one_of({"slide", "hold"}, true) == "slide") {
      parse_slide(node.required("slide"), seg, v);
    } else {
      const CheckedNode hold = node.required("hold");
      hold.allow_keys({"duration"});
      seg.velocity.setZero();
      seg.duration =
          v.get_noted(hold, "duration", dimension::time, Magnitude::duration, Range::positive());
    }
  });
  errors.attempt([&] { parse_stepping(node, seg, motion); });
  // (a normal velocity needs the duration)
  if (motion) errors.attempt([&] { parse_normal(node.optional("normal"), model, seg, fn, v); });
  errors.throw_if_any();
  return seg;
}

// Every segment is read, each error reported.
std::vector<contact::Segment> parse_loading(const CheckedNode& node,
                                            const contact::ContactModel& model, SceneValues& v) {
  if (node.size() == 0) node.fail("needs at least one segment");
  std::vector<contact::Segment> segments;
  double fn = model.initial_normal_traction;
  InputErrorList errors;
  for (const CheckedNode& element : node.elements())
    errors.attempt([&] { segments.push_back(parse_segment(element, model, fn, v)); });
  errors.throw_if_any();
  return segments;
}

history::IntegratorOptions parse_integrator(const std::optional<CheckedNode>& node) {
  history::IntegratorOptions opt;
  if (!node) return opt;
  node->allow_keys({"method", "max_cutbacks", "residual_tolerance", "tolerance", "order"});
  if (auto m = node->optional("method")) {
    opt.method = m->as_enum<contact::Method>({{"implicit", contact::Method::implicit},
                                              {"forward_euler", contact::Method::forward_euler}});
  }
  opt.max_cutbacks =
      node->get_int("max_cutbacks", opt.max_cutbacks, Range::in_closed_interval(0, 200));
  // (0, 1) in traction-ratio units, as point::ContactPoint requires of its flow-rule tolerance.
  opt.residual_tolerance = node->get_double("residual_tolerance", opt.residual_tolerance,
                                            Range::in_open_interval(0.0, 1.0));
  // A residual tolerance the scene names is used as given, not tied to the tolerance.
  opt.residual_follows_tolerance = !node->has("residual_tolerance");
  if (auto tol = node->optional("tolerance")) {
    if (opt.method != contact::Method::implicit)
      tol->fail("adaptive stepping needs method: implicit");
    opt.tolerance = node->get_double("tolerance", 0.0, Range::in_open_interval(0.0, 1.0));
  }
  opt.order = parse_adaptive_order(*node, opt.tolerance);
  return opt;
}

std::vector<ContactField> parse_contact_output(const std::optional<CheckedNode>& node) {
  const std::vector<ContactField> all(kAllContactFields.begin(), kAllContactFields.end());
  if (!node) return all;
  node->allow_keys({"fields", "at", kCompressionKeys[0], kCompressionKeys[1]});
  const auto fields = node->optional("fields");
  if (!fields) return all;
  std::vector<std::string_view> names;
  for (ContactField f : kAllContactFields) names.push_back(to_string(f));
  std::vector<bool> wanted(kAllContactFields.size(), false);
  for (const CheckedNode& element : fields->elements()) {
    const std::string name = element.as_choice(names);
    const auto k =
        static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
    if (wanted[k]) element.fail("field '" + name + "' listed twice");
    wanted[k] = true;
  }
  // Every later reading of a run needs the time axis and the friction ratio.
  for (ContactField must : {ContactField::time, ContactField::ratio}) {
    if (!wanted[static_cast<std::size_t>(must)]) {
      fields->fail("must include '" + std::string(to_string(must)) + "'");
    }
  }
  std::vector<ContactField> out;
  for (std::size_t k = 0; k < wanted.size(); ++k) {
    if (wanted[k]) out.push_back(kAllContactFields[k]);
  }
  return out;
}

// `output.at`: output at chosen times or sliding distances instead of at increments; the
// segments' steps end on them (contact::Segment::output_times).
void parse_output_at(const CheckedNode& root, std::vector<contact::Segment>& segments,
                     const Units& units) {
  const auto output = root.optional("output");
  const auto at = output ? output->optional("at") : std::nullopt;
  if (!at) return;
  auto clock_of = [&](const std::string& clock) {
    std::vector<ClockSegment> c;
    for (const auto& s : segments)
      c.push_back({clock == "time" ? 1.0 : s.velocity.norm(), s.duration});
    return c;
  };
  auto unit_of = [&](const std::string& clock) {
    return units.unit(clock == "time" ? dimension::time : dimension::length);
  };
  const OutputPoints points = parse_output_points(*at, {"time", "distance"}, clock_of, unit_of);
  const auto times = segment_times(points.values, clock_of(points.clock));
  const CheckedNode loading = root.required("loading");
  for (std::size_t k = 0; k < segments.size(); ++k) {
    if (auto every = loading.element(k).optional("output_every"))
      every->fail("output.at chooses the output points; drop output_every");
    segments[k].output_at_times = true;
    segments[k].output_times = times[k];
  }
}

void check_contact_top_level(const CheckedNode& root) {
  root.allow_keys({"scene", "title", "units", "law", "contact", "initial", "loading", "integrator",
                   "output", "sweep"});
}

// Every block is read and each error reported; a block that needs a failed one (the initial
// state needs the law, the loading the contact, output.at the loading) is skipped.
ContactCase parse_contact_case(SweepCase swept, const Units& units) {
  const CheckedNode root = swept.document.root();
  ContactCase c;
  c.name = std::move(swept.name);
  c.overrides = std::move(swept.overrides);
  SceneValues values(units);
  InputErrorList errors;
  const bool law = errors.attempt(
      [&] { c.model.law = parse_law_block(root.required("law"), contact_law_units(units)); });
  const bool contact =
      errors.attempt([&] { parse_contact_block(root.required("contact"), c.model, values); });
  if (law) errors.attempt([&] { parse_initial(root.optional("initial"), c.model); });
  const bool loading = contact && errors.attempt([&] {
    c.segments = parse_loading(root.required("loading"), c.model, values);
  });
  errors.attempt([&] { c.integrator = parse_integrator(root.optional("integrator")); });
  const bool output =
      errors.attempt([&] { c.fields = parse_contact_output(root.optional("output")); });
  if (loading && output) errors.attempt([&] { parse_output_at(root, c.segments, units); });
  errors.throw_if_any();
  c.magnitudes = values.take_magnitudes();
  return c;
}

}  // namespace

ContactScene load_contact_scene(const std::filesystem::path& path) {
  return parse_contact_scene(compose_scene(YamlDocument::from_file(path)));
}

ContactScene parse_contact_scene(const YamlDocument& document) {
  const CheckedNode root = document.root();
  ContactScene scene;
  scene.file = document.file();
  scene.text = document.text();
  scene.makeup = makeup_of(document);
  InputErrorList errors;
  root.get_choice("scene", {"contact"});  // a scene of another kind is read no further
  errors.attempt([&] { check_contact_top_level(root); });
  errors.attempt([&] { scene.title = root.get_string("title", ""); });
  const bool units = errors.attempt([&] { scene.units = parse_units(root.required("units")); });
  errors.attempt([&] { scene.compression = parse_compression(root.optional("output")); });
  if (units) {
    const Units& u = scene.units;
    errors.attempt([&] {
      scene.cases = parse_sweep_cases(document, kContactSweepable, [&u](SweepCase swept) {
        return parse_contact_case(std::move(swept), u);
      });
    });
  }
  errors.throw_if_any();
  return scene;
}

}  // namespace subslip::io
