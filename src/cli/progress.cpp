#include "progress.hpp"

#include <sys/ioctl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iterator>
#include <numeric>
#include <utility>

#include "subslip/io/text_layout.hpp"

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

// What a progress line shows: the case name cut to `name_columns` (0: none), a bar of at most
// `bar_cells` (0: none), and which times.
struct LineLayout {
  int name_columns;
  int bar_cells;
  bool elapsed;
  bool left;
};

// A narrower bar shows too little to be worth its room.
constexpr int kMinBarCells = 10;
// The widest duration up to 1000 days ("59 min 59 s").
constexpr int kDurationColumns = 11;

// From the fullest line to the barest; progress_line takes the first that fits. The fraction
// done and the time left are what a glance at the line is for: they go last, after the elapsed
// time and the bar.
constexpr LineLayout kLayouts[] = {
    {24, ProgressReporter::kBarWidth, true, true},
    {12, ProgressReporter::kBarWidth, true, true},
    {12, ProgressReporter::kBarWidth, false, true},
    {12, 0, false, true},
    {0, 0, false, true},
    {0, 0, false, false},
};

std::string compose(const ProgressView& v, const LineLayout& layout, int bar_cells) {
  std::string line = "case " + std::to_string(v.case_number) + "/" + std::to_string(v.cases);
  if (layout.name_columns > 0 && !v.case_name.empty()) {
    line += ' ';  // appended: GCC 12 warns falsely on "literal" + std::string&&
    line += io::text::fit_middle(io::text::printable(v.case_name), layout.name_columns);
  }
  line += "  ";
  if (bar_cells > 0) line += format_bar(v.fraction, bar_cells) + "  ";
  line += printf_string("%5.1f %%", 100.0 * std::clamp(v.fraction, 0.0, 1.0));
  if (layout.elapsed) line += "  elapsed " + format_duration(v.elapsed);
  if (layout.left) line += "  left " + format_duration(v.eta);
  return line;
}

// The columns the times of `layout` may still grow by: the bar is sized as if they were as wide
// as they get, so that it keeps its width while "9.8 s" becomes "1 min 02 s".
int time_growth(const ProgressView& v, const LineLayout& layout) {
  const auto growth = [](double seconds) {
    return std::max(0, kDurationColumns - io::text::display_width(format_duration(seconds)));
  };
  return (layout.elapsed ? growth(v.elapsed) : 0) + (layout.left ? growth(v.eta) : 0);
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

std::string progress_text(const ProgressView& v) {
  const LineLayout whole{static_cast<int>(v.case_name.size()), 0, true, true};
  return compose(v, whole, 0);
}

std::string progress_line(const ProgressView& v, int width) {
  for (const LineLayout& layout : kLayouts) {
    const std::string without_bar = compose(v, layout, 0);
    const int rest = io::text::display_width(without_bar);
    if (layout.bar_cells == 0) {
      if (rest <= width) return without_bar;
      continue;
    }
    const int room = width - rest - time_growth(v, layout) - 4;  // brackets, two spaces
    const int cells = std::min(layout.bar_cells, room);
    if (cells >= kMinBarCells) return compose(v, layout, cells);
  }
  return io::text::fit_end(compose(v, kLayouts[std::size(kLayouts) - 1], 0), width);
}

int columns_from_environment(const char* value) {
  constexpr int kDefault = 80;
  if (value == nullptr) return kDefault;
  char* end = nullptr;
  const long columns = std::strtol(value, &end, 10);
  if (end == value || *end != '\0' || columns <= 0 || columns > 100000) return kDefault;
  return static_cast<int>(columns);
}

int terminal_columns(int fd) {
  winsize size{};
  if (fd >= 0 && ::ioctl(fd, TIOCGWINSZ, &size) == 0 && size.ws_col > 0) return size.ws_col;
  return columns_from_environment(std::getenv("COLUMNS"));
}

ProgressMode progress_mode(bool quiet, bool terminal) {
  if (quiet) return ProgressMode::none;
  return terminal ? ProgressMode::bar : ProgressMode::lines;
}

ProgressReporter::Clock ProgressReporter::steady_clock() {
  return [] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
}

ProgressReporter::ProgressReporter(ProgressMode mode, std::FILE* out, std::vector<double> case_work,
                                   Clock clock, Columns columns)
    : mode_(mode),
      out_(out),
      clock_(std::move(clock)),
      columns_(std::move(columns)),
      start_(clock_()) {
  if (!columns_) columns_ = [out] { return terminal_columns(::fileno(out)); };
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
    // One column short of the terminal: a character in the last column leaves the cursor
    // waiting to wrap, which some terminals do at once, and the next "\r" would then return to
    // a new line. "\x1b[K" clears what a longer previous line left to the right.
    const int width = std::max(1, columns_() - 1);
    std::fprintf(out_, "\r%s\x1b[K", progress_line(v, width).c_str());
    bar_shown_ = true;
  } else {
    std::fprintf(out_, "progress: %s\n", progress_text(v).c_str());
  }
  std::fflush(out_);
}

