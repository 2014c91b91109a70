// Text laid out for a terminal, or for a file read in one: widths in display columns of UTF-8
// text, names and messages shortened with an ellipsis, prose wrapped at spaces, numbers printed
// in a given width, and tables of fixed-width columns. The tables and wrapped text subslip
// prints fit kTextColumns.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace subslip::io::text {

// The width of the tables and wrapped text on standard output: the usual (and smallest common)
// terminal width, so that nothing wraps on such a terminal, whether stdout is one or a file.
inline constexpr int kTextColumns = 80;

// The columns `s` takes on a terminal: one per UTF-8 code point, two for East Asian wide and
// fullwidth characters, none for combining marks; a byte that is not UTF-8 counts one.
int display_width(std::string_view s);

// `s` with control characters (a tab, a newline: they would move the cursor) shown as '?'.
std::string printable(std::string_view s);

// `s` when it fits `width` columns; else its start and "...", `width` columns together.
std::string fit_end(std::string_view s, int width);

// `s` when it fits `width` columns; else its start, "..." and its end: the names of sweep cases
// ("rate=1e-3,grains=10") differ at their ends, which a cut at the end would lose (the progress
// line, which must stay one line).
std::string fit_middle(std::string_view s, int width);

// `s` in lines of at most `width` columns (at least one), every character kept: broken after
// its commas ("speed=1 mm/min," / "eta_v=950"), a part wider than a line after its spaces, a
// word wider than a line wherever it reaches the width. For names that must be read whole.
std::vector<std::string> wrap_name(std::string_view s, int width);

// `text` broken at spaces into lines of at most `width` columns, every line after the first
// starting with `indent`. A word longer than a line stays whole: a path cut in two could not be
// copied.
std::vector<std::string> wrap_words(std::string_view text, int width, std::string_view indent);

// `phrases` joined by ", " into lines of at most `width` columns, broken only between phrases
// ("0 cutbacks" stays together), every line after the first starting with `indent`; a phrase
// longer than a line is wrapped at its spaces.
std::vector<std::string> wrap_phrases(const std::vector<std::string>& phrases, int width,
                                      std::string_view indent);

// `x` printed with %.{digits}g, with fewer digits when that is wider than `width` columns (any
// double fits 7 columns with one digit); "-" for NaN.
std::string fit_number(double x, int width, int digits = 4);

struct Column {
  std::string header;
  int width = 0;              // display columns; at least the header's
  bool left_aligned = false;  // text (names) on the left, numbers on the right
};

// Columns of fixed width, two spaces apart (one when a column of names needs the room): the
// header and every line of a row are at most width() columns whatever the cells hold, since a
// name wider than its column is wrapped onto further lines and any other cell shortened.
class Table {
 public:
  explicit Table(std::vector<Column> columns);

  // Widens `column` towards `wanted` (its longest cell) as far as a table of `total` columns
  // allows, first with two spaces between columns, else with one.
  void fit_column(std::size_t column, int wanted, int total = kTextColumns);

  int width() const;
  int column_width(std::size_t column) const { return columns_.at(column).width; }
  std::string header() const;
  // The cells in their columns, trailing spaces dropped. Left-aligned text (a name) that does
  // not fit is wrapped (wrap_name): the row then takes several lines ('\n' between them), the
  // other cells on the first. Anything else that does not fit is cut at its end.
  std::string row(const std::vector<std::string>& cells) const;
  // `x` in the width of `column` (fit_number).
  std::string number(std::size_t column, double x, int digits = 4) const;

 private:
  int width_with(int separator) const;

  std::vector<Column> columns_;
  int separator_ = 2;
};

}  // namespace subslip::io::text
