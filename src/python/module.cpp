// subslip._core: the Python bindings of the core (pybind11), wrapped by python/subslip/
// (run.py, point.py; docs/python.md).
//
// * run_scene: `subslip run` itself (cli/run_scene.hpp), quiet, into a result file; the Python
//   side reads that file into memory. Runs of one process take turns: the HDF5 library of an MPI
//   build is not thread-safe, and a run writes through it from start to end.
// * ContactPoint, GrainPoint, TaylorPoint: the material-point API (material_point.hpp) with the
//   parameters of a scene's case (parsed by io, so that names, units, checks and messages are a
//   scene's), driven along paths given as numpy arrays; states as dicts of arrays.
// * fit_report, crystal_fit_predict: `subslip fit FILE --json`'s report, and the crystal fit's
//   model of one curve (the synthetic curves of the shipped crystal fit are made with it).
// * von_mises_stress, von_mises_strain, equivalent_plastic_strain, weighted_mean_abs: the
//   derived measures of crystal/measures.hpp on numpy arrays, the package's only implementation
//   of them (python/subslip/tensors.py, derived.py), so that they are `subslip post`'s numbers.
// The GIL is released while the core computes (OpenMP inside); no failure of the core ends the
// interpreter: bad input raises SceneError (a ValueError) with the command line's message, a
// step that cannot be completed StepFailure (a RuntimeError).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <exception>
#include <mutex>
#include <span>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "../cli/fit_report.hpp"
#include "../cli/run_scene.hpp"
#include "subslip/calibration/contact_fit.hpp"
#include "subslip/calibration/crystal_fit.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/measures.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/integrators/step_control.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/fit_file.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_compose.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/law/parameter_table.hpp"
#include "subslip/material_point.hpp"
#include "subslip/parallel/team.hpp"

namespace py = pybind11;
namespace pt = subslip::point;
namespace cr = subslip::crystal;
namespace ct = subslip::contact;
using subslip::InputError;

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// One run at a time in this process (see the head of the file).
std::mutex g_run_mutex;

// ---- runs -----------------------------------------------------------------------------------

// The scene `scene` (a file, or the name of `scene_text`) run into `output`: (exit status,
// message, warnings); status 0 and no message when it completed. The statuses are the command
// line's (cli::exit_code_of), the message what it prints after "subslip: error: ".
py::tuple run_scene(const std::string& scene, const std::string& scene_text,
                    const std::string& output, bool force, int threads,
                    const std::vector<std::string>& settings) {
  subslip::cli::RunArgs a;
  a.scene = scene;
  a.scene_text = scene_text;
  a.settings = settings;
  a.output = output;
  a.force = force;
  a.quiet = true;
  a.threads = threads;
  a.stop_on_signals = false;
  std::vector<std::string> warnings;
  a.warnings = &warnings;
  int code = 0;
  std::string message;
  {
    const py::gil_scoped_release released;
    const std::lock_guard<std::mutex> one_run(g_run_mutex);
    try {
      subslip::cli::run_scene(a, subslip::parallel::serial_team());
    } catch (const std::exception& e) {
      code = subslip::cli::exit_code_of(std::current_exception());
      message = e.what();
    } catch (...) {
      code = 1;
      message = "unknown failure";
    }
  }
  return py::make_tuple(code, message, warnings);
}

// ---- scenes as point parameters ---------------------------------------------------------------

// (with its base scenes, as a run reads it)
subslip::io::YamlDocument scene_document(const std::string& scene, const std::string& text) {
  return subslip::io::compose_scene(text.empty()
                                        ? subslip::io::YamlDocument::from_file(scene)
                                        : subslip::io::YamlDocument::from_string(text, scene));
}