void ProgressReporter::clear() {
  if (!bar_shown_) return;
  std::fprintf(out_, "\r\x1b[K");
  std::fflush(out_);
  bar_shown_ = false;
  last_draw_ = -1e300;  // redraw at the next update
}

namespace {

// What this session computed: the run's counters less the earlier sessions'.
RunTotals this_session(const RunTotals& t, const RunTotals& before) {
  RunTotals s = t;
  s.increments -= before.increments;
  s.grain_steps -= before.grain_steps;
  s.solves -= before.solves;
  s.newton_iterations -= before.newton_iterations;
  s.cutbacks -= before.cutbacks;
  s.rejected -= before.rejected;
  s.compute_seconds -= before.compute_seconds;
  return s;
}

}  // namespace

std::string summary_text(const RunTotals& t, double session_seconds, const std::string& output) {
  return summary_text(t, RunTotals{}, session_seconds, output);
}

std::string summary_text(const RunTotals& run, const RunTotals& before, double session_seconds,
                         const std::string& output) {
  const RunTotals t = this_session(run, before);
  std::vector<std::string> phrases{"done in " + format_duration(session_seconds) + ": " +
                                   plural(static_cast<long>(t.cases), "case")};
  std::vector<std::string> notes;
  if (t.failed > 0) notes.push_back(std::to_string(t.failed) + " failed");
  if (before.cases > 0) notes.push_back(std::to_string(before.cases) + " ended before the restart");
  if (!notes.empty()) {
    phrases.back() += " (" + notes[0];
    for (std::size_t k = 1; k < notes.size(); ++k) phrases.back() += ", " + notes[k];
    phrases.back() += ")";
  }
  phrases.push_back(plural(t.increments, "increment"));
  if (before.increments > 0) {
    phrases.back() += " (" + std::to_string(run.increments) + " with the " +
                      std::to_string(before.increments) + " before the restart)";
  }
  if (t.grain_steps > 0) {
    std::string steps = printf_string("%.3g grain-steps", static_cast<double>(t.grain_steps));
    if (t.compute_seconds > 0.0)
      steps += printf_string(" (%.3g grain-steps/s)",
                             static_cast<double>(t.grain_steps) / t.compute_seconds);
    phrases.push_back(steps);
  }
  if (t.solves > 0) {
    phrases.push_back(
        printf_string("%.3g Newton iterations per ",
                      static_cast<double>(t.newton_iterations) / static_cast<double>(t.solves)) +
        (t.grain_steps > 0 ? "grain solve" : "increment"));
  }
  phrases.push_back(plural(t.cutbacks, "cutback"));
  phrases.push_back(plural(t.rejected, "rejected step"));
  std::string s;
  for (const auto& line : io::text::wrap_phrases(phrases, io::text::kTextColumns, "  "))
    s += line + "\n";
  return s + "results: " + output;
}

}  // namespace subslip::cli
