#include "subslip/io/text_layout.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace subslip::io::text {

namespace {

// One character as a terminal shows it: its bytes in the string and its columns.
struct Glyph {
  std::size_t begin;
  std::size_t size;
  int width;
};

// The length of the UTF-8 sequence that `lead` starts; 1 for a byte that starts none.
std::size_t sequence_length(unsigned char lead) {
  if (lead < 0x80) return 1;
  if ((lead >> 5) == 0x6) return 2;
  if ((lead >> 4) == 0xE) return 3;
  if ((lead >> 3) == 0x1E) return 4;
  return 1;
}

bool continuation(unsigned char byte) {
  return (byte >> 6) == 0x2;
}

char32_t decode(std::string_view s, std::size_t begin, std::size_t size) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(s[begin + k]); };
  if (size == 1) return byte(0);
  char32_t c = byte(0) & (0x7F >> size);
  for (std::size_t k = 1; k < size; ++k) c = (c << 6) | (byte(k) & 0x3F);
  return c;
}

bool within(char32_t c, char32_t first, char32_t last) {
  return c >= first && c <= last;
}

// Combining marks, zero-width spaces and joiners, and variation selectors take no column.
bool zero_width(char32_t c) {
  return within(c, 0x0300, 0x036F) || within(c, 0x1AB0, 0x1AFF) || within(c, 0x1DC0, 0x1DFF) ||
         within(c, 0x200B, 0x200F) || within(c, 0x20D0, 0x20FF) || within(c, 0xFE00, 0xFE0F) ||
         within(c, 0xFE20, 0xFE2F);
}

// East Asian wide and fullwidth characters (Hangul, CJK, fullwidth forms, most emoji) take two.
bool double_width(char32_t c) {
  return within(c, 0x1100, 0x115F) || within(c, 0x2E80, 0x303E) || within(c, 0x3041, 0x33FF) ||
         within(c, 0x3400, 0x4DBF) || within(c, 0x4E00, 0x9FFF) || within(c, 0xA000, 0xA4CF) ||
         within(c, 0xAC00, 0xD7A3) || within(c, 0xF900, 0xFAFF) || within(c, 0xFE30, 0xFE4F) ||
         within(c, 0xFF00, 0xFF60) || within(c, 0xFFE0, 0xFFE6) || within(c, 0x1F300, 0x1F64F) ||
         within(c, 0x1F900, 0x1F9FF) || within(c, 0x20000, 0x3FFFD);
}

std::vector<Glyph> glyphs(std::string_view s) {
  std::vector<Glyph> out;
  for (std::size_t i = 0; i < s.size();) {
    std::size_t n = sequence_length(static_cast<unsigned char>(s[i]));
    for (std::size_t k = 1; k < n; ++k) {
      if (i + k >= s.size() || !continuation(static_cast<unsigned char>(s[i + k]))) n = 1;
    }
    const char32_t c = decode(s, i, n);
    out.push_back({i, n, zero_width(c) ? 0 : double_width(c) ? 2 : 1});
    i += n;
  }
  return out;
}

// The longest start of `s` that fits `width` columns (with the marks combining with its last
// character).
std::string front(std::string_view s, int width) {
  std::size_t end = 0;
  int used = 0;
  for (const Glyph& g : glyphs(s)) {
    if (used + g.width > width) break;
    used += g.width;
    end = g.begin + g.size;
  }
  return std::string(s.substr(0, end));
}

// The longest end of `s` that fits `width` columns, not starting with a combining mark.
std::string back(std::string_view s, int width) {
  const std::vector<Glyph> all = glyphs(s);
  std::size_t begin = s.size();
  int used = 0;
  for (auto g = all.rbegin(); g != all.rend(); ++g) {
    if (used + g->width > width) break;
    used += g->width;
    begin = g->begin;
  }
  for (const Glyph& g : all) {
    if (g.begin >= begin && g.width == 0) begin = g.begin + g.size;
    if (g.begin >= begin && g.width > 0) break;
  }
  return std::string(s.substr(begin));
}

const std::string_view kEllipsis = "...";

}  // namespace

std::string printable(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) c = '?';
  }
  return out;
}

int display_width(std::string_view s) {
  int width = 0;
  for (const Glyph& g : glyphs(s)) width += g.width;
  return width;
}

std::string fit_end(std::string_view s, int width) {
  if (display_width(s) <= width) return std::string(s);
  const int ellipsis = static_cast<int>(kEllipsis.size());
  if (width <= ellipsis) return front(s, width);
  return front(s, width - ellipsis) + std::string(kEllipsis);
}

std::string fit_middle(std::string_view s, int width) {
  if (display_width(s) <= width) return std::string(s);
  const int ellipsis = static_cast<int>(kEllipsis.size());
  if (width <= ellipsis) return front(s, width);
  const int kept = width - ellipsis;
  return front(s, (kept + 1) / 2) + std::string(kEllipsis) + back(s, kept / 2);
}

namespace {

// `part` in lines of at most `width` columns: at its spaces, a word too wide where it reaches
// the width. The spaces a break replaces are dropped.
void break_part(std::string_view part, int width, std::vector<std::string>& lines) {
  for (const std::string& line : wrap_words(part, width, "")) {
    std::string_view rest = line;
    while (display_width(rest) > width) {
      std::string head = front(rest, width);
      if (head.empty()) head = front(rest, display_width(rest));  // a glyph wider than `width`
      lines.push_back(head);
      rest.remove_prefix(head.size());
    }
    lines.emplace_back(rest);
  }
}

}  // namespace