// The case named `name` of `cases` (empty: the only case).
template <class Case>
const Case& case_named(const std::vector<Case>& cases, const std::string& name,
                       const std::string& scene) {
  if (name.empty() && cases.size() == 1) return cases.front();
  std::string names;
  for (const Case& c : cases) {
    if (c.name == name) return c;
    names += (names.empty() ? "" : ", ") + c.name;
  }
  throw InputError(
      scene, 0, "case",
      (name.empty() ? std::string("the scene has several cases") : "no case '" + name + "'") +
          "; give one of: " + names);
}

// ---- arrays -----------------------------------------------------------------------------------

// `a` as a C-contiguous double array of the given shape (-1: any extent), or a ValueError
// naming `what`.
Array checked(const py::handle& a, const std::vector<py::ssize_t>& shape, const char* what) {
  Array out = Array::ensure(a);
  if (!out) throw py::value_error(std::string(what) + ": not an array of numbers");
  bool ok = out.ndim() == static_cast<py::ssize_t>(shape.size());
  for (std::size_t k = 0; ok && k < shape.size(); ++k)
    ok = shape[k] < 0 || out.shape(static_cast<py::ssize_t>(k)) == shape[k];
  if (!ok) {
    std::string want = "(";
    for (std::size_t k = 0; k < shape.size(); ++k)
      want += (k ? ", " : "") + (shape[k] < 0 ? std::string("n") : std::to_string(shape[k]));
    throw py::value_error(std::string(what) + ": shape " + want + (shape.size() == 1 ? ",)" : ")") +
                          " expected");
  }
  return out;
}

Array array_of(const std::vector<double>& values, const std::vector<py::ssize_t>& shape) {
  Array out(shape);
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

// ---- derived measures (crystal/measures.hpp, as `subslip post` computes them) -----------------

std::span<const double> values_of(const Array& a) {
  return {a.data(), static_cast<std::size_t>(a.size())};
}

// The leading axes of `a`, without its last `drop`.
std::vector<py::ssize_t> leading(const Array& a, py::ssize_t drop) {
  return {a.shape(), a.shape() + a.ndim() - drop};
}

// The von Mises measure of every tensor of (..., 3, 3) -> (...).
Array von_mises(const py::handle& tensors, bool stress) {
  Array t = Array::ensure(tensors);
  if (!t || t.ndim() < 2 || t.shape(t.ndim() - 1) != 3 || t.shape(t.ndim() - 2) != 3)
    throw py::value_error("von Mises: an array of 3x3 tensors (..., 3, 3) expected");
  const auto out = stress ? cr::von_mises_stress(values_of(t)) : cr::von_mises_strain(values_of(t));
  return array_of(out, leading(t, 2));
}

// Accumulated equivalent plastic strain (n, G) of slips (n, G, N) and systems (N, 6).
Array equivalent_plastic_strain(const py::handle& slip, const py::handle& systems) {
  const Array s = checked(slip, {-1, -1, -1}, "slip (n, G, N)");
  const Array m = checked(systems, {s.shape(2), 6}, "slip systems (N, 6)");
  const auto rows = static_cast<std::size_t>(s.shape(0));
  const auto grains = static_cast<std::size_t>(s.shape(1));
  return array_of(cr::equivalent_plastic_strain(values_of(s), rows, grains, values_of(m)),
                  {s.shape(0), s.shape(1)});
}

// Weighted grain mean of |values| (n, G, ...) -> (n, ...), weights (G,) of any sum.
Array weighted_mean_abs(const py::handle& values, const py::handle& weights) {
  const Array v = Array::ensure(values);
  if (!v || v.ndim() < 2) throw py::value_error("values: an array (n, G, ...) expected");
  const Array w = checked(weights, {v.shape(1)}, "weights (G,)");
  std::vector<py::ssize_t> shape{v.shape(0)};
  for (py::ssize_t k = 2; k < v.ndim(); ++k) shape.push_back(v.shape(k));
  return array_of(cr::weighted_mean_abs(values_of(v), static_cast<std::size_t>(v.shape(0)),
                                        static_cast<std::size_t>(v.shape(1)), values_of(w)),
                  shape);
}

template <class Matrix>
void append(std::vector<double>& to, const Matrix& m) {  // row-major
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) to.push_back(m(i, j));
}

