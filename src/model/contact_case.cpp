#include "subslip/model/contact_case.hpp"

namespace subslip::model {

std::string_view to_string(ContactField f) {
  switch (f) {
    case ContactField::time:
      return "time";
    case ContactField::slip:
      return "slip";
    case ContactField::slip_path:
      return "slip_path";
    case ContactField::traction:
      return "traction";
    case ContactField::ratio:
      return "ratio";
    case ContactField::mu:
      return "mu";
    case ContactField::r:
      return "r";
    case ContactField::r_s:
      return "r_s";
    case ContactField::vp_slip:
      return "vp_slip";
    case ContactField::vp_rate:
      return "vp_rate";
    case ContactField::segment:
      return "segment";
  }
  return "?";
}

double last_sliding_speed(const std::vector<contact::Segment>& segments) {
  for (auto it = segments.rbegin(); it != segments.rend(); ++it) {
    if (it->velocity.norm() > 0.0) return it->velocity.norm();
  }
  return 0.0;
}

std::size_t output_count(const std::vector<contact::Segment>& segments) {
  return count_output_states(segments);
}

}  // namespace subslip::model
