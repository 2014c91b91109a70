// Compiled in every build: whether the CVODE peer is there, and what its entry points do when it
// is not (the implementations are in study/cvode/, compiled only with SUNDIALS).
#include "subslip/study/cvode_peer.hpp"
#include "subslip/history/contact_history.hpp"

namespace subslip::cvode {

#ifdef SUBSLIP_HAVE_CVODE

bool available() {
  return true;
}

#else

bool available() {
  return false;
}

namespace {
[[noreturn]] void not_built() {
  throw std::runtime_error(
      "this build of subslip has no CVODE: install SUNDIALS (Debian: apt-get install "
      "libsundials-dev) and reconfigure (cmake -DSUBSLIP_WITH_CVODE=ON or AUTO)");
}
}  // namespace

history::RunStats run_contact_history(const contact::ContactModel&,
                                      const std::vector<contact::Segment>&, const CvodeOptions&,
                                      const history::OutputCallback&, CvodeStats*) {
  not_built();
}

crystal::AggregateStats run_taylor_aggregate(const crystal::PhaseDescription&,
                                             const std::vector<crystal::Orientation>&,
                                             const std::vector<crystal::LoadSegment>&,
                                             const CvodeOptions&, const crystal::MacroObserver&,
                                             CvodeStats*) {
  not_built();
}

#endif

}  // namespace subslip::cvode