double scalar(const py::dict& d, const char* key) {
  return d[key].cast<double>();
}

// The fixed steps of a contact or crystal segment as the drivers take them (with output times:
// increments split at them).
template <class Segment>
std::vector<subslip::integrators::FixedStep> segment_steps(const Segment& seg) {
  std::vector<double> lengths;
  if constexpr (std::is_same_v<Segment, ct::Segment>)
    lengths = ct::increment_lengths(seg);
  else
    lengths = cr::increment_lengths(seg.duration, seg.increments, seg.growth);
  const std::vector<double> none;
  return subslip::integrators::fixed_steps(lengths, seg.output_at_times ? seg.output_times : none,
                                           seg.duration);
}

// ---- the contact point --------------------------------------------------------------------

py::dict contact_state_dict(const ct::ContactState& s) {
  py::dict d;
  d["time"] = s.time;
  d["slip"] = array_of({s.slip(0), s.slip(1)}, {2});
  d["slip_path"] = s.slip_path;
  d["vp_slip"] = s.vp_slip;
  d["vp_rate"] = s.vp_rate;
  d["traction"] = array_of({s.traction_t(0), s.traction_t(1)}, {2});
  d["normal_traction"] = s.traction_n;
  d["mu"] = s.law.mu;
  d["r_s"] = s.law.r_s;
  d["r"] = s.r;
  return d;
}

ct::ContactState contact_state(const py::dict& d) {
  ct::ContactState s;
  s.time = scalar(d, "time");
  const Array slip = checked(d["slip"], {2}, "state['slip']");
  s.slip = {slip.at(0), slip.at(1)};
  s.slip_path = scalar(d, "slip_path");
  s.vp_slip = scalar(d, "vp_slip");
  s.vp_rate = scalar(d, "vp_rate");
  const Array t = checked(d["traction"], {2}, "state['traction']");
  s.traction_t = {t.at(0), t.at(1)};
  s.traction_n = scalar(d, "normal_traction");
  s.law.mu = scalar(d, "mu");
  s.law.r_s = scalar(d, "r_s");
  s.r = scalar(d, "r");
  return s;
}

// A contact point with the law, stiffness and update of a contact scene's case.
class ContactPoint {
 public:
  ContactPoint(const std::string& scene, const std::string& text, const std::string& case_name)
      : case_(case_named(subslip::io::parse_contact_scene(scene_document(scene, text)).cases,
                         case_name, scene)),
        point_(parameters(case_)) {}

  py::dict initial_state() const { return contact_state_dict(ct::initial_state(case_.model)); }

  // The steps of the case's loading as the history driver takes them with fixed increments
  // (split at output times) and no cutback: (slip increments (n, 2), normal traction at each step's
  // end (n,), dt (n,)).
  py::tuple steps() const {
    std::vector<double> du, fn, dt;
    double fn_start = case_.model.initial_normal_traction;
    for (const ct::Segment& seg : case_.segments) {
      double t_local = 0.0, fn1 = fn_start;
      for (const subslip::integrators::FixedStep& step : segment_steps(seg)) {
        append(du, (seg.velocity * step.length).transpose());
        fn1 = ct::normal_traction_at(seg, point_.parameters().stiffness, fn_start,
                                     t_local + step.length);
        fn.push_back(fn1);
        dt.push_back(step.length);
        t_local = step.end;
      }
      fn_start = fn1;
    }
    const auto n = static_cast<py::ssize_t>(dt.size());
    return py::make_tuple(array_of(du, {n, 2}), array_of(fn, {n}), array_of(dt, {n}));
  }