std::vector<std::string> wrap_name(std::string_view s, int width) {
  width = std::max(width, 2);      // (a double-width character fits)
  std::vector<std::string> parts;  // each ending after a comma, but the last
  for (std::size_t at = 0; at < s.size();) {
    const std::size_t comma = s.find(',', at);
    const std::size_t end = comma == std::string_view::npos ? s.size() : comma + 1;
    parts.emplace_back(s.substr(at, end - at));
    at = end;
  }
  std::vector<std::string> lines{""};
  for (std::string_view part : parts) {
    if (display_width(lines.back()) + display_width(part) <= width) {
      lines.back() += part;
      continue;
    }
    // A part that starts a line leaves its spaces behind ("[1," / "0]"), as a break at them.
    part.remove_prefix(std::min(part.find_first_not_of(' '), part.size()));
    if (lines.back().empty()) lines.pop_back();
    if (display_width(part) <= width) {
      lines.emplace_back(part);
    } else {
      break_part(part, width, lines);
    }
  }
  return lines;
}

std::vector<std::string> wrap_words(std::string_view text, int width, std::string_view indent) {
  if (display_width(text) <= width) return {std::string(text)};
  const std::size_t first_word = std::min(text.find_first_not_of(' '), text.size());
  std::string line(text.substr(0, first_word));  // the text's own indentation stays
  bool line_empty = true;
  std::vector<std::string> lines;
  for (std::size_t at = first_word; at < text.size();) {
    const std::size_t end = std::min(text.find(' ', at), text.size());
    const std::string_view word = text.substr(at, end - at);
    at = end + 1;
    if (word.empty()) continue;
    if (!line_empty && display_width(line) + 1 + display_width(word) <= width) {
      line += ' ';
      line += word;
      continue;
    }
    if (!line_empty) {
      lines.push_back(line);
      line = std::string(indent);
    }
    line += word;
    line_empty = false;
  }
  lines.push_back(line);
  return lines;
}

std::vector<std::string> wrap_phrases(const std::vector<std::string>& phrases, int width,
                                      std::string_view indent) {
  std::vector<std::string> lines;
  std::string line;
  for (std::size_t k = 0; k < phrases.size(); ++k) {
    const bool last = k + 1 == phrases.size();
    const std::string piece = phrases[k] + (last ? "" : ",");
    const bool starts_line = line.empty() || line == indent;
    if (!starts_line && display_width(line) + 1 + display_width(piece) <= width) {
      line += ' ' + piece;
      continue;
    }
    if (!starts_line) {
      lines.push_back(line);
      line = std::string(indent);
    }
    const auto wrapped = wrap_words(line + piece, width, indent);
    lines.insert(lines.end(), wrapped.begin(), wrapped.end() - 1);
    line = wrapped.back();
  }
  lines.push_back(line);
  return lines;
}

std::string fit_number(double x, int width, int digits) {
  if (std::isnan(x)) return "-";
  char buf[64] = "";
  for (int d = std::max(digits, 1); d >= 1; --d) {
    std::snprintf(buf, sizeof buf, "%.*g", d, x);
    if (display_width(buf) <= width) break;
  }
  return buf;
}

Table::Table(std::vector<Column> columns) : columns_(std::move(columns)) {
  for (Column& c : columns_) c.width = std::max(c.width, display_width(c.header));
}

int Table::width_with(int separator) const {
  const int cells = std::accumulate(columns_.begin(), columns_.end(), 0,
                                    [](int sum, const Column& c) { return sum + c.width; });
  return cells + separator * static_cast<int>(columns_.size() > 0 ? columns_.size() - 1 : 0);
}

void Table::fit_column(std::size_t column, int wanted, int total) {
  Column& c = columns_.at(column);
  const int header = display_width(c.header);
  const int room_wide = total - (width_with(2) - c.width);
  if (wanted <= room_wide) {
    separator_ = 2;
    c.width = std::max(header, wanted);
    return;
  }
  separator_ = 1;
  const int room_narrow = total - (width_with(1) - c.width);
  c.width = std::max(header, std::min(wanted, room_narrow));
}

int Table::width() const {
  return width_with(separator_);
}

std::string Table::header() const {
  std::vector<std::string> cells;
  for (const Column& c : columns_) cells.push_back(c.header);
  return row(cells);
}

std::string Table::row(const std::vector<std::string>& cells) const {
  std::vector<std::vector<std::string>> shown;  // per column, its lines
  std::size_t lines = 1;
  for (std::size_t k = 0; k < columns_.size(); ++k) {
    const Column& c = columns_[k];
    const std::string cell = printable(k < cells.size() ? cells[k] : "");
    shown.push_back(c.left_aligned ? wrap_name(cell, c.width)
                                   : std::vector<std::string>{fit_end(cell, c.width)});
    lines = std::max(lines, shown.back().size());
  }
  std::string out;
  for (std::size_t l = 0; l < lines; ++l) {
    std::string line;
    for (std::size_t k = 0; k < columns_.size(); ++k) {
      const Column& c = columns_[k];
      const std::string text = l < shown[k].size() ? shown[k][l] : "";
      const std::string pad(static_cast<std::size_t>(std::max(0, c.width - display_width(text))),
                            ' ');
      if (k > 0) line.append(static_cast<std::size_t>(separator_), ' ');
      line += c.left_aligned ? text + pad : pad + text;
    }
    line.erase(line.find_last_not_of(' ') + 1);
    out += (l > 0 ? "\n" : "") + line;
  }
  return out;
}

std::string Table::number(std::size_t column, double x, int digits) const {
  return fit_number(x, column_width(column), digits);
}

}  // namespace subslip::io::text
