// Test helper: records the macro state and every per-grain field at each output step.
#pragma once

#include <vector>

#include "subslip/crystal/aggregate.hpp"

namespace subslip::testing {

struct GrainSnapshot {
  crystal::MacroState macro;
  std::vector<double> stress, orientation, slip, rate, crss, ratio, r_s;
};

struct GrainRecorder {
  std::vector<GrainSnapshot> snaps;
  crystal::MacroObserver observer() {
    return [this](const crystal::MacroState& m, const crystal::GrainFields& f) {
      GrainSnapshot s;
      s.macro = m;
      const auto g = static_cast<size_t>(f.grain_count());
      const auto n = g * static_cast<size_t>(f.slip_count());
      s.stress.resize(6 * g), s.orientation.resize(9 * g), s.slip.resize(n), s.rate.resize(n),
          s.crss.resize(n), s.ratio.resize(n), s.r_s.resize(n);
      f.values(crystal::GrainField::stress, s.stress.data());
      f.values(crystal::GrainField::orientation, s.orientation.data());
      f.values(crystal::GrainField::slip, s.slip.data());
      f.values(crystal::GrainField::slip_rate, s.rate.data());
      f.values(crystal::GrainField::crss, s.crss.data());
      f.values(crystal::GrainField::r, s.ratio.data());
      f.values(crystal::GrainField::r_s, s.r_s.data());
      snaps.push_back(std::move(s));
    };
  }
};

}  // namespace subslip::testing