  // The point from `state` (None: the initial state) over the steps k = 0 .. n-1: row k of each
  // array is the state after step k; "tangent" d f_t / d (du_t, f_n), "state" the last state.
  py::dict along_path(const py::handle& slip, const py::handle& normal, const py::handle& dts,
                      const py::object& state) const {
    const Array dt = checked(dts, {-1}, "dt");
    const py::ssize_t n = dt.shape(0);
    const Array du = checked(slip, {n, 2}, "slip increments");
    const Array fn = checked(normal, {n}, "normal traction");
    ct::ContactState s =
        state.is_none() ? ct::initial_state(case_.model) : contact_state(state.cast<py::dict>());
    std::vector<ct::ContactState> states;
    std::vector<double> tangent;
    std::vector<double> iterations;
    std::string failure;
    {
      const py::gil_scoped_release released;
      for (py::ssize_t k = 0; k < n; ++k) {
        const pt::ContactStep step{{du.at(k, 0), du.at(k, 1)}, fn.at(k), dt.at(k)};
        const pt::ContactUpdate u = point_.update(s, step);
        if (!u.report.ok) {
          failure = "step " + std::to_string(k) + ": " + u.report.why;
          break;
        }
        s = u.state;
        states.push_back(s);
        append(tangent, u.tangent);
        iterations.push_back(u.report.iterations);
      }
    }
    if (!failure.empty()) throw subslip::history::StepFailure(failure);
    return path_dict(states, tangent, iterations, s);
  }

 private:
  static pt::ContactParameters parameters(const subslip::model::ContactCase& c) {
    pt::ContactParameters p = subslip::history::point_parameters(c.model, c.integrator);
    p.tangent = true;  // (the same update; the history needs no tangent)
    return p;
  }

  static py::dict path_dict(const std::vector<ct::ContactState>& states,
                            const std::vector<double>& tangent,
                            const std::vector<double>& iterations, const ct::ContactState& last) {
    std::vector<double> time, slip, traction, fn, mu, r_s, r, vp_slip;
    for (const ct::ContactState& s : states) {
      time.push_back(s.time);
      append(slip, s.slip.transpose());
      append(traction, s.traction_t.transpose());
      fn.push_back(s.traction_n);
      mu.push_back(s.law.mu);
      r_s.push_back(s.law.r_s);
      r.push_back(s.r);
      vp_slip.push_back(s.vp_slip);
    }
    const auto rows = static_cast<py::ssize_t>(states.size());
    py::dict d;
    d["time"] = array_of(time, {rows});
    d["slip"] = array_of(slip, {rows, 2});
    d["traction"] = array_of(traction, {rows, 2});
    d["normal_traction"] = array_of(fn, {rows});
    d["mu"] = array_of(mu, {rows});
    d["r_s"] = array_of(r_s, {rows});
    d["r"] = array_of(r, {rows});
    d["vp_slip"] = array_of(vp_slip, {rows});
    d["tangent"] = array_of(tangent, {rows, 2, 3});
    d["iterations"] = array_of(iterations, {rows});
    d["state"] = contact_state_dict(last);
    return d;
  }

  subslip::model::ContactCase case_;
  pt::ContactPoint point_;
};

// ---- grains ---------------------------------------------------------------------------------

// The fields of a grain state that are per slip system, in the order of the dicts.
constexpr const char* kSlipFields[] = {"mu",   "r_s",        "slip",
                                       "rate", "rate_trend", "rate_trend_change"};

pt::SlipVector* slip_field(pt::GrainState& s, int k) {
  pt::SlipVector* fields[] = {&s.mu, &s.r_s, &s.slip, &s.rate, &s.rate_trend, &s.rate_trend_change};
  return fields[k];
}

