// The run model of a contact scene (`scene: contact`): its cases, each one frictional contact
// point (its law and contact model), a prescribed sliding history, the integrator's options and
// the fields it writes. io/contact_scene.hpp makes one from a scene file; driver/contact_run.hpp
// runs it.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/model/case_common.hpp"
#include "subslip/model/series_compression.hpp"
#include "subslip/model/units.hpp"

namespace subslip::model {

// The time series a contact run can write, in output order.
enum class ContactField {
  time,
  slip,
  slip_path,
  traction,
  ratio,
  mu,
  r,
  r_s,
  vp_slip,
  vp_rate,
  segment,
};
inline constexpr std::array<ContactField, 11> kAllContactFields = {
    ContactField::time,    ContactField::slip,    ContactField::slip_path, ContactField::traction,
    ContactField::ratio,   ContactField::mu,      ContactField::r,         ContactField::r_s,
    ContactField::vp_slip, ContactField::vp_rate, ContactField::segment};
std::string_view to_string(ContactField f);

// One case of a contact scene (the whole scene when it has no sweep).
struct ContactCase {
  std::string name;                      // "base", or built from the sweep overrides
  std::vector<SweepOverride> overrides;  // this case's swept values
  contact::ContactModel model;
  std::vector<contact::Segment> segments;
  history::IntegratorOptions integrator;
  std::vector<ContactField> fields;      // the requested output fields, in kAllContactFields order
  std::vector<WrittenValue> magnitudes;  // for the plausibility warnings (scene_warnings.hpp)
};

struct ContactScene {
  std::string file;    // as given
  std::string text;    // the YAML text, verbatim
  SceneMakeup makeup;  // its base scenes and settings, when it has any
  std::string title;   // "" when the scene has none
  Units units;
  SeriesCompression compression;   // of the finished file (output.compression)
  std::vector<ContactCase> cases;  // in sweep order (first swept key slowest)
};

// The speed |v| of the last segment that slides; 0 when none does.
double last_sliding_speed(const std::vector<contact::Segment>& segments);
// The number of states run_history reports for `segments` (the initial state included).
std::size_t output_count(const std::vector<contact::Segment>& segments);

}  // namespace subslip::model
