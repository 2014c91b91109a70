// The Taylor aggregate's grains (src/crystal/aggregate.cpp): their committed and trial states,
// step reports, consistent tangents and slip-rate histories, one sweep of every grain over a
// step, and the weighted volume averages over them (exact sums: the same bits at any thread or
// rank count). Internal to the aggregate.
#pragma once

#include "grain_update.hpp"
#include "subslip/crystal/aggregate.hpp"

#include <array>
#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace subslip::crystal::aggregate_parts {

inline Mat3 symmetric_part(const Mat3& l) {
  return 0.5 * (l + l.transpose());
}

struct ErrorEstimate {
  double value = 0.0;
  size_t grain = 0;
  int system = -1;
  double scale = 0.0;  // that system's yield scale at the step's start (its estimate's unit)
};

template <int N>
class GrainSweep final : public GrainFields {
 public:
  using VecN = typename SlipTypes<N>::VecN;

  GrainSweep(Phase<N> phase, const std::vector<Mat3>& orientations,
             const std::vector<double>& weights, const VecN& initial_mu, const GrainShare& share);

  const Phase<N>& phase() const { return phase_; }
  const parallel::Team& team() const { return team_; }
  size_t total() const { return total_; }
  std::vector<GrainState<N>>& committed() { return committed_; }
  const std::vector<GrainState<N>>& committed() const { return committed_; }
  std::vector<GrainState<N>>& trial() { return trial_; }
  const std::vector<GrainState<N>>& trial() const { return trial_; }
  std::vector<GrainStepReport>& reports() { return reports_; }
  double trend_step() const { return trend_step_; }
  void set_trend_step(double dt) { trend_step_ = dt; }
  // Where the next cold solves start their grains' Newton iterations: the committed rates
  // continued (continued_rates, the default), the committed rates themselves, or `given` rates
  // (one per grain).
  enum class ColdStart { continued, committed, given };
  void set_cold_starts(ColdStart kind, const std::vector<VecN>* given = nullptr) {
    cold_start_ = kind;
    cold_starts_ = given;
  }
  // The strain directions of the free components the tangents are taken along (set for each
  // mixed-control step).
  StrainDirections& tangent_directions() { return tangent_directions_; }
  // trial_ is no longer the last solve's.
  void forget_solve() { solved_.valid = false; }

  // Runs every grain from the committed state with L; false (and why) when any grain fails.
  bool solve(const Mat3& l, double dt, bool want_tangent, const AggregateOptions& opt,
             AggregateStats& stats, std::string& why, bool warm = false);
  // Whether every grain's report (reports_) is ok; else why, for the first failing grain.
  bool every_grain_ok(AggregateStats& stats, std::string& why);
  // The average stress of trial_: the last solve's where trial_ is still its.
  Vec6 trial_average_stress() const {
    return solved_.valid ? solved_.average_stress : average_stress(trial_);
  }
  Vec6 average_stress(const std::vector<GrainState<N>>& grains) const;
  // Commits the trial states of a step of dt (their slip-rate histories taken along); returns
  // their average stress.
  Vec6 commit(double dt, AggregateStats& stats);
  // The grains' weighted elastic stiffness in the sample frame, over the team.
  Mat6 average_stiffness() const;
  // The largest stress and the largest strength mu f_n of the trial states, over the team.
  std::array<double, 2> largest_stress_and_strength() const;
  // The smallest strength mu f_n (f_n > 0) of any slip system of the trial states, over every
  // rank; the largest double where no plane carries one.
  double smallest_strength() const;
  // The weighted mean of the grains' tangents, in the free components' rows `rows` (the others
  // zero), over the team.
  Tangent mean_tangent(const std::array<int, 6>& rows, int k) const;
  ErrorEstimate local_error(double dt) const;