// Grain states as a dict of arrays with a leading grain axis: stress (G, 6) (lattice frame,
// Mandel), orientation (G, 3, 3), mu ... rate_trend_change (G, N), trend_step (G,).
py::dict grain_states_dict(std::vector<pt::GrainState> states) {
  const auto g = static_cast<py::ssize_t>(states.size());
  const auto n = static_cast<py::ssize_t>(states.front().mu.size());
  std::vector<double> stress, orientation, trend_step;
  std::vector<std::vector<double>> slip(std::size(kSlipFields));
  for (pt::GrainState& s : states) {
    append(stress, s.stress.transpose());
    append(orientation, s.orientation);
    trend_step.push_back(s.trend_step);
    for (std::size_t k = 0; k < slip.size(); ++k)
      append(slip[k], slip_field(s, static_cast<int>(k))->transpose());
  }
  py::dict d;
  d["stress"] = array_of(stress, {g, 6});
  d["orientation"] = array_of(orientation, {g, 3, 3});
  for (std::size_t k = 0; k < slip.size(); ++k) d[kSlipFields[k]] = array_of(slip[k], {g, n});
  d["trend_step"] = array_of(trend_step, {g});
  return d;
}

std::vector<pt::GrainState> grain_states(const py::dict& d, py::ssize_t grains, int systems) {
  std::vector<pt::GrainState> out(static_cast<std::size_t>(grains));
  const Array stress = checked(d["stress"], {grains, 6}, "state['stress']");
  const Array orientation = checked(d["orientation"], {grains, 3, 3}, "state['orientation']");
  const Array trend_step = checked(d["trend_step"], {grains}, "state['trend_step']");
  for (std::size_t k = 0; k < std::size(kSlipFields); ++k) {
    const std::string what = std::string("state['") + kSlipFields[k] + "']";
    const Array a = checked(d[kSlipFields[k]], {grains, systems}, what.c_str());
    for (py::ssize_t g = 0; g < grains; ++g) {
      pt::SlipVector& v = *slip_field(out[static_cast<std::size_t>(g)], static_cast<int>(k));
      v.resize(systems);
      for (int i = 0; i < systems; ++i) v(i) = a.at(g, i);
    }
  }
  for (py::ssize_t g = 0; g < grains; ++g) {
    pt::GrainState& s = out[static_cast<std::size_t>(g)];
    for (int i = 0; i < 6; ++i) s.stress(i) = stress.at(g, i);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) s.orientation(i, j) = orientation.at(g, i, j);
    s.trend_step = trend_step.at(g);
  }
  return out;
}

// A crystal scene's case with its orientations read.
subslip::model::CrystalCase crystal_case(const std::string& scene, const std::string& text,
                                         const std::string& case_name) {
  subslip::io::CrystalScene parsed = subslip::io::parse_crystal_scene(scene_document(scene, text));
  subslip::model::CrystalCase c = case_named(parsed.cases, case_name, scene);
  if (c.options.method != cr::CrystalMethod::implicit)
    throw InputError(scene, 0, "integrator.method",
                     "a grain point takes the implicit grain step; the scene asks for another");
  return c;
}

// The steps of a crystal case's loading with fixed increments: (L (n, 3, 3), dt (n,)).
py::tuple crystal_steps(const subslip::model::CrystalCase& c, const std::string& scene) {
  std::vector<double> l, dt;
  for (const cr::LoadSegment& seg : c.segments) {
    if (seg.free.any())
      throw InputError(scene, 0, "loading",
                       "mixed control (stress components prescribed): a point takes the whole "
                       "velocity gradient of each step");
    if (seg.rate_control != cr::RateControl::velocity_gradient)
      throw InputError(scene, 0, "loading",
                       "dot_F: a point takes the velocity gradient of each step; give L");
    for (const subslip::integrators::FixedStep& step : segment_steps(seg)) {
      append(l, seg.velocity_gradient);
      dt.push_back(step.length);
    }
  }
  const auto n = static_cast<py::ssize_t>(dt.size());
  return py::make_tuple(array_of(l, {n, 3, 3}), array_of(dt, {n}));
}

Eigen::Matrix3d matrix_at(const Array& a, py::ssize_t k) {
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = a.at(k, i, j);
  return m;
}

