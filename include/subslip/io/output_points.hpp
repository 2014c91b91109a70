// Output at chosen points (docs/scenes.md, "Output at chosen points"): a scene's `output.at`
// (and, for crystals, `output.grains_at`) names points on a clock that advances at a constant
// rate within each loading segment: the time, the loading strain (crystal: the integral of the
// segment's largest prescribed |L_ij|, the `strain:` of a segment) or the sliding distance
// (contact: the integral of the sliding speed). The points are an explicit list or a uniform
// spacing (linear or logarithmic); each becomes a time into its segment, which the drivers'
// steps end on exactly (contact::Segment / crystal::LoadSegment output_times).
#pragma once

#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "subslip/io/units.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace subslip::io {

// How the clock advances in one segment: `rate` clock units per unit time over `duration`.
struct ClockSegment {
  double rate = 1.0;
  double duration = 0.0;
};

// At most this many output points (a spacing that would give more is refused at its key).
inline constexpr std::size_t kMaxOutputPoints = 10000000;

struct OutputPoints {
  std::string clock;           // the key: "time", "strain", "distance"
  std::vector<double> values;  // increasing, in (0, end]; 0 (the initial state) is dropped
};

// Reads `node` (`output.at`): a mapping with one of `clocks` as its key, whose value is a list
// of points or a spacing {every: d} / {count: n} with optional from, to (default 0 and the end
// of the loading) and spacing (linear, log). `clock_segments(clock)` gives the clock's rate in
// every segment, `unit_of(clock)` the scene's unit of it (points may be written with a unit of
// the same dimension, "30 s", and are converted). Every problem is an InputError at its key.
template <class ClockOf, class UnitOf>
OutputPoints parse_output_points(const CheckedNode& node,
                                 std::initializer_list<std::string_view> clocks,
                                 ClockOf&& clock_segments, UnitOf&& unit_of);

// The parsing itself, for one clock already chosen (`value` is the node under the clock key).
std::vector<double> parse_points(const CheckedNode& value, const std::string& clock, double end,
                                 const Unit& unit);

// The clock at the end of the loading.
double clock_end(const std::vector<ClockSegment>& segments);

// For every segment, the times into it (increasing, in (0, duration]) that the points fall on;
// a point in a segment where the clock stands still (a hold) falls on the end of the segment
// before. Points closer than round-off fall on one time.
std::vector<std::vector<double>> segment_times(const std::vector<double>& points,
                                               const std::vector<ClockSegment>& segments);

// The union of two sets of segment times (per segment, increasing), and for each time of the
// union whether it is in `b`; times within round-off of each other are one.
struct MergedTimes {
  std::vector<std::vector<double>> times;
  std::vector<std::vector<bool>> in_b;
};
MergedTimes merge_segment_times(const std::vector<std::vector<double>>& a,
                                const std::vector<std::vector<double>>& b,
                                const std::vector<ClockSegment>& segments);

template <class ClockOf, class UnitOf>
OutputPoints parse_output_points(const CheckedNode& node,
                                 std::initializer_list<std::string_view> clocks,
                                 ClockOf&& clock_segments, UnitOf&& unit_of) {
  node.allow_keys(clocks);
  OutputPoints out;
  out.clock = *node.one_of(clocks, true);
  out.values = parse_points(node.required(out.clock), out.clock,
                            clock_end(clock_segments(out.clock)), unit_of(out.clock));
  return out;
}

}  // namespace subslip::io
