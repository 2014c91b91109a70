// The text layout of the tables and wrapped lines subslip prints (src/io/text_layout.cpp):
// display columns of UTF-8 text, cuts with an ellipsis, wrapping, numbers in a width, tables.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "subslip/io/text_layout.hpp"
#include "terminal_screen.hpp"

namespace text = subslip::io::text;
using subslip::testing::columns_of;

TEST(TextLayout, DisplayWidthCountsColumnsNotBytes) {
  EXPECT_EQ(text::display_width("speed=10"), 8);
  EXPECT_EQ(text::display_width("\u00e4\u00f6\u00fc"), 3);  // two bytes each
  EXPECT_EQ(text::display_width("\u9285\u306e"), 4);        // wide
  EXPECT_EQ(text::display_width("e\u0301"), 1);             // a combining accent
  EXPECT_EQ(text::display_width("\xff\xfe"), 2);            // not UTF-8: a column a byte
}

TEST(TextLayout, FittingKeepsWholeCharactersAndTheEnds) {
  EXPECT_EQ(text::fit_end("speed=10", 8), "speed=10");
  EXPECT_EQ(text::fit_end("speed=1000", 8), "speed...");
  EXPECT_EQ(text::fit_middle("rate=1e-3,grains=10", 11), "rate...s=10");
  EXPECT_EQ(text::fit_middle("rate=1e-3,grains=100", 11), "rate...=100");
  const std::string umlauts = "\u00e4\u00f6\u00fc\u00e4\u00f6\u00fc\u00e4\u00f6\u00fc";
  EXPECT_EQ(text::fit_end(umlauts, 6), "\u00e4\u00f6\u00fc...");
  const std::string wide = "\u9285\u306e\u5f15\u5f35\u8a66\u9a13";  // 12 columns
  EXPECT_EQ(text::fit_end(wide, 8), "\u9285\u306e...");  // 2 x 2 + 3: a half does not fit
  EXPECT_LE(text::display_width(text::fit_middle(wide, 8)), 8);
  EXPECT_EQ(text::fit_end("abcdef", 2), "ab");
  EXPECT_EQ(text::printable("a\tb\nc"), "a?b?c");
}

TEST(TextLayout, WrapBreaksAtSpacesAndBetweenPhrases) {
  EXPECT_EQ(text::wrap_words("short", 80, "  "), std::vector<std::string>{"short"});
  EXPECT_EQ(text::wrap_words("aaa bbb ccc ddd", 8, "  "),
            (std::vector<std::string>{"aaa bbb", "  ccc", "  ddd"}));
  EXPECT_EQ(text::wrap_words("  x /a/very/long/path y", 8, "    "),
            (std::vector<std::string>{"  x", "    /a/very/long/path", "    y"}));
  EXPECT_EQ(text::wrap_phrases({"done in 1 s: 1 case", "0 cutbacks", "0 rejected steps"}, 32, "  "),
            (std::vector<std::string>{"done in 1 s: 1 case, 0 cutbacks,", "  0 rejected steps"}));
}

TEST(TextLayout, NumbersFitTheirColumn) {
  EXPECT_EQ(text::fit_number(65.4, 8), "65.4");
  EXPECT_EQ(text::fit_number(18123.0, 9), "1.812e+04");
  EXPECT_EQ(text::fit_number(18123.0, 8), "1.81e+04");  // a digit less to fit
  EXPECT_EQ(text::fit_number(-1.0e300, 7), "-1e+300");  // any double fits 7 columns
  EXPECT_EQ(text::fit_number(std::nan(""), 7), "-");
}

// A table whose name column must share 80 columns: the separators narrow to one space, then
// names are wrapped onto further lines, whole; no line is ever wider than the table.
TEST(TextLayout, TableRowsNeverExceedTheirWidth) {
  text::Table t({{"case", 0, true}, {"strain_33", 9}, {"stress[MPa]", 10}, {"wall[s]", 7}});
  t.fit_column(0, 12);
  EXPECT_EQ(t.width(), 12 + 9 + 11 + 7 + 3 * 2);
  EXPECT_EQ(t.header(), "case          strain_33  stress[MPa]  wall[s]");
  EXPECT_EQ(t.row({"speed=10", t.number(1, 0.05), t.number(2, -1234.5678), t.number(3, 13.797, 3)}),
            "speed=10           0.05        -1235     13.8");
  t.fit_column(0, 100);
  EXPECT_EQ(t.width(), 80);
  EXPECT_EQ(t.header().find("case "), 0u);
  EXPECT_NE(t.header().find(" strain_33 stress[MPa] wall[s]"), std::string::npos);
  const std::string long_name(120, 'x');
  for (double x : {0.0, -1.0e-300, 1.0e300, -123456789.0, std::nan(""), HUGE_VAL}) {
    const std::string row =
        t.row({long_name + "-end", t.number(1, x), t.number(2, x), t.number(3, x)});
    std::string name;  // the name column of every line, read back
    std::size_t lines = 0;
    for (std::size_t at = 0; at <= row.size(); ++lines) {
      const std::size_t end = std::min(row.find('\n', at), row.size());
      const std::string line = row.substr(at, end - at);
      EXPECT_LE(columns_of(line), 80) << line;
      name += line.substr(0, line.find(' '));
      at = end + 1;
    }
    EXPECT_EQ(name, long_name + "-end") << row;
    EXPECT_EQ(lines, 3u) << row;  // 124 characters in a column of 80 - 9 - 11 - 7 - 3 = 50
    EXPECT_EQ(row.find("-end"), row.rfind('\n') + 1 + 20) << row;
  }
}

// Names are wrapped after their commas, a part wider than the column at its spaces, a word
// wider than it where it reaches the width; every character stays.
TEST(TextLayout, NamesWrapWholeAtCommas) {
  EXPECT_EQ(text::wrap_name("speed=1 mm/min", 20), std::vector<std::string>{"speed=1 mm/min"});
  EXPECT_EQ(text::wrap_name("speed=1 mm/min,eta_v=950 s/mm", 20),
            (std::vector<std::string>{"speed=1 mm/min,", "eta_v=950 s/mm"}));
  EXPECT_EQ(text::wrap_name("a=1,b=2,speed=1 mm/min", 10),
            (std::vector<std::string>{"a=1,b=2,", "speed=1", "mm/min"}));
  EXPECT_EQ(text::wrap_name("direction=[1, 0]", 6),
            (std::vector<std::string>{"direct", "ion=[1", ", 0]"}));
  EXPECT_EQ(text::wrap_name("direction=[1, 0]", 13),
            (std::vector<std::string>{"direction=[1,", "0]"}));
  const std::string wide = "\u9285\u306e\u901f\u3055";  // 4 x 2 columns
  for (const auto& line : text::wrap_name(wide, 3)) EXPECT_EQ(text::display_width(line), 2);
  text::Table t({{"case", 6, true}, {"peak", 5}});
  EXPECT_EQ(t.row({"a=1,b=22", "0.5"}), "a=1,      0.5\nb=22");
}