// What a path of grain or Taylor updates returns, row k after step k: the sample-frame stress
// as a symmetric matrix (as the file's macro/stress), the tangent d sigma / d (D dt) (Mandel),
// the Newton iterations; and the last state.
struct PathRecord {
  std::vector<double> stress, tangent, iterations;
  std::string failure;

  template <class Update>
  bool add(const Update& u, py::ssize_t k) {
    if (!u.report.ok) {
      failure = "step " + std::to_string(k) + ": " + u.report.why;
      return false;
    }
    append(stress, cr::symmetric_from_mandel(u.stress));
    append(tangent, u.tangent);
    iterations.push_back(u.report.iterations);
    return true;
  }

  py::dict dict(std::vector<pt::GrainState> last) {
    if (!failure.empty()) throw subslip::history::StepFailure(failure);
    const auto n = static_cast<py::ssize_t>(iterations.size());
    py::dict d;
    d["stress"] = array_of(stress, {n, 3, 3});
    d["tangent"] = array_of(tangent, {n, 6, 6});
    d["iterations"] = array_of(iterations, {n});
    d["state"] = grain_states_dict(std::move(last));
    return d;
  }
};

// A Taylor aggregate of a crystal scene's case (its phase, orientations and weights) as one
// material point.
class TaylorPoint {
 public:
  TaylorPoint(const std::string& scene, const std::string& text, const std::string& case_name)
      : scene_(scene), case_(crystal_case(scene, text, case_name)), point_(make(case_)) {}

  py::dict initial_state() const { return grain_states_dict(point_.initial_state().grains); }
  py::tuple steps() const { return crystal_steps(case_, scene_); }
  int grain_count() const { return point_.grain_count(); }

  py::dict along_path(const py::handle& gradients, const py::handle& dts,
                      const py::object& state) const {
    const Array dt = checked(dts, {-1}, "dt");
    const py::ssize_t n = dt.shape(0);
    const Array l = checked(gradients, {n, 3, 3}, "velocity gradients");
    pt::TaylorState s;
    s.grains = state.is_none() ? point_.initial_state().grains
                               : grain_states(state.cast<py::dict>(), point_.grain_count(),
                                              point_.grain().slip_count());
    PathRecord record;
    {
      const py::gil_scoped_release released;
      for (py::ssize_t k = 0; k < n; ++k) {
        pt::TaylorUpdate u = point_.update(s, matrix_at(l, k), dt.at(k));
        if (!record.add(u, k)) break;
        s = std::move(u.state);
      }
    }
    return record.dict(std::move(s.grains));
  }

 private:
  static pt::TaylorPoint make(const subslip::model::CrystalCase& c) {
    std::vector<Eigen::Matrix3d> g;
    std::vector<double> w;
    for (const cr::Orientation& o : c.orientations) {
      g.push_back(o.g);
      w.push_back(o.weight);
    }
    return pt::TaylorPoint(c.phase, std::move(g), std::move(w));
  }

  std::string scene_;
  subslip::model::CrystalCase case_;
  pt::TaylorPoint point_;
};

// One grain of a crystal scene's case.
class GrainPoint {
 public:
  GrainPoint(const std::string& scene, const std::string& text, const std::string& case_name,
             int grain)
      : scene_(scene), case_(crystal_case(scene, text, case_name)), point_(case_.phase) {
    if (grain < 0 || grain >= static_cast<int>(case_.orientations.size()))
      throw py::index_error("grain " + std::to_string(grain) + ": the case has " +
                            std::to_string(case_.orientations.size()) + " grains");
    orientation_ = case_.orientations[static_cast<std::size_t>(grain)].g;
  }

  py::dict initial_state() const { return grain_states_dict({point_.initial_state(orientation_)}); }
  py::tuple steps() const { return crystal_steps(case_, scene_); }

