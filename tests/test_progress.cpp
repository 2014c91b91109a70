// The progress report of `subslip run` (src/cli/progress.cpp): duration and bar formatting, the
// time-left estimate, a line that fits any terminal width, the terminal's width, the redraw rate
// of the bar and of plain lines under a simulated clock, and the closing summary. No wall times
// are asserted.
#include <gtest/gtest.h>
#include <pty.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "progress.hpp"
#include "terminal_screen.hpp"

using namespace subslip::cli;
using subslip::testing::columns_of;

TEST(Progress, DurationsReadLikeAClock) {
  EXPECT_EQ(format_duration(0.0), "0.0 s");
  EXPECT_EQ(format_duration(0.44), "0.4 s");
  EXPECT_EQ(format_duration(9.9), "9.9 s");
  EXPECT_EQ(format_duration(12.4), "12 s");
  EXPECT_EQ(format_duration(59.4), "59 s");
  EXPECT_EQ(format_duration(59.6), "1 min 00 s");  // rounded before it is split
  EXPECT_EQ(format_duration(185.0), "3 min 05 s");
  EXPECT_EQ(format_duration(3599.4), "59 min 59 s");
  EXPECT_EQ(format_duration(3600.0), "1 h 00 min");
  EXPECT_EQ(format_duration(7620.0), "2 h 07 min");
  EXPECT_EQ(format_duration(86000.0), "23 h 53 min");
  EXPECT_EQ(format_duration(86399.0), "1 d 00 h");  // rounded to minutes first
  EXPECT_EQ(format_duration(3 * 86400.0 + 4 * 3600.0), "3 d 04 h");
  EXPECT_EQ(format_duration(std::nan("")), "--");
  EXPECT_EQ(format_duration(INFINITY), "--");
  EXPECT_EQ(format_duration(-1.0), "--");
}

TEST(Progress, BarFillsInProportion) {
  EXPECT_EQ(format_bar(0.0, 10), "[..........]");
  EXPECT_EQ(format_bar(0.5, 10), "[#####.....]");
  EXPECT_EQ(format_bar(0.999, 10), "[#########.]");  // full only when done
  EXPECT_EQ(format_bar(1.0, 10), "[##########]");
  EXPECT_EQ(format_bar(0.3, 10), "[###.......]");  // 0.3 * 10 is 2.9999...: still three cells
  EXPECT_EQ(format_bar(-0.5, 4), "[....]");
  EXPECT_EQ(format_bar(7.0, 4), "[####]");
  EXPECT_EQ(format_bar(std::nan(""), 4), "[....]");
}

TEST(Progress, TimeLeftFromTheRateSoFar) {
  // A quarter done in 10 s: 30 s left at that rate.
  EXPECT_DOUBLE_EQ(eta_seconds(10.0, 0.25, 0.0), 30.0);
  // A restart that began at 60 % and is at 80 % after 10 s: 10 s left.
  EXPECT_DOUBLE_EQ(eta_seconds(10.0, 0.8, 0.6), 10.0);
  EXPECT_DOUBLE_EQ(eta_seconds(10.0, 1.0, 0.0), 0.0);
  // Too little done to say.
  EXPECT_TRUE(std::isnan(eta_seconds(10.0, 0.0005, 0.0)));
  EXPECT_TRUE(std::isnan(eta_seconds(0.0, 0.5, 0.0)));
}

namespace {

ProgressView view(const std::string& name, double fraction, double elapsed, double eta) {
  ProgressView v;
  v.case_number = 2;
  v.cases = 5;
  v.case_name = name;
  v.fraction = fraction;
  v.elapsed = elapsed;
  v.eta = eta;
  return v;
}

}  // namespace

TEST(Progress, LineNamesCaseFractionAndTimes) {
  ProgressView v = view("speed=10", 0.47, 62.0, 65.0);
  EXPECT_EQ(progress_line(v, 120),
            "case 2/5 speed=10  [##############................]   47.0 %  elapsed 1 min 02 s  "
            "left 1 min 05 s");
  v.eta = std::nan("");
  EXPECT_EQ(progress_text(v), "case 2/5 speed=10   47.0 %  elapsed 1 min 02 s  left --");
}

