// One grain's update over one step, as every caller takes it: the Taylor aggregate's grain sweep
// and the material-point API (include/subslip/material_point.hpp).
//
// Besides the state of the law (GrainState), a grain carries the memory of where its next
// step's Newton iteration starts: the change of its slip rates per unit time over its last step
// (the trend) and the trend's change per unit time since the step before, with the length of the
// last step. A step starts from the committed rates continued along the parabola through the
// rates of the last three committed states (a system whose continued rate would change sign, or
// start from zero, keeps its committed rate): on a loading path the rates change smoothly, and
// this start lies at a third-order distance from the solution. Should the step fail from there,
// it is solved again from the committed rates, with the semismooth step's continuation in the
// strain increment allowed only on that last try.
#pragma once

#include "subslip/crystal/crystal_kernel.hpp"

namespace subslip::crystal {

// The start memory of one grain (see above). trend_step = 0: no committed step yet (or a step
// whose solutions all start from the step's start, as an extrapolated step's do).
template <int N>
struct RateHistory {
  using VecN = typename SlipTypes<N>::VecN;
  VecN trend;         // change of the slip rates per unit time over the last step [1/s^2]
  VecN trend_change;  // the trend's change per unit time between the last two steps [1/s^3]
};

// The committed rates continued over dt (the start of a step's Newton iteration).
template <int N>
typename SlipTypes<N>::VecN continued_rates(const GrainState<N>& committed,
                                            const RateHistory<N>& history, double trend_step,
                                            double dt) {
  const auto& rate = committed.rate;
  typename SlipTypes<N>::VecN start = rate + history.trend * dt;
  if (trend_step > 0.0) start += (0.5 * dt * (dt + trend_step)) * history.trend_change;
  for (int a = 0; a < rate.size(); ++a)
    if (!(start(a) * rate(a) > 0.0)) start(a) = rate(a);
  return start;
}

// The trend after a step of dt from `before` to `after`: the change of the slip rates per unit
// time. A system idle at the step's start has no trend yet: its rate over the step is the onset
// of its slip (after the virgin first step, of every system's), whose continuation (twice that
// rate) is no guess for the next step: from such starts the active sets of the default scene's
// second increment cycled in 757 of 1000 grains.
template <int N>
typename SlipTypes<N>::VecN rate_trend(const GrainState<N>& before, const GrainState<N>& after,
                                       double dt) {
  typename SlipTypes<N>::VecN trend = (after.rate - before.rate) / dt;
  for (int a = 0; a < before.rate.size(); ++a)
    if (before.rate(a) == 0.0) trend(a) = 0.0;
  return trend;
}

// The history after a step of dt from `before` to `after` that followed one of trend_step (0:
// none). `out` may be `history` itself: it is read before it is written.
template <int N>
void history_after_step(const GrainState<N>& before, const GrainState<N>& after,
                        const RateHistory<N>& history, double trend_step, double dt,
                        RateHistory<N>& out) {
  const typename SlipTypes<N>::VecN next = rate_trend(before, after, dt);
  if (trend_step > 0.0)
    out.trend_change = (next - history.trend) / (0.5 * (dt + trend_step));
  else
    out.trend_change.setZero(next.size());
  out.trend = next;
}

// The implicit step from `start` (rates) and, should that fail and `retry` allow it, again
// from the committed rates, the continuation (GrainStepOptions) being allowed only on the last
// try. A cold step retries where its start is not the committed rates already. The report's
// iterations count both tries.
template <int N>
GrainStepReport implicit_step_from(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                   double dt, const GrainStepOptions& opt,
                                   const typename SlipTypes<N>::VecN& start, bool retry,
                                   GrainState<N>& s1, Tangent* tangent,
                                   SlipTangent<N>* slip_tangent = nullptr) {
  GrainStepOptions first = opt;
  if (retry) first.continuation = false;
  GrainStepReport rep =
      implicit_grain_step(ph, s0, L, dt, first, s1, tangent, &start, slip_tangent);
  if (!rep.ok && retry) {
    const int spent = rep.iterations;
    rep = implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, nullptr, slip_tangent);
    rep.iterations += spent;
  }
  return rep;
}

// A cold step of one grain (the first solve of a step): from its committed rates continued
// over dt, then from the committed rates.
template <int N>
GrainStepReport cold_implicit_step(const Phase<N>& ph, const GrainState<N>& s0,
                                   const RateHistory<N>& history, double trend_step, const Mat3& L,
                                   double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                   Tangent* tangent, SlipTangent<N>* slip_tangent = nullptr) {
  const typename SlipTypes<N>::VecN start = continued_rates(s0, history, trend_step, dt);
  return implicit_step_from(ph, s0, L, dt, opt, start, start != s0.rate, s1, tangent, slip_tangent);
}

}  // namespace subslip::crystal
