// The Taylor aggregate's mixed control (src/crystal/aggregate.cpp): the Newton iteration on the
// free components of the prescribed rate (L or dot_F) that brings the free stresses (Cauchy or
// first Piola-Kirchhoff) to their targets, where it starts (the elastic start of a segment, the
// predictor's path of the free components), the first-order correction of the error a step
// accepts, and the velocity gradient a step under dot_F takes. Internal to the aggregate.
#pragma once

#include "grain_sweep.hpp"
#include "subslip/crystal/free_components.hpp"

#include <string>
#include <vector>

namespace subslip::crystal::aggregate_parts {

// L with the free components set to u.
Mat3 assemble_velocity_gradient(const Mat3& prescribed, const std::vector<FreeComponent>& fc,
                                const Eigen::VectorXd& u);

template <int N>
class MixedControl {
 public:
  // The path of the free components of L that a step's mixed-control iteration starts from
  // (MixedPredictor::trend, continued_free). A step accepts free stresses within the tolerance,
  // and the state it commits carries that error into the next step, whose targets are absolute:
  // the L that meets them differs from the path by the error's first-order correction. So the
  // trend is taken along the path (each step's L corrected by its error and by the error it
  // inherited: path = u + (correction - previous correction) / dt), not along the accepted L,
  // and a step starts from the path continued plus the correction of the error it inherits.
  // Along the accepted L the errors were continued too: with a tolerance the first solve meets,
  // they grew as the steps went (a third-order recursion), and the free L oscillated by 2 % of
  // its value (docs/internals.md, "Mixed control").
  struct FreePath {
    Eigen::VectorXd trend;       // the path's change per unit time over the last step (1/s^2)
    Eigen::VectorXd value;       // the path at the last committed step (1/s)
    Eigen::VectorXd correction;  // strain that removes the last step's free-stress error
    bool from_step = false;      // whether value is a committed step's (of this segment)
  };

  // `macro` (its stress scales the tolerance) and `stats` are the aggregate's.
  MixedControl(GrainSweep<N>& grains, const MacroState& macro, AggregateStats& stats)
      : grains_(grains), macro_(macro), stats_(stats) {}

  FreePath& path() { return path_; }
  const FreePath& path() const { return path_; }
  // The strain along the free components that removes the free-stress error of the last step
  // try_step solved, to first order (zero where it solved none: FreePath).
  const Eigen::VectorXd& step_correction() const { return step_correction_; }
  // The largest abs(free stress - target) of the last step try_step solved (0 without free
  // components): what the step's stress is resolved to, at most the free stresses' tolerance.
  double free_stress_error() const { return free_stress_error_; }

  Eigen::VectorXd elastic_free_start(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                     const Mat3& stress_start) const;
  // The velocity gradient of a step of dt from the committed state at the free components u:
  // L itself, or under dot_F the L whose Cayley map over dt takes F_n to F_n + dot_F dt.
  Mat3 step_velocity_gradient(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                              const Eigen::VectorXd& u, double dt) const;
  // The segment's stress measure of the committed state (the start of a segment's ramp).
  Mat3 committed_stress(const LoadSegment& seg) const;
  void forget_free_trend();
  void record_free_step(const Eigen::VectorXd& after, const Eigen::VectorXd& correction, double dt);
  bool try_step(const LoadSegment& seg, const std::vector<FreeComponent>& fc, const Mat3& target,
                double dt, Eigen::VectorXd& u, const AggregateOptions& opt, std::string& why);

  static Eigen::VectorXd zero_correction(const std::vector<FreeComponent>& fc) {
    return Eigen::VectorXd::Zero(static_cast<int>(fc.size()));
  }

 private:
  // The mixed-control residual of the trial state: the free stresses minus their targets.
  struct MixedResidual {
    Eigen::VectorXd value;  // per free component
    double merit = 0.0;     // 1/2 |value|^2, what the line search decreases
    double size = 0.0;      // max |value_a|, what the convergence test bounds
  };

  // What the free stresses of the trial state can be resolved to, below which no L does better.
  struct StressResolution {
    // Round-off of the grain stresses and of the elastic trial increment C D dt they are
    // computed from (a large step's trial is mostly cancelled by the plastic correction).
    double round_off = 0.0;
    // The grains' Newton tolerance: a flow-rule residual delta (traction-ratio units) leaves a
    // resolved-shear error below delta mu f_n (every row's slope dG/dr >= 1), so the stress is
    // a function of L only to about this (measured: 2e-12 .. 1e-11 MPa at mu tau0 = 20 MPa
    // and delta = 1e-12; the bound is 8 delta max(mu f_n)).
    double grain_noise = 0.0;
  };

  // The mixed-control iterate: free components of L, the full L, and its residual (the grains'
  // trial_ and tangents_ belong to it).
  struct MixedIterate {
    Eigen::VectorXd u;
    Mat3 l;
    MixedResidual residual;
  };

  enum class Search { decreased, stalled, failed };

  // What a step's deformation gradient and its change with the unknowns are built from.
  struct StepKinematics {
    Mat3 l;      // the velocity gradient the grains step with
    Mat3 f;      // F_{n+1}, from the committed F_n
    Mat3 rate;   // B = dot_F F_n^-1 (dot_F), or L
    Mat3 f_inv;  // F_n^-1
  };

  // Whether the segment is the velocity gradient under Cauchy targets, whose iteration is on
  // the free L with the free stresses' own rows of the tangent (the general one is on any rate
  // with the whole tangent: first_piola_jacobian).
  static bool cauchy_on_l(const LoadSegment& seg) {
    return seg.rate_control == RateControl::velocity_gradient &&
           seg.stress_measure == StressMeasure::cauchy;
  }
  StepKinematics step_kinematics(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                 const Eigen::VectorXd& u, double dt) const;
  MixedResidual free_stress_residual(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                     const Mat3& target, const Eigen::VectorXd& u, double dt) const;
  Eigen::VectorXd general_elastic_start(const LoadSegment& seg,
                                        const std::vector<FreeComponent>& fc,
                                        const Mat3& stress_start) const;
  Eigen::MatrixXd general_jacobian(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                   const Eigen::VectorXd& u, double dt) const;
  StressResolution stress_resolution(const Mat3& l, double dt, const AggregateOptions& opt) const;
  double free_stress_tolerance(const AggregateOptions& opt, double scale, const Mat3& l,
                               double dt) const;
  Eigen::MatrixXd free_stress_jacobian(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                       const Eigen::VectorXd& u, double dt) const;
  bool evaluate_mixed(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                      const Mat3& target, double dt, const Eigen::VectorXd& u,
                      const AggregateOptions& opt, MixedIterate& out, std::string& why,
                      bool warm = true, bool want_tangent = false);
  Search mixed_line_search(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                           const Mat3& target, double dt, const Eigen::VectorXd& delta,
                           const AggregateOptions& opt, int halvings, MixedIterate& it, int& budget,
                           std::string& why);
  Eigen::VectorXd continued_free(const Eigen::VectorXd& u, double dt) const;
  bool solve_free_components(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                             const Mat3& target, double dt, Eigen::VectorXd& u,
                             const AggregateOptions& opt, std::string& why);

  GrainSweep<N>& grains_;
  const MacroState& macro_;
  AggregateStats& stats_;
  FreePath path_;
  Eigen::VectorXd step_correction_;
  double free_stress_error_ = 0.0;
};

}  // namespace subslip::crystal::aggregate_parts
