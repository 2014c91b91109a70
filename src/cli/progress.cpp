#include "progress.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

namespace subslip::cli {

namespace {

std::string printf_string(const char* format, double a, double b = 0.0) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, a, b);
  return buf;
}

std::string plural(long n, const char* word) {
  return std::to_string(n) + " " + word + (n == 1 ? "" : "s");
}

}  // namespace

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) return "--";
  if (seconds < 9.95) return printf_string("%.1f s", seconds);
  const double s = std::round(seconds);
  if (s < 60.0) return printf_string("%.0f s", s);
  if (s < 3600.0)
    return printf_string("%.0f min %02.0f s", std::floor(s / 60.0), std::fmod(s, 60.0));
  const double m = std::round(seconds / 60.0);
  if (m < 24.0 * 60.0)
    return printf_string("%.0f h %02.0f min", std::floor(m / 60.0), std::fmod(m, 60.0));
  const double h = std::round(seconds / 3600.0);
  return printf_string("%.0f d %02.0f h", std::floor(h / 24.0), std::fmod(h, 24.0));
}

std::string format_bar(double fraction, int width) {
  const double f = std::clamp(std::isfinite(fraction) ? fraction : 0.0, 0.0, 1.0);
  const int full = static_cast<int>(std::floor(f * width + 1e-9));
  std::string bar(1, '[');  // appended: GCC 12 warns falsely on "literal" + std::string&&
  bar.append(static_cast<std::size_t>(full), '#');
  bar.append(static_cast<std::size_t>(width - full), '.');
  return bar + ']';
}

double eta_seconds(double elapsed, double fraction, double start_fraction) {
  const double done = fraction - start_fraction;
  if (!(done >= 1e-3) || !(elapsed > 0.0)) return std::nan("");
  return std::max(0.0, elapsed * (1.0 - fraction) / done);
}

std::string progress_line(const ProgressView& v, int bar_width) {
  std::string line = "case " + std::to_string(v.case_number) + "/" + std::to_string(v.cases);
  if (!v.case_name.empty()) line += " " + v.case_name;
  line += "  ";
  if (bar_width > 0) line += format_bar(v.fraction, bar_width) + "  ";
  line += printf_string("%5.1f %%", 100.0 * std::clamp(v.fraction, 0.0, 1.0));
  line += "  elapsed " + format_duration(v.elapsed);
  line += "  left " + format_duration(v.eta);
  return line;
}

ProgressMode progress_mode(bool quiet, bool output_is_terminal) {
  if (quiet) return ProgressMode::none;
  return output_is_terminal ? ProgressMode::bar : ProgressMode::lines;
}

ProgressReporter::Clock ProgressReporter::steady_clock() {
  return [] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
}

ProgressReporter::ProgressReporter(ProgressMode mode, std::FILE* out, std::vector<double> case_work,
                                   Clock clock)
    : mode_(mode), out_(out), clock_(std::move(clock)), start_(clock_()) {
  double total = std::accumulate(case_work.begin(), case_work.end(), 0.0);
  if (!(total > 0.0)) {  // no weights: every case counts the same
    case_work.assign(case_work.size(), 1.0);
    total = static_cast<double>(case_work.size());
  }
  double sum = 0.0;
  for (double w : case_work) {
    before_.push_back(sum / total);
    share_.push_back(w / total);
    sum += w;
  }
}

double ProgressReporter::overall(std::size_t index, double case_fraction) const {
  if (index >= share_.size()) return 1.0;
  return std::min(1.0, before_[index] + share_[index] * std::clamp(case_fraction, 0.0, 1.0));
}

double ProgressReporter::elapsed() const {
  return clock_() - start_;
}

void ProgressReporter::set_done_before(std::size_t index, double case_fraction) {
  start_fraction_ = overall(index, case_fraction);
}

void ProgressReporter::update(std::size_t index, const std::string& case_name,
                              double case_fraction) {
  if (mode_ == ProgressMode::none) return;
  const double now = clock_();
  const double interval = mode_ == ProgressMode::bar ? 1.0 / kRedrawsPerSecond : kLineSeconds;
  if (mode_ == ProgressMode::lines && last_draw_ < -1e299) last_draw_ = start_;  // first after 10 s
  if (now - last_draw_ < interval) return;
  last_draw_ = now;
  ProgressView v;
  v.case_number = index + 1;
  v.cases = share_.size();
  v.case_name = case_name;
  v.fraction = overall(index, case_fraction);
  v.elapsed = now - start_;
  v.eta = eta_seconds(v.elapsed, v.fraction, start_fraction_);
  draw(v);
}

void ProgressReporter::draw(const ProgressView& v) {
  if (mode_ == ProgressMode::bar) {
    const std::string line = progress_line(v, kBarWidth);
    // Pad over a longer previous line; no newline, the next draw returns to the line start.
    const std::size_t pad = drawn_width_ > line.size() ? drawn_width_ - line.size() : 0;
    std::fprintf(out_, "\r%s%s", line.c_str(), std::string(pad, ' ').c_str());
    drawn_width_ = line.size();
    bar_shown_ = true;
  } else {
    std::fprintf(out_, "progress: %s\n", progress_line(v, 0).c_str());
  }
  std::fflush(out_);
}

void ProgressReporter::clear() {
  if (!bar_shown_) return;
  std::fprintf(out_, "\r%s\r", std::string(drawn_width_, ' ').c_str());
  std::fflush(out_);
  bar_shown_ = false;
  drawn_width_ = 0;
  last_draw_ = -1e300;  // redraw at the next update
}

std::string summary_text(const RunTotals& t, double session_seconds, const std::string& output) {
  std::string s = "done in " + format_duration(session_seconds) + ": " +
                  plural(static_cast<long>(t.cases), "case");
  if (t.failed > 0) s += " (" + std::to_string(t.failed) + " failed)";
  s += ", " + plural(t.increments, "increment");
  if (t.grain_steps > 0) {
    s += printf_string(", %.3g grain-steps", static_cast<double>(t.grain_steps));
    if (t.compute_seconds > 0.0)
      s += printf_string(" (%.3g grain-steps/s)",
                         static_cast<double>(t.grain_steps) / t.compute_seconds);
  }
  if (t.solves > 0) {
    s += printf_string(", %.3g Newton iterations per ",
                       static_cast<double>(t.newton_iterations) / static_cast<double>(t.solves));
    s += t.grain_steps > 0 ? "grain solve" : "increment";
  }
  s += ", " + plural(t.cutbacks, "cutback") + ", " + plural(t.rejected, "rejected step");
  return s + "\nresults: " + output;
}

}  // namespace subslip::cli
