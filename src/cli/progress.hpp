// Progress of `subslip run` and its closing summary: a bar with the time left on standard error,
// redrawn in place when that is a terminal (at most kRedrawsPerSecond times a second, one line
// that always fits the terminal's width), a plain line every kLineSeconds when it is not, nothing
// with --quiet. Standard output keeps only the results. The drivers only report how far a case
// is (a fraction); everything about time and text is here.
#pragma once

#include <cstddef>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace subslip::cli {

// "0.4 s", "12 s", "3 min 05 s", "2 h 07 min", "3 d 04 h"; "--" when unknown (NaN, infinite or
// negative).
std::string format_duration(double seconds);

// "[#########...........]": `width` cells between the brackets, the first fraction of them '#'.
std::string format_bar(double fraction, int width);

// The time left when `fraction` of the work is done after `elapsed` seconds, the run having
// started (this session) at `start_fraction`: elapsed (1 - fraction) / (fraction -
// start_fraction). NaN until at least 0.1 % of the work (and some time) has gone by.
double eta_seconds(double elapsed, double fraction, double start_fraction);

struct ProgressView {
  std::size_t case_number = 1;  // 1-based
  std::size_t cases = 1;
  std::string case_name;
  double fraction = 0.0;  // of the whole run's work
  double elapsed = 0.0;   // seconds, this session
  double eta = 0.0;       // seconds left (NaN: unknown)
};

// "case 2/5 speed=10   47.0 %  elapsed 1 min 02 s  left 1 min 05 s": the whole text, no bar (the
// plain `progress:` lines).
std::string progress_text(const ProgressView& v);

// "case 2/5 speed=10  [#####.....]   47.0 %  elapsed 1 min 02 s  left 1 min 05 s" in at most
// `width` display columns: as the width shrinks, the case name is cut (with "..."), the bar
// narrows from kBarWidth cells, the elapsed time goes, then the bar, the name and the time left;
// below 17 columns what is left is cut.
std::string progress_line(const ProgressView& v, int width);

// The columns of the terminal on `fd` (TIOCGWINSZ), else $COLUMNS, else 80.
int terminal_columns(int fd);
// $COLUMNS (`value`, may be null) as a width: a positive number, else 80.
int columns_from_environment(const char* value);

enum class ProgressMode { none, bar, lines };
// `terminal`: whether the progress's stream (stderr) is a terminal.
ProgressMode progress_mode(bool quiet, bool terminal);

class ProgressReporter {
 public:
  static constexpr double kRedrawsPerSecond = 5.0;
  static constexpr double kLineSeconds = 10.0;
  static constexpr int kBarWidth = 30;    // cells, when the terminal is wide enough
  using Clock = std::function<double()>;  // monotonic seconds
  using Columns = std::function<int()>;   // the terminal's width now (it may be resized)

  // `case_work`: the relative amount of work of each case (grains x increments, increments...),
  // which weighs the cases in the overall fraction. `out` is where the bar or lines go (stderr);
  // `columns` gives the width of the bar's terminal, by default that of `out`.
  ProgressReporter(ProgressMode mode, std::FILE* out, std::vector<double> case_work,
                   Clock clock = steady_clock(), Columns columns = {});
  // Case `index` is `fraction` (0..1) done; draws when due.
  void update(std::size_t index, const std::string& case_name, double case_fraction);
  // Cases already done before this session (a restart): not counted in the speed.
  void set_done_before(std::size_t index, double case_fraction);
  // Erases the bar so that other text can be printed; the next update draws it again.
  void clear();
  // The fraction of the run's work done when case `index` is `case_fraction` done.
  double overall(std::size_t index, double case_fraction) const;
  double elapsed() const;
  static Clock steady_clock();

 private:
  void draw(const ProgressView& v);

  ProgressMode mode_;
  std::FILE* out_;
  std::vector<double> before_;  // work of the cases before each case, normalised
  std::vector<double> share_;   // each case's share of the work
  Clock clock_;
  Columns columns_;
  double start_;
  double start_fraction_ = 0.0;
  double last_draw_ = -1e300;
  bool bar_shown_ = false;
};

// Totals over the cases of a run, for the closing summary.
struct RunTotals {
  std::size_t cases = 0;
  std::size_t failed = 0;
  long increments = 0;
  long grain_steps = 0;  // 0 for contact runs
  long solves = 0;       // grain solves (crystal) or increments (contact)
  long newton_iterations = 0;
  long cutbacks = 0;
  long rejected = 0;
  double compute_seconds = 0.0;  // summed over cases (across sessions for a restarted case)
};

// "done in 12.3 s: 1 case, 250 increments, 2.5e+05 grain-steps (1.9e+04 grain-steps/s), 2.43
// Newton iterations per grain solve, 1 cutback, 0 rejected steps\nresults: out.h5", the first
// part wrapped into lines of at most 80 columns (continued lines indented by two spaces).
std::string summary_text(const RunTotals& t, double session_seconds, const std::string& output);
// The same for a run an earlier session began (a restart): `t` counts every session, `before`
// the earlier ones (its `cases`: those they ended). The counters are this session's, with the
// run's increments and the cases ended before beside them: "done in 26 s: 1 case, 189
// increments (250 with the 61 before the restart), ...".
std::string summary_text(const RunTotals& t, const RunTotals& before, double session_seconds,
                         const std::string& output);

}  // namespace subslip::cli