  // The largest of every grain's and system's error (error_of(g): per system), the same at any
  // thread or rank count: a NaN wins, then the first of the largest in grain order.
  template <class PerGrain>
  ErrorEstimate worst_error(PerGrain&& error_of) const {
    ErrorEstimate worst;
    const auto keep_worse = [&worst](double value, size_t grain, int system, double scale) {
      if (!std::isnan(worst.value) && (std::isnan(value) || value > worst.value))
        worst = {value, grain, system, scale};
    };
    for (size_t g = 0; g < committed_.size(); ++g) {
      const VecN error = error_of(g);
      const VecN scale = yield_scale(phase_, committed_[g]);
      for (int a = 0; a < phase_.slip_count; ++a) keep_worse(error(a), offset_ + g, a, scale(a));
    }
    if (team_.size() == 1) return worst;
    const double mine[4] = {worst.value, static_cast<double>(worst.grain),
                            static_cast<double>(worst.system), worst.scale};
    const std::vector<double> all = team_.all_gather(mine);
    worst = {};
    for (size_t r = 0; r < all.size(); r += 4)
      keep_worse(all[r], static_cast<size_t>(all[r + 1]), static_cast<int>(all[r + 2]), all[r + 3]);
    return worst;
  }

  // The committed states and slip-rate histories in a checkpoint's per-grain layout
  // (AggregateCheckpoint::grains; src/crystal/aggregate_checkpoint.cpp).
  void pack(double* out) const;
  void unpack(const double* in);

  // GrainFields
  int grain_count() const override { return static_cast<int>(committed_.size()); }
  int slip_count() const override { return phase_.slip_count; }
  void values(GrainField f, double* out) const override;

 private:
  void stress(double* out) const;
  void orientation(double* out) const;
  void slip(double* out) const;
  void slip_rate(double* out) const;
  void crss(double* out) const;
  void strength(double* out) const;
  void ratio(double* out) const;
  void subloading_ratio(double* out) const;
  void resolved_shear(double* out) const;
  void solve_implicit_grain(
      size_t gi, const Mat3& l, double dt, const GrainStepOptions& grain_options, Tangent* t,
      bool warm, bool carried, bool slip_tangent,
      const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>& direction_change);
  void note_solved_grain(size_t gi, double dt, std::array<parallel::ExactSum, 6>& part);
  std::string describe_failure(size_t g, const GrainStepReport& rep) const;
  void describe_plane_pressure(const GrainState<N>& s, int system, std::ostringstream& msg) const;
  template <class F>
  void per_grain(double* out, int width, F&& f) const {
    for (size_t g = 0; g < committed_.size(); ++g)
      f(committed_[g], out + g * static_cast<size_t>(width));
  }
  void per_system(double* out, const std::function<double(const GrainState<N>&, int)>& f) const;

  Phase<N> phase_;
  const parallel::Team& team_;
  size_t offset_ = 0;  // of this rank's grains in the aggregate
  size_t total_ = 0;   // grains of the aggregate (over the team)
  std::vector<GrainState<N>> committed_, trial_;
  std::vector<Tangent> tangents_;
  std::vector<GrainStepReport> reports_;
  // The grains' slip-rate history (continued_rates): the rates' change per unit time over the
  // last committed step, trend_, and that trend's change per unit time since the step before,
  // trend_change_ (valid where trend_step_ > 0, the last step's length).
  std::vector<RateHistory<N>> history_;
  double trend_step_ = 0.0;
  // What commit() takes from the grain loop of the last solve (note_solved_grain): each grain's
  // trend and trend change over the step dt solved after one of trend_step, and the average
  // stress of trial_. Valid while trial_ and committed_ are that solve's.
  struct SolvedStep {
    std::vector<RateHistory<N>> history;
    Vec6 average_stress = Vec6::Zero();
    double dt = 0.0, trend_step = 0.0;
    bool valid = false;
  } solved_;
  ColdStart cold_start_ = ColdStart::continued;     // set_cold_starts
  const std::vector<VecN>* cold_starts_ = nullptr;  // (ColdStart::given)
  std::vector<VecN> warm_;      // slip rates of each grain's last successful solve (solve)
  Mat3 warm_l_ = Mat3::Zero();  // the L of that solve
  StrainDirections tangent_directions_ = Mat6::Identity();
  // d dgamma / d(D dt) of each grain from the last solve with tangents, and whether it belongs
  // to the step being solved (solve).
  std::vector<SlipTangent<N>> slip_tangents_;
  bool slip_tangents_current_ = false;
  std::vector<double> weights_;
};

}  // namespace subslip::crystal::aggregate_parts
