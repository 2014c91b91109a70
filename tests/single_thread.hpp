// Test helper: runs the aggregates of a scope on one OpenMP thread.
//
// Most crystal tests run one to a few grains, for which a parallel region per step costs more
// than it gains (on an oversubscribed machine ~0.1 ms a step: 6 s instead of 0.07 s for 60000
// forward Euler steps). Results do not depend on the thread count (CrystalThreads checks it
// bitwise), so this changes only the time a test takes.
#pragma once

#include <omp.h>

namespace subslip::testing {

class SingleThread {
 public:
  SingleThread() { omp_set_num_threads(1); }
  ~SingleThread() { omp_set_num_threads(saved_); }
  SingleThread(const SingleThread&) = delete;
  SingleThread& operator=(const SingleThread&) = delete;

 private:
  int saved_ = omp_get_max_threads();
};

}  // namespace subslip::testing
