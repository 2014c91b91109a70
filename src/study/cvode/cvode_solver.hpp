// What the contact and crystal CVODE peers share: an owning wrapper of one CVODE BDF solver
// (context, vector, linear solver), the output-point walk over a segment, the counters, and the
// subloading-ratio variable z. Private to src/study/cvode/ (compiled only with SUNDIALS).
#pragma once

#include <cvode/cvode.h>
#include <cvode/cvode_ls.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>

#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

#include "subslip/law/subloading_friction.hpp"
#include "subslip/study/cvode_peer.hpp"

namespace subslip::cvode::detail {

// The subloading ratio as the ODE variable z = 1 - exp(-k H(r_s)), H the slip integral of 1/U
// (see cvode_peer.hpp): dz/dt = k (1 - z) phi while sliding, regular at r_s = 0 and r_s = 1.
class SubloadingVariable {
 public:
  explicit SubloadingVariable(const law::SubloadingFrictionLaw& law);
  double z_of(double r_s) const;
  double ratio_of(double z) const;  // r_s, in [0, 1]
  double sliding_rate(double z, double phi) const { return k_ * (1.0 - z) * phi; }
  double slope(double r_s) const;  // dz/dr_s, finite on [0, 1]

 private:
  const law::SubloadingFrictionLaw* law_;
  law::SubloadingFunction function_;
  double k_;
  law::SubloadingFrictionLaw::SubloadingStart start_;  // r_s = 0
};

// Right-hand side: return 0 on success, > 0 (recoverable) when the state is outside the
// admissible set, so that CVODE retries with a smaller step.
using RhsFunction = int (*)(double t, const double* y, double* ydot, void* user);

// A preconditioner for the Krylov solver (CVODE's CVLsPrecSetupFn / CVLsPrecSolveFn on plain
// arrays). setup returns 0 or > 0 (recoverable failure).
struct Preconditioner {
  int (*setup)(double t, const double* y, bool jok, bool& recomputed, double gamma,
               void* user) = nullptr;
  void (*solve)(const double* r, double* z, void* user) = nullptr;
};

// One CVODE BDF integrator over a state of fixed size. Segments are integrated one after the
// other by restart() (re-initialisation at the segment start) and integrate_to().
class Solver {
 public:
  Solver(int size, RhsFunction rhs, void* user, const CvodeOptions& options,
         const std::vector<double>& absolute_tolerance, bool krylov,
         const Preconditioner& preconditioner = {});
  ~Solver();
  Solver(const Solver&) = delete;
  Solver& operator=(const Solver&) = delete;

  double* state() { return N_VGetArrayPointer(y_); }
  // Starts a segment at t0 from the current state(), never stepping beyond t_stop.
  void restart(double t0, double t_stop);
  // Advances to t_out (<= t_stop) and leaves the state there. With `on_step`, also calls it
  // after every internal step strictly before t_out with the step's time and state.
  // Returns false when CVODE fails (message()).
  bool integrate_to(double t_out, const std::function<void(double t, const double* y)>& on_step);
  // Adds this segment's counters to `stats` (CVODE resets them at every restart).
  void add_counters(CvodeStats& stats) const;
  const std::string& message() const { return message_; }
  void* memory() { return mem_; }
  // The error weights 1 / (rtol |y_i| + atol_i) of the current step (for difference quotients).
  const std::vector<double>& error_weights();

 private:
  static void error_handler(int code, const char* module, const char* function, char* msg,
                            void* self);
  static int rhs_callback(double t, N_Vector y, N_Vector ydot, void* self);
  static int jacobian_callback(double t, N_Vector y, N_Vector fy, SUNMatrix j, void* self, N_Vector,
                               N_Vector, N_Vector);
  static int setup_callback(double t, N_Vector y, N_Vector fy, booleantype jok, booleantype* jcur,
                            double gamma, void* self);
  static int solve_callback(double t, N_Vector y, N_Vector fy, N_Vector r, N_Vector z, double gamma,
                            double delta, int lr, void* self);
  RhsFunction rhs_;
  void* user_;
  Preconditioner preconditioner_;
  std::vector<double> column_, perturbed_, weight_values_;
  long jacobian_rhs_evaluations_ = 0;
  SUNContext ctx_ = nullptr;
  void* mem_ = nullptr;
  N_Vector y_ = nullptr, atol_ = nullptr, scratch_ = nullptr, weights_ = nullptr;
  SUNMatrix matrix_ = nullptr;
  SUNLinearSolver linear_ = nullptr;
  bool initialised_ = false;
  double t_ = 0.0;
  std::string message_;
};

// The output times of a segment that starts at t0: the end of every output increment (every
// output_every-th and the last), as the fixed-step drivers report them. The last is t0 +
// duration exactly.
std::vector<double> output_times(double t0, const std::vector<double>& increments,
                                 int output_every);

// Natural scale for a tolerance: max(|values|), never below `floor`.
double scale_of(std::initializer_list<double> values, double floor);

}  // namespace subslip::cvode::detail