  py::dict along_path(const py::handle& gradients, const py::handle& dts,
                      const py::object& state) const {
    const Array dt = checked(dts, {-1}, "dt");
    const py::ssize_t n = dt.shape(0);
    const Array l = checked(gradients, {n, 3, 3}, "velocity gradients");
    pt::GrainState s = state.is_none()
                           ? point_.initial_state(orientation_)
                           : grain_states(state.cast<py::dict>(), 1, point_.slip_count()).front();
    PathRecord record;
    {
      const py::gil_scoped_release released;
      for (py::ssize_t k = 0; k < n; ++k) {
        pt::GrainUpdate u = point_.update(s, matrix_at(l, k), dt.at(k));
        if (!record.add(u, k)) break;
        s = std::move(u.state);
      }
    }
    return record.dict({s});
  }

  // along_path from the initial state, with the forward sensitivities of the sample-frame stress
  // (n, 3, 3, K) and of mu, r_s and slip (n, N, K) to the K columns of
  // crystal/grain_sensitivity.hpp.
  py::dict sensitivities_along_path(const py::handle& gradients, const py::handle& dts) const {
    const Array dt = checked(dts, {-1}, "dt");
    const py::ssize_t n = dt.shape(0);
    const Array l = checked(gradients, {n, 3, 3}, "velocity gradients");
    pt::GrainState s = point_.initial_state(orientation_);
    pt::GrainSensitivity d = point_.initial_sensitivity();
    PathRecord record;
    std::vector<double> stress, mu, r_s, slip;
    {
      const py::gil_scoped_release released;
      for (py::ssize_t k = 0; k < n; ++k) {
        pt::GrainUpdate u = point_.update(s, matrix_at(l, k), dt.at(k), d);
        if (!record.add(u, k)) break;
        s = std::move(u.state);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            for (int c = 0; c < cr::kGrainParameterCount; ++c)
              stress.push_back(cr::symmetric_from_mandel(d.sample_stress.col(c))(i, j));
        append(mu, d.mu);
        append(r_s, d.r_s);
        append(slip, d.slip);
      }
    }
    const auto steps = static_cast<py::ssize_t>(record.iterations.size());
    py::dict out = record.dict({s});
    const py::ssize_t systems = point_.slip_count(), k = cr::kGrainParameterCount;
    py::list names;
    for (const auto& p : subslip::law::kLawParameters) names.append(std::string(p.name));
    names.append("tau0");
    names.append("initial_mu");
    out["parameters"] = names;
    out["d_stress"] = array_of(stress, {steps, 3, 3, k});
    out["d_mu"] = array_of(mu, {steps, systems, k});
    out["d_r_s"] = array_of(r_s, {steps, systems, k});
    out["d_slip"] = array_of(slip, {steps, systems, k});
    return out;
  }

 private:
  std::string scene_;
  subslip::model::CrystalCase case_;
  pt::GrainPoint point_;
  Eigen::Matrix3d orientation_;
};

// `subslip fit FILE --json`'s report, from the same fit (the GIL released while it computes).
std::string fit_report(const std::string& file) {
  std::ostringstream json;
  {
    const py::gil_scoped_release released;
    const subslip::io::FitFile f = subslip::io::read_fit_file(file);
    subslip::cli::write_fit_json(json, f, subslip::cli::fit_of(f));
  }
  return json.str();
}

