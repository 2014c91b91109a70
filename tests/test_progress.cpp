// The progress report of `subslip run` (src/cli/progress.cpp): duration and bar formatting, the
// time-left estimate, the redraw rate of the bar and of plain lines under a simulated clock, and
// the closing summary. No wall times are asserted.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "progress.hpp"

using namespace subslip::cli;

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

TEST(Progress, LineNamesCaseFractionAndTimes) {
  ProgressView v;
  v.case_number = 2;
  v.cases = 5;
  v.case_name = "speed=10";
  v.fraction = 0.47;
  v.elapsed = 62.0;
  v.eta = 65.0;
  EXPECT_EQ(progress_line(v, 10),
            "case 2/5 speed=10  [####......]   47.0 %  elapsed 1 min 02 s  left 1 min 05 s");
  v.eta = std::nan("");
  EXPECT_EQ(progress_line(v, 0), "case 2/5 speed=10   47.0 %  elapsed 1 min 02 s  left --");
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
  ProgressReporter r(ProgressMode::bar, c.file, {1.0}, c.clock());
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
  const std::size_t before = c.text().size();
  r.update(0, "base", 1.0);
  EXPECT_GT(c.text().size(), before);
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
  EXPECT_EQ(summary_text(t, 26.0, "results/default.h5"),
            "done in 26 s: 2 cases (1 failed), 500 increments, 5e+05 grain-steps (2e+04 "
            "grain-steps/s), 2.43 Newton iterations per grain solve, 1 cutback, 0 rejected "
            "steps\nresults: results/default.h5");
  RunTotals contact;
  contact.cases = 1;
  contact.increments = 2000;
  contact.solves = 2000;
  contact.newton_iterations = 4409;
  EXPECT_EQ(summary_text(contact, 0.05, "c.h5"),
            "done in 0.1 s: 1 case, 2000 increments, 2.2 Newton iterations per increment, 0 "
            "cutbacks, 0 rejected steps\nresults: c.h5");
}
