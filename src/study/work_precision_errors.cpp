#include "subslip/study/work_precision.hpp"

#include "work_precision_detail.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

#include "subslip/study/cvode_peer.hpp"

namespace subslip::study {

using namespace work_precision_detail;

namespace {

// An outer node takes part in the interpolation of a bracket only when its spacing is at least
// this fraction of the bracket's. Nodes packed far closer than the bracket (a 1e150-graded
// segment has nodes at 9e-18, 2e-8 and 50 s) turn the cubic into an extrapolation of their local
// slope across the whole bracket: measured, 2e12 between values of 0.1 (a crystal parser-edge
// case of crystal_parser_edges.yaml in `subslip accuracy`). Adaptive steps grow at most 4 times.
constexpr double kSmallestOuterSpacing = 1.0 / 8.0;

// The nodes [first, last] for the bracket [t_j, t_j+1]: widened by a node on the left and one on
// the right, again, to at most four (so shifted inward at the ends of the nodes), never by a node
// whose spacing is below kSmallestOuterSpacing of the bracket's.
std::pair<std::size_t, std::size_t> interpolation_nodes(const std::vector<double>& t,
                                                        std::size_t j) {
  const double least = kSmallestOuterSpacing * (t[j + 1] - t[j]);
  std::size_t first = j, last = j + 1;
  const auto left_ok = [&] { return first > 0 && t[first] - t[first - 1] >= least; };
  const auto right_ok = [&] { return last + 1 < t.size() && t[last + 1] - t[last] >= least; };
  while (last - first < 3) {
    const bool left = left_ok(), right = right_ok();
    if (!left && !right) break;
    if (left) --first;
    if (right && last - first < 3) ++last;
  }
  return {first, last};
}

// Local cubic interpolation on nodes (t strictly increasing), clamped to their span: the cubic
// through the four nodes around x (j-1 .. j+2 for x in [t_j, t_j+1], shifted inward at the ends
// of the nodes; fewer nodes, lower degree, also where outer nodes are packed much closer than
// the bracket). Exact for cubics; the error falls as h^4 where the path is smooth. Every channel
// of the node-major values y (width per node) is interpolated with the same weights.
void local_cubic_at(const std::vector<double>& t, const std::vector<double>& y, int width, double x,
                    std::span<double> out) {
  const auto w = static_cast<std::size_t>(width);
  const auto copy_node = [&](std::size_t k) {
    std::copy(y.begin() + static_cast<std::ptrdiff_t>(k * w),
              y.begin() + static_cast<std::ptrdiff_t>((k + 1) * w), out.begin());
  };
  const std::size_t n = t.size();
  if (n == 1 || x <= t.front()) return copy_node(0);
  if (x >= t.back()) return copy_node(n - 1);
  const auto upper = std::upper_bound(t.begin(), t.end(), x);
  const std::size_t j = static_cast<std::size_t>(upper - t.begin()) - 1;
  if (x == t[j]) return copy_node(j);
  const auto [first, last] = interpolation_nodes(t, j);
  std::fill(out.begin(), out.end(), 0.0);
  for (std::size_t a = first; a <= last; ++a) {
    double weight = 1.0;
    for (std::size_t b = first; b <= last; ++b) {
      if (b != a) weight *= (x - t[b]) / (t[a] - t[b]);
    }
    const double* node = y.data() + a * w;
    for (std::size_t c = 0; c < w; ++c) out[c] += weight * node[c];
  }
}

}  // namespace

// ---- interpolation and errors

PathInterpolant::PathInterpolant(const Trajectory& path) : width_(path.width) {
  for (std::size_t k = 0; k < path.size(); ++k) {
    const int seg = path.segment[k];
    if (pieces_.empty() || pieces_.back().segment != seg) {
      Piece p;
      p.segment = seg;
      if (k > 0) {  // the segment starts where the previous one ended
        p.t.push_back(path.times_into_segments ? 0.0 : path.time[k - 1]);
        const auto v = path.at(k - 1);
        p.y.insert(p.y.end(), v.begin(), v.end());
      }
      pieces_.push_back(std::move(p));
    }
    pieces_.back().t.push_back(path.time[k]);
    const auto v = path.at(k);
    pieces_.back().y.insert(pieces_.back().y.end(), v.begin(), v.end());
  }
}

const PathInterpolant::Piece* PathInterpolant::piece_of(int segment) const {
  for (const auto& p : pieces_)
    if (p.segment == segment) return &p;
  return nullptr;
}

void PathInterpolant::at(double t, int segment, std::span<double> out) const {
  const Piece* p = piece_of(segment);
  if (p == nullptr) {
    throw std::out_of_range("reference path has no segment " + std::to_string(segment));
  }
  if (out.size() != static_cast<std::size_t>(width_)) {
    throw std::invalid_argument("a path of " + std::to_string(out.size()) +
                                " channels compared with a reference of " + std::to_string(width_));
  }
  local_cubic_at(p->t, p->y, width_, t, out);
}

double PathInterpolant::at(double t, int segment) const {
  std::vector<double> out(static_cast<std::size_t>(width_));
  at(t, segment, out);
  return out[0];
}

double PathInterpolant::estimated_error(const ErrorScales& scales) const {
  const auto w = static_cast<std::size_t>(width_);
  double worst = 0.0;
  std::vector<double> value(w);
  for (const auto& p : pieces_) {
    const std::size_t n = p.t.size();
    if (n < 5) continue;
    std::vector<double> t2, y2;
    const auto keep = [&](std::size_t k) {
      t2.push_back(p.t[k]);
      y2.insert(y2.end(), p.y.begin() + static_cast<std::ptrdiff_t>(k * w),
                p.y.begin() + static_cast<std::ptrdiff_t>((k + 1) * w));
    };
    for (std::size_t k = 0; k < n; k += 2) keep(k);
    if ((n - 1) % 2 != 0) keep(n - 1);  // keep the last node
    for (std::size_t k = 1; k + 1 < n; k += 2) {
      local_cubic_at(t2, y2, width_, p.t[k], value);
      const std::span<const double> node(p.y.data() + k * w, w);
      for (std::size_t c = 0; c < w; ++c) {
        const double scale = scales.empty() ? 1.0 : scales[c].at(node);
        worst = std::max(worst, std::abs(value[c] - node[c]) / scale);
      }
    }
  }
  return worst;
}

ErrorAccumulator::ErrorAccumulator(const PathInterpolant& reference, ErrorScales scales)
    : reference_(reference),
      scales_(std::move(scales)),
      interpolated_(static_cast<std::size_t>(reference.width())) {
  if (scales_.size() != interpolated_.size()) {
    throw std::invalid_argument("one error scale per channel of the reference is needed");
  }
}

void ErrorAccumulator::add(double time, std::span<const double> values, int segment) {
  if (values.size() != interpolated_.size()) {
    throw std::invalid_argument("a point of " + std::to_string(values.size()) +
                                " channels compared with a reference of " +
                                std::to_string(interpolated_.size()));
  }
  reference_.at(time, segment, interpolated_);
  double d = 0.0;
  int channel = 0;
  for (std::size_t c = 0; c < values.size(); ++c) {
    const double dc = std::abs(values[c] - interpolated_[c]) / scales_[c].at(interpolated_);
    if (std::isnan(dc) || dc > d) {  // a NaN wins
      d = dc;
      channel = static_cast<int>(c);
      if (std::isnan(dc)) break;
    }
  }
  // The first point sets the maximum; a NaN sticks.
  if (!std::isnan(e_.max_error) && (!any_ || !(d <= e_.max_error))) {
    e_.max_error = d;
    e_.max_error_time = time;
    e_.max_error_channel = channel;
    e_.max_error_segment = segment;
  }
  e_.end_error = d;
  any_ = true;
}

ErrorMeasure ErrorAccumulator::result(bool complete) const {
  if (!complete || !any_) return {};
  return e_;
}

ErrorMeasure measure_error(const Trajectory& run, const PathInterpolant& reference,
                           const ErrorScales& scales, bool complete) {
  ErrorAccumulator acc(reference, scales);
  for (std::size_t k = 0; k < run.size(); ++k) acc.add(run.time[k], run.at(k), run.segment[k]);
  return acc.result(complete);
}

ErrorMeasure measure_error(const Trajectory& run, const PathInterpolant& reference, double scale,
                           bool complete) {
  return measure_error(run, reference, ErrorScales{ErrorScale(scale)}, complete);
}

Trajectory richardson(const Trajectory& fine, const Trajectory& coarse) {
  // The correction y_h - y_2h is known at the coarse points (fine nodes there); it is small and
  // smooth, so interpolating it to the other fine nodes adds only a small fraction of itself.
  const PathInterpolant f(fine);
  const auto w = static_cast<std::size_t>(fine.width);
  std::vector<double> v(w);
  Trajectory correction;
  correction.times_into_segments = fine.times_into_segments;
  for (std::size_t k = 0; k < coarse.size(); ++k) {
    const double t = coarse.time[k];
    f.at(t, coarse.segment[k], v);
    const auto c = coarse.at(k);
    for (std::size_t i = 0; i < w; ++i) v[i] -= c[i];
    correction.add(t, v, coarse.segment[k]);
  }
  const PathInterpolant c(correction);
  Trajectory out;
  out.times_into_segments = fine.times_into_segments;
  for (std::size_t k = 0; k < fine.size(); ++k) {
    const double t = fine.time[k];
    c.at(t, fine.segment[k], v);
    const auto y = fine.at(k);
    for (std::size_t i = 0; i < w; ++i) v[i] += y[i];
    out.add(t, v, fine.segment[k]);
  }
  return out;
}

double median(std::vector<double> values) {
  if (values.empty()) return kNaN;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

}  // namespace subslip::study
