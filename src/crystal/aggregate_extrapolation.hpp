// The Taylor aggregate's extrapolated steps (AggregateOptions::order >= 2;
// src/crystal/aggregate.cpp, integrators/extrapolation.hpp): the work space of one step's solutions
// with 1 .. k backward Euler substeps, their combination into the grains' trial states and the
// macroscopic state, and the combination's error estimate. Internal to the aggregate.
#pragma once

#include "grain_sweep.hpp"
#include "subslip/crystal/free_components.hpp"
#include "subslip/integrators/extrapolation.hpp"

#include <array>
#include <optional>
#include <vector>

namespace subslip::crystal::aggregate_parts {

// The logarithmic strain of a deformation gradient.
Mat3 log_strain(const Mat3& f);

template <int N>
class Extrapolation {
 public:
  using VecN = typename SlipTypes<N>::VecN;
  using MatNN = typename SlipTypes<N>::MatNN;

  explicit Extrapolation(size_t grains) : errors_(grains) {}

  // The grains' states at the step's start, and the solution with j substeps (j = 1 .. k) with
  // its macroscopic state.
  std::vector<GrainState<N>>& start() { return step_start_; }
  std::vector<GrainState<N>>& solution(int j) { return solutions_[static_cast<size_t>(j - 1)]; }
  MacroState& solution_macro(int j) { return solution_macros_[static_cast<size_t>(j - 1)]; }
  // The combined macroscopic state (combine).
  const MacroState& macro() const { return extrapolated_macro_; }

  // The finest solution's substep m (1 .. k) as solved: its grains' slip rates at the end and
  // its free components of L. From them, where substep i of the solution with j < k substeps
  // starts (coarse_substep_start): each grain from the finest's rates at that substep's end
  // (linear in time between the ends of its substeps), the free components from the finest's
  // averaged over the substep's interval (the same strain increment; the first of the finest's
  // substeps carries the correction of the step's inherited free-stress error, which the
  // average spreads over the coarse substep as it should).
  void note_finest_substep(int m, int order, const std::vector<GrainState<N>>& grains,
                           const Eigen::VectorXd& free);
  void coarse_substep_start(int order, int j, int i, std::vector<VecN>& rates,
                            Eigen::VectorXd& free) const;
  // The free components of the finest solution's last substep.
  const Eigen::VectorXd& finest_free(int order) const {
    return finest_free_[static_cast<size_t>(order - 1)];
  }

  // `dt`: the step's length (backward Euler's own estimate on steps with a switch).
  // `flow_residual`: what the solutions' grain steps admitted (admitted_flow_residual).
  // `start_l`: the velocity gradient the grains were loaded by at the step's start (the last
  // step's), or none at a segment's start (the step's own).
  void combine(int order, double dt, double flow_residual, GrainSweep<N>& grains,
               const std::optional<Mat3>& start_l);
  ErrorEstimate error(const GrainSweep<N>& grains) const {
    return grains.worst_error([&](size_t g) { return errors_[g]; });
  }
  // The round-off level of an estimate decided by a system of yield scale `deciding_scale`, of a
  // step whose substeps met their free stresses' targets within `free_stress_error`.
  static double resolution(const Phase<N>& phase, const AggregateOptions& opt,
                           double free_stress_error, double deciding_scale);

 private:
  VecN system_errors(const Phase<N>& phase, const Vec6& stress, const VecN& scale) const;
  // d|tau|/dt of every system at a state (pressure-sensitive: f_n d(|tau| / f_n)/dt), and the
  // rounding of its terms (loading()).
  struct Loading {
    VecN growth, rounding;
    bool loading(int a) const { return growth(a) > rounding(a); }
    bool unloading(int a) const { return growth(a) < -rounding(a); }
  };
  static Loading loading(const Phase<N>& phase, const GrainState<N>& s,
                         const Mat3& velocity_gradient);
  static void add_strength_change(const Phase<N>& phase, const GrainState<N>& s,
                                  const Vec6& strain_rate, const VecN& tau, Loading& out);
  bool switches_phase(const Phase<N>& phase, const GrainState<N>& start, size_t g, int order,
                      const GrainState<N>& combined) const;
  VecN switch_step_errors(const Phase<N>& phase, size_t g, int order, const GrainState<N>& combined,
                          double dt, const Loading& at_start, bool segment_start) const;
  VecN located_starts(const Phase<N>& phase, const MatNN& drive, size_t g, int order,
                      const GrainState<N>& combined, const Loading& at_start,
                      const std::array<bool, SlipTypes<N>::MaxN>& steady,
                      const std::array<bool, SlipTypes<N>::MaxN>& started,
                      const std::array<bool, SlipTypes<N>::MaxN>& stopped) const;
  static VecN located_start_errors(const Phase<N>& phase, const MatNN& drive,
                                   const GrainState<N>& start, const GrainState<N>& one,
                                   const VecN& inverse_relaxation, const VecN& onset,
                                   const VecN& jump, double dt);
  static double inverse_relaxation_of(const Phase<N>& phase, int a, const GrainState<N>& start,
                                      const Vec6& stress, double mu, double r_s, double slip,
                                      double dt);
  void classify_switches_at_start(const Phase<N>& phase, size_t g, int order,
                                  const Loading& at_start,
                                  const std::array<bool, SlipTypes<N>::MaxN>& steady,
                                  std::array<bool, SlipTypes<N>::MaxN>& started,
                                  std::array<bool, SlipTypes<N>::MaxN>& stopped) const;
  static double relaxation_at_end(const Phase<N>& phase, int a, const GrainState<N>& start,
                                  const GrainState<N>& one, double dt);
  static double relaxation_at_start(const Phase<N>& phase, int a, const GrainState<N>& start,
                                    double dt);
  static VecN inverse_relaxations(const Phase<N>& phase, const GrainState<N>& start,
                                  const GrainState<N>& one,
                                  const std::array<bool, SlipTypes<N>::MaxN>& steady, double dt);
  static MatNN driving_interaction(const Phase<N>& phase, const Vec6& stress);
  static VecN relaxed(const Phase<N>& phase, const MatNN& drive, const VecN& inverse_relaxation,
                      const VecN& error, const VecN& drive_error);
  static VecN switching_subloading_errors(const Phase<N>& phase, const GrainState<N>& one,
                                          const GrainState<N>& two,
                                          const std::array<bool, SlipTypes<N>::MaxN>& steady);
  static VecN turn_errors(const Phase<N>& phase, const GrainState<N>& start,
                          const GrainState<N>& combined, const Mat3& start_l, const Mat3& end_l,
                          double dt);
  void combine_macro(int order, const Mat3& velocity_gradient, const GrainSweep<N>& grains);
  Mat3 combined_velocity_gradient(int order) const;

  // The start state, the solutions with 1 .. k substeps, the combined macroscopic state and
  // per-grain error estimates.
  std::vector<GrainState<N>> step_start_;
  std::array<std::vector<GrainState<N>>, integrators::kMaxExtrapolationOrder> solutions_;
  std::array<MacroState, integrators::kMaxExtrapolationOrder> solution_macros_;
  MacroState extrapolated_macro_;
  std::vector<VecN> errors_;
  // The finest solution's rates at the ends of its substeps 1 .. k - 1 (the last one's end is
  // the solution itself), and its free components in each (note_finest_substep).
  std::array<std::vector<VecN>, integrators::kMaxExtrapolationOrder - 1> finest_rates_;
  std::array<Eigen::VectorXd, integrators::kMaxExtrapolationOrder> finest_free_;
};

}  // namespace subslip::crystal::aggregate_parts
