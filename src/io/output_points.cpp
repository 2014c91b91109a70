#include "subslip/io/output_points.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "subslip/integrators/step_control.hpp"

namespace subslip::io {

namespace {

// A point this close above the end of the loading (relative) is the end: a spacing or a list
// written from rounded numbers must not fail on the last digit.
constexpr double kEndSlack = 1e-12;

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string end_text(const std::string& clock, double end, const Unit& unit) {
  const bool with_unit = !unit.name.empty() && unit.name != "1";
  return "the end of the loading (" + clock + " " + number(end) +
         (with_unit ? " " + unit.name : std::string()) + ")";
}

// A point of the clock, checked against the end and made exactly the end when within slack.
double within_end(const CheckedNode& at, double v, const std::string& clock, double end,
                  const Unit& unit) {
  if (v > end * (1.0 + kEndSlack) + std::numeric_limits<double>::min())
    at.fail(number(v) + " is beyond " + end_text(clock, end, unit));
  return std::min(v, end);
}

std::vector<double> parse_list(const CheckedNode& value, const std::string& clock, double end,
                               const Unit& unit) {
  if (value.size() == 0) value.fail("needs at least one point");
  std::vector<double> points;
  for (const CheckedNode& element : value.elements()) {
    const double v =
        within_end(element, element.as_quantity(unit, Range::non_negative()), clock, end, unit);
    if (!points.empty() && !(v > points.back()))
      element.fail("must be larger than the point before it (" + number(points.back()) + ")");
    points.push_back(v);
  }
  return points;
}

std::vector<double> parse_spacing(const CheckedNode& value, const std::string& clock, double end,
                                  const Unit& unit) {
  value.allow_keys({"every", "count", "from", "to", "spacing"});
  const std::string how = *value.one_of({"every", "count"}, true);
  const bool log = value.get_choice("spacing", "linear", {"linear", "log"}) == "log";
  const double from = value.get_quantity("from", 0.0, unit, Range::non_negative());
  double to = end;
  if (auto t = value.optional("to"))
    to = within_end(*t, t->as_quantity(unit, Range::positive()), clock, end, unit);
  if (auto f = value.optional("from")) {
    if (!(from < to)) f->fail("must be below 'to' (" + number(to) + ")");
  }
  std::vector<double> points;
  if (how == "every") {
    if (log) value.required("spacing").fail("log spacing needs 'count' ('every' is linear)");
    const CheckedNode every = value.required("every");
    const double step = every.as_quantity(unit, Range::positive());
    const double n = std::floor((to - from) / step);
    if (!(n < static_cast<double>(kMaxOutputPoints))) {
      every.fail("gives " + number(n) + " points from " + number(from) + " to " + number(to) +
                 "; at most " + std::to_string(kMaxOutputPoints) + " (use a larger spacing)");
    }
    for (double k = 0.0; k <= n; k += 1.0) {
      const double v = from + k * step;
      if (v < to * (1.0 - kEndSlack)) points.push_back(v);
    }
    points.push_back(to);  // the end of the range always
    return points;
  }
  const CheckedNode count_node = value.required("count");
  const int count = count_node.as_int(
      Range::in_closed_interval(log ? 2.0 : 1.0, static_cast<double>(kMaxOutputPoints)));
  if (log) {
    const auto f = value.optional("from");
    if (!f) throw value.missing("from", "log spacing needs 'from' > 0");
    if (!(from > 0.0)) f->fail("must be > 0 for log spacing");
    const double ratio = std::log(to / from);
    for (int k = 0; k < count; ++k)
      points.push_back(k == 0           ? from
                       : k + 1 == count ? to
                                        : from * std::exp(ratio * k / (count - 1)));
    return points;
  }
  if (count == 1) return {to};
  for (int k = 0; k < count; ++k)
    points.push_back(k + 1 == count ? to : from + (to - from) * k / (count - 1));
  return points;
}

}  // namespace

std::vector<double> parse_points(const CheckedNode& value, const std::string& clock, double end,
                                 const Unit& unit) {
  std::vector<double> points;
  if (value.is_sequence()) {
    points = parse_list(value, clock, end, unit);
  } else if (value.is_map()) {
    points = parse_spacing(value, clock, end, unit);
  } else {
    value.fail("must be a list of points or a spacing ({every: d} or {count: n}), got " +
               value.kind_name());
  }
  // The initial state is always row 0: a point at 0 is that row.
  points.erase(std::remove(points.begin(), points.end(), 0.0), points.end());
  return points;
}

double clock_end(const std::vector<ClockSegment>& segments) {
  double c = 0.0;
  for (const auto& s : segments) c += s.rate * s.duration;
  return c;
}

std::vector<std::vector<double>> segment_times(const std::vector<double>& points,
                                               const std::vector<ClockSegment>& segments) {
  std::vector<std::vector<double>> out(segments.size());
  std::size_t next = 0;
  double c0 = 0.0;
  for (std::size_t k = 0; k < segments.size() && next < points.size(); ++k) {
    const ClockSegment& s = segments[k];
    const double c1 = c0 + s.rate * s.duration;
    const bool last = k + 1 == segments.size();
    while (next < points.size() && (points[next] <= c1 || last)) {
      const double p = points[next++];
      if (!(s.rate > 0.0)) continue;  // (cannot happen: c1 == c0 takes no point)
      const double t = p >= c1 ? s.duration : std::min(s.duration, (p - c0) / s.rate);
      // Two points are the same time where the clock cannot tell them apart: within round-off
      // of the clock's value there (p), not of the segment's length. Points 3e-17 min apart
      // 5e-11 min into a slide of 0.2 min are two times (an impact's first steps).
      const double same = integrators::kSameTime * p / s.rate;
      auto& times = out[k];
      if (!times.empty() && t <= times.back() + same) continue;  // the same time
      times.push_back(t);
    }
    c0 = c1;
  }
  return out;
}

MergedTimes merge_segment_times(const std::vector<std::vector<double>>& a,
                                const std::vector<std::vector<double>>& b,
                                const std::vector<ClockSegment>& segments) {
  MergedTimes m;
  m.times.resize(segments.size());
  m.in_b.resize(segments.size());
  for (std::size_t k = 0; k < segments.size(); ++k) {
    const double same = integrators::kSameTime * segments[k].duration;
    std::size_t i = 0, j = 0;
    while (i < a[k].size() || j < b[k].size()) {
      const bool take_a = j == b[k].size() || (i < a[k].size() && a[k][i] < b[k][j] - same);
      const bool take_b = i == a[k].size() || (j < b[k].size() && b[k][j] < a[k][i] - same);
      if (take_a) {
        m.times[k].push_back(a[k][i++]);
        m.in_b[k].push_back(false);
      } else if (take_b) {
        m.times[k].push_back(b[k][j++]);
        m.in_b[k].push_back(true);
      } else {  // the same time in both
        m.times[k].push_back(a[k][i++]);
        ++j;
        m.in_b[k].push_back(true);
      }
    }
  }
  return m;
}

}  // namespace subslip::io