// Whatever the width, the name, the times and the counts, the line fits: counted here in display
// columns (a CJK character takes two), independently of the program's counting.
TEST(Progress, LineNeverWiderThanTheTerminal) {
  const std::vector<std::string> names{
      "",
      "base",
      "speed=10",
      "loading[0].slide.speed=100,law.overstress.eta_v=0.001,orientations.random.count=1000",
      "Zugversuch-\u00e4\u00f6\u00fc-\u00e9\u00e8-\u00df\u00df\u00df\u00df\u00df\u00df",
      "\u9285\u306e\u5f15\u5f35\u8a66\u9a13\u9285\u306e\u5f15\u5f35\u8a66\u9a13-\u9285\u306e",
      "e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301"
      "e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e\u0301e"
      "\u0301"};
  for (int width : {40, 60, 80, 120, 17, 10, 1}) {
    for (const auto& name : names) {
      for (double fraction : {0.0, 0.473, 1.0}) {
        for (double seconds : {0.4, 62.0, 3599.0, 3.0 * 86400.0, std::nan("")}) {
          ProgressView v = view(name, fraction, seconds, seconds);
          v.case_number = 123;
          v.cases = 4567;
          const std::string line = progress_line(v, width);
          SCOPED_TRACE(line);
          EXPECT_LE(columns_of(line), width) << "width " << width;
          EXPECT_EQ(line.find_first_of("\r\n\x1b"), std::string::npos);
          if (width >= 40) {
            EXPECT_EQ(line.rfind("case 123/4567", 0), 0u);
            EXPECT_NE(line.find(" %"), std::string::npos);  // the fraction always stays
          }
        }
      }
    }
  }
}

// As the width shrinks: the name is cut with "..." (in the middle: sweep names differ at their
// ends), the bar narrows, then the elapsed time, the bar, the name and the time left go in turn.
TEST(Progress, LineGivesUpFieldsInOrder) {
  const ProgressView v = view("grains=1000,rate=1e-3,speed=10", 0.5, 62.0, 65.0);
  EXPECT_EQ(progress_line(v, 200),
            "case 2/5 grains=1000...3,speed=10  [###############...............]   50.0 %  "
            "elapsed 1 min 02 s  left 1 min 05 s");
  EXPECT_EQ(progress_line(v, 85),
            "case 2/5 grain...d=10  [######......]   50.0 %  elapsed 1 min 02 s  left 1 min 05 s");
  EXPECT_EQ(progress_line(v, 79),
            "case 2/5 grain...d=10  [#############..............]   50.0 %  left 1 min 05 s");
  EXPECT_EQ(progress_line(v, 60), "case 2/5 grain...d=10   50.0 %  left 1 min 05 s");
  EXPECT_EQ(progress_line(v, 40), "case 2/5   50.0 %  left 1 min 05 s");
  EXPECT_EQ(progress_line(v, 30), "case 2/5   50.0 %");
  EXPECT_EQ(progress_line(v, 12), "case 2/5 ...");
}

// The bar keeps its width while the times grow ("9.9 s" to "1 min 00 s"): no jitter.
TEST(Progress, BarWidthDoesNotFollowTheTimes) {
  const auto bar_cells = [](double seconds) {
    const std::string line = progress_line(view("base", 0.5, seconds, seconds), 79);
    return line.find(']') - line.find('[');
  };
  EXPECT_EQ(bar_cells(0.5), bar_cells(62.0));
  EXPECT_EQ(bar_cells(9.9), bar_cells(3599.0));
}

TEST(Progress, TerminalWidthFromTheTerminalElseColumnsElse80) {
  EXPECT_EQ(columns_from_environment(nullptr), 80);
  EXPECT_EQ(columns_from_environment("132"), 132);
  EXPECT_EQ(columns_from_environment(""), 80);
  EXPECT_EQ(columns_from_environment("wide"), 80);
  EXPECT_EQ(columns_from_environment("100x"), 80);
  EXPECT_EQ(columns_from_environment("0"), 80);
  EXPECT_EQ(columns_from_environment("-40"), 80);
  const char* saved = std::getenv("COLUMNS");
  const std::string before = saved != nullptr ? saved : "";
  ::setenv("COLUMNS", "100", 1);
  EXPECT_EQ(terminal_columns(-1), 100);  // no terminal: $COLUMNS
  int master = -1;
  int slave = -1;
  winsize size{};
  size.ws_col = 57;
  size.ws_row = 20;
  ASSERT_EQ(::openpty(&master, &slave, nullptr, nullptr, &size), 0);
  EXPECT_EQ(terminal_columns(slave), 57);  // the terminal's own width comes first
  ::close(master);
  ::close(slave);
  ::unsetenv("COLUMNS");
  EXPECT_EQ(terminal_columns(-1), 80);
  if (saved != nullptr) ::setenv("COLUMNS", before.c_str(), 1);
}