// The crystal fit's model (calibration::predict): sigma11 [stress] at the logarithmic axial
// strains `strain` [-] of one grain of the phase of the crystal scene `scene` (its case
// `case_name`), oriented by Bunge Euler angles `euler_deg` [deg], pulled along sample x at
// `strain_rate` [1/time] with sigma22 = sigma33 = 0 and no shear, in at most `increments` steps
// of equal strain (split at every strain). What scripts/make_crystal_fit_curves.py makes its
// curves with.
Array crystal_fit_predict(const std::string& scene, const std::string& text,
                          const std::string& case_name, const std::vector<double>& euler_deg,
                          double strain_rate, const py::handle& strains, int increments) {
  if (euler_deg.size() != 3)
    throw py::value_error("euler_deg: [phi1, Phi, phi2] in degrees expected");
  const Array e = checked(strains, {-1}, "strain");
  subslip::calibration::CrystalCurve curve;
  curve.name = scene;
  curve.orientation = cr::Orientation::from_euler(cr::degrees_to_radians(cr::Vec3(
                                                      euler_deg[0], euler_deg[1], euler_deg[2])))
                          .g;
  curve.strain_rate = strain_rate;
  curve.strain.assign(e.data(), e.data() + e.size());
  curve.stress.assign(curve.strain.size(), 0.0);  // (a measured curve's; the model ignores them)
  const subslip::model::CrystalCase c = crystal_case(scene, text, case_name);
  std::vector<double> stress;
  {
    const py::gil_scoped_release released;
    stress = subslip::calibration::predict(c.phase, curve, {increments}).stress;
  }
  return array_of(stress, {static_cast<py::ssize_t>(stress.size())});
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() =
      "subslip's core: scenes run as `subslip run` runs them, material points (docs/python.md)";
  // The errors are subslip.errors' classes, so that Python code can catch them without this
  // module.
  py::register_exception_translator([](std::exception_ptr p) {
    const auto raise = [](const char* name, const char* what) {
      const py::object type = py::module_::import("subslip.errors").attr(name);
      PyErr_SetString(type.ptr(), what);
    };
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      raise("SceneError", e.what());
    } catch (const subslip::history::StepFailure& e) {
      raise("StepFailure", e.what());
    } catch (const cr::CrystalStepFailure& e) {
      raise("StepFailure", e.what());
    }
  });
  m.def("fit_report", &fit_report, py::arg("file"));
  m.def("crystal_fit_predict", &crystal_fit_predict, py::arg("scene"), py::arg("scene_text"),
        py::arg("case"), py::arg("euler_deg"), py::arg("strain_rate"), py::arg("strain"),
        py::arg("increments") = subslip::calibration::CrystalPathSteps{}.increments);
  m.def("run_scene", &run_scene, py::arg("scene"), py::arg("scene_text"), py::arg("output"),
        py::arg("force"), py::arg("threads"), py::arg("settings") = std::vector<std::string>{});
  m.def(
      "increment_lengths",
      [](double duration, int increments, double growth) {
        const std::vector<double> h = cr::increment_lengths(duration, increments, growth);
        return array_of(h, {static_cast<py::ssize_t>(h.size())});
      },
      py::arg("duration"), py::arg("increments"), py::arg("growth") = 1.0);
  m.def(
      "von_mises_stress", [](const py::handle& t) { return von_mises(t, true); },
      py::arg("stress"));
  m.def(
      "von_mises_strain", [](const py::handle& t) { return von_mises(t, false); },
      py::arg("strain"));
  m.def("equivalent_plastic_strain", &equivalent_plastic_strain, py::arg("slip"),
        py::arg("systems"));
  m.def("weighted_mean_abs", &weighted_mean_abs, py::arg("values"), py::arg("weights"));
  py::class_<ContactPoint>(m, "ContactPoint")
      .def(py::init<std::string, std::string, std::string>())
      .def("initial_state", &ContactPoint::initial_state)
      .def("steps", &ContactPoint::steps)
      .def("along_path", &ContactPoint::along_path);
  py::class_<TaylorPoint>(m, "TaylorPoint")
      .def(py::init<std::string, std::string, std::string>())
      .def("initial_state", &TaylorPoint::initial_state)
      .def("steps", &TaylorPoint::steps)
      .def_property_readonly("grain_count", &TaylorPoint::grain_count)
      .def("along_path", &TaylorPoint::along_path);
  py::class_<GrainPoint>(m, "GrainPoint")
      .def(py::init<std::string, std::string, std::string, int>())
      .def("initial_state", &GrainPoint::initial_state)
      .def("steps", &GrainPoint::steps)
      .def("along_path", &GrainPoint::along_path)
      .def("sensitivities_along_path", &GrainPoint::sensitivities_along_path);
}