TEST(Progress, ModeFollowsTheTerminal) {
  EXPECT_EQ(progress_mode(false, true), ProgressMode::bar);
  EXPECT_EQ(progress_mode(false, false), ProgressMode::lines);
  EXPECT_EQ(progress_mode(true, true), ProgressMode::none);
  EXPECT_EQ(progress_mode(true, false), ProgressMode::none);
}

namespace {

// Captures what a reporter prints, with a clock the test moves.
struct Capture {
  char* buffer = nullptr;
  std::size_t size = 0;
  std::FILE* file = open_memstream(&buffer, &size);
  double now = 100.0;
  ~Capture() {
    std::fclose(file);
    std::free(buffer);
  }
  std::string text() {
    std::fflush(file);
    return std::string(buffer, size);
  }
  ProgressReporter::Clock clock() {
    return [this] { return now; };
  }
};

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST(Progress, OverallFractionWeighsCasesByWork) {
  Capture c;
  const ProgressReporter r(ProgressMode::none, c.file, {1.0, 3.0}, c.clock());
  EXPECT_DOUBLE_EQ(r.overall(0, 0.5), 0.125);
  EXPECT_DOUBLE_EQ(r.overall(0, 1.0), 0.25);
  EXPECT_DOUBLE_EQ(r.overall(1, 0.5), 0.625);
  EXPECT_DOUBLE_EQ(r.overall(1, 1.0), 1.0);
  const ProgressReporter unweighted(ProgressMode::none, c.file, {0.0, 0.0}, c.clock());
  EXPECT_DOUBLE_EQ(unweighted.overall(1, 0.0), 0.5);
}

TEST(Progress, BarRedrawsAtMostFiveTimesASecond) {
  Capture c;
  ProgressReporter r(ProgressMode::bar, c.file, {1.0}, c.clock(), [] { return 80; });
  for (int i = 1; i <= 100; ++i) {  // 100 updates over 2 simulated seconds
    c.now += 0.02;
    r.update(0, "base", i / 100.0);
  }
  const std::string out = c.text();
  const std::size_t draws = count(out, "\r");
  EXPECT_GE(draws, 9u);
  EXPECT_LE(draws, 11u);            // 2 s at 5 per second (+1 for the first)
  EXPECT_EQ(count(out, "\n"), 0u);  // redrawn in place
  // The last bar drawn is within a redraw interval (0.2 s of 2 s) of the end.
  const auto last = out.rfind('\r');
  const double shown = std::atof(out.substr(out.find(']', last) + 1).c_str());
  EXPECT_GE(shown, 90.0);
  EXPECT_LE(shown, 100.0);
  // clear() blanks the line and returns to its start, and the next update draws at once.
  r.clear();
  EXPECT_EQ(c.text().substr(c.text().size() - 4), "\r\x1b[K");
  const std::size_t before = c.text().size();
  r.update(0, "base", 1.0);
  EXPECT_GT(c.text().size(), before);
}

// Every redraw returns to the line's start, fits one column short of the terminal (which may be
// resized between draws) and clears what a longer line left: the bar stays on one line.
TEST(Progress, BarRedrawsInPlaceWithinTheTerminal) {
  Capture c;
  int columns = 120;
  ProgressReporter r(ProgressMode::bar, c.file, {1.0, 1.0, 1.0}, c.clock(),
                     [&columns] { return columns; });
  const std::string name = "a-case-name-of-forty-characters-or-so-xx";
  std::vector<int> widths;
  for (int i = 1; i <= 300; ++i) {
    c.now += 0.25;  // every update draws
    columns = i < 100 ? 120 : i < 200 ? 80 : 40;
    widths.push_back(columns);
    r.update(static_cast<std::size_t>((i - 1) / 100), name, (i % 100) / 100.0);
  }
  const std::string out = c.text();
  EXPECT_EQ(out.find('\n'), std::string::npos);
  std::vector<std::string> draws;
  for (std::size_t at = out.find('\r'); at != std::string::npos;) {
    const std::size_t next = out.find('\r', at + 1);
    draws.push_back(out.substr(at + 1, next == std::string::npos ? next : next - at - 1));
    at = next;
  }
  ASSERT_EQ(draws.size(), widths.size());
  for (std::size_t k = 0; k < draws.size(); ++k) {
    SCOPED_TRACE(draws[k]);
    const std::string clear = "\x1b[K";
    ASSERT_GE(draws[k].size(), clear.size());
    EXPECT_EQ(draws[k].substr(draws[k].size() - clear.size()), clear);
    EXPECT_LE(columns_of(draws[k].substr(0, draws[k].size() - clear.size())), widths[k] - 1);
  }
}

TEST(Progress, PlainLinesEveryTenSeconds) {
  Capture c;
  ProgressReporter r(ProgressMode::lines, c.file, {1.0, 1.0}, c.clock());
  for (int i = 1; i <= 60; ++i) {  // one update a second for a minute
    c.now += 1.0;
    r.update(i <= 30 ? 0 : 1, i <= 30 ? "a" : "b", (i % 30) / 30.0);
  }
  const std::string out = c.text();
  EXPECT_EQ(count(out, "\n"), 6u);
  EXPECT_EQ(count(out, "\r"), 0u);
  EXPECT_EQ(out.rfind("progress: case 1/2 a", 0), 0u);  // the first line after 10 s
  EXPECT_NE(out.find("progress: case 2/2 b"), std::string::npos);
  EXPECT_NE(out.find("left "), std::string::npos);
}

TEST(Progress, QuietPrintsNothing) {
  Capture c;
  ProgressReporter r(ProgressMode::none, c.file, {1.0}, c.clock());
  for (int i = 0; i < 50; ++i) {
    c.now += 1.0;
    r.update(0, "base", i / 50.0);
  }
  r.clear();
  EXPECT_TRUE(c.text().empty());
}

TEST(Progress, RestartCountsOnlyThisSessionsSpeed) {
  Capture c;
  ProgressReporter r(ProgressMode::lines, c.file, {1.0}, c.clock());
  r.set_done_before(0, 0.5);  // half done by the killed run
  c.now += 10.0;
  r.update(0, "base", 0.75);  // a quarter in 10 s: 10 s left, not 3.3 s
  EXPECT_NE(c.text().find("left 10 s"), std::string::npos) << c.text();
}

TEST(Progress, SummaryGivesRatesCountsAndOutput) {
  RunTotals t;
  t.cases = 2;
  t.failed = 1;
  t.increments = 500;
  t.grain_steps = 500000;
  t.solves = 1100000;
  t.newton_iterations = 2673000;
  t.cutbacks = 1;
  t.rejected = 0;
  t.compute_seconds = 25.0;
  // Wrapped to 80 columns between its phrases.
  EXPECT_EQ(summary_text(t, 26.0, "results/default.h5"),
            "done in 26 s: 2 cases (1 failed), 500 increments,\n"
            "  5e+05 grain-steps (2e+04 grain-steps/s),\n"
            "  2.43 Newton iterations per grain solve, 1 cutback, 0 rejected steps\n"
            "results: results/default.h5");
  RunTotals contact;
  contact.cases = 1;
  contact.increments = 2000;
  contact.solves = 2000;
  contact.newton_iterations = 4409;
  // A restart: the counters are this session's; the run's increments and the cases ended
  // before stand beside them.
  RunTotals before;
  before.cases = 1;
  before.increments = 200;
  before.grain_steps = 200000;
  before.solves = 400000;
  before.newton_iterations = 873000;
  before.cutbacks = 1;
  before.compute_seconds = 5.0;
  EXPECT_EQ(summary_text(t, before, 21.0, "results/default.h5"),
            "done in 21 s: 2 cases (1 failed, 1 ended before the restart),\n"
            "  300 increments (500 with the 200 before the restart),\n"
            "  3e+05 grain-steps (1.5e+04 grain-steps/s),\n"
            "  2.57 Newton iterations per grain solve, 0 cutbacks, 0 rejected steps\n"
            "results: results/default.h5");
  EXPECT_EQ(summary_text(t, RunTotals{}, 26.0, "results/default.h5"),
            summary_text(t, 26.0, "results/default.h5"));
  EXPECT_EQ(summary_text(contact, 0.05, "c.h5"),
            "done in 0.1 s: 1 case, 2000 increments, 2.2 Newton iterations per increment,\n"
            "  0 cutbacks, 0 rejected steps\nresults: c.h5");
}
