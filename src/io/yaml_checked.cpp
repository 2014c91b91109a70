#include "subslip/io/yaml_checked.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <yaml-cpp/depthguard.h>

#include "subslip/io/text_encoding.hpp"

namespace subslip::io {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::string_view kUnitOne = "1";

std::string format_number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", x);
  return buf;
}

std::string in_quotes(std::string_view s) {
  return "'" + std::string(s) + "'";
}

// A value quoted in a message: long ones (a binary or mangled file read as one scalar) are cut
// at a character boundary, so that the message stays one readable line.
std::string quoted_value(std::string_view s, char quote = '\'') {
  constexpr std::size_t kShown = 60;
  const std::string q(1, quote);
  if (s.size() <= kShown + 20) return q + std::string(s) + q;
  std::size_t n = kShown;
  while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80) --n;
  return q + std::string(s.substr(0, n)) + "..." + q + " (" + std::to_string(s.size()) + " bytes)";
}

std::string join(std::span<const std::string_view> names, std::string_view separator) {
  std::string out;
  for (const auto& n : names) {
    if (!out.empty()) out += separator;
    out += n;
  }
  return out;
}

// YAML marks are 0-based and -1 when the node has no position (created in memory).
int line_of(const YAML::Node& node) {
  if (!node.IsDefined()) return 0;
  const int line = node.Mark().line;
  return line >= 0 ? line + 1 : 0;
}

// A quoted scalar ("1.5") carries the non-specific tag "!"; we do not read it as a number so
// that a string meant as a string is never silently accepted as one.
bool is_quoted(const YAML::Node& node) {
  return node.Tag() == "!";
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// The YAML 1.2 core-schema spellings of infinity and NaN, which from_chars does not know.
std::optional<double> yaml_special_float(std::string_view s) {
  static const std::pair<std::string_view, double> kSpecial[] = {
      {".inf", kInf},
      {"+.inf", kInf},
      {".Inf", kInf},
      {"+.Inf", kInf},
      {".INF", kInf},
      {"-.inf", -kInf},
      {"-.Inf", -kInf},
      {"-.INF", -kInf},
      {".nan", std::numeric_limits<double>::quiet_NaN()},
      {".NaN", std::numeric_limits<double>::quiet_NaN()},
      {".NAN", std::numeric_limits<double>::quiet_NaN()}};
  for (const auto& [name, value] : kSpecial) {
    if (s == name) return value;
  }
  return std::nullopt;
}

// The number without the one sign from_chars does not take, a leading '+' ("+-1" stays wrong).
std::string_view without_plus(std::string_view s) {
  if (s.size() > 1 && s.front() == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  return s;
}

std::optional<double> parse_double(std::string_view text) {
  std::string_view s = trim(text);
  if (auto special = yaml_special_float(s)) return special;
  s = without_plus(s);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec != std::errc() || end != s.data() + s.size() || s.empty()) return std::nullopt;
  return value;
}

// "1e400", "-1e-400": numbers that a double cannot hold.
bool out_of_double_range(std::string_view text) {
  const std::string_view s = without_plus(trim(text));
  double value = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc::result_out_of_range && end == s.data() + s.size();
}

// "168.4 GPa", "1e-3 1/s", "60min": a number, then (after optional blanks) the rest of the text.
struct NumberAndRest {
  double number;
  std::string_view rest;  // trimmed, non-empty
};

// nullopt when the text does not start with a number or has nothing after it; an out-of-range
// number ("1e400 MPa") is reported through `out_of_range`.
std::optional<NumberAndRest> split_number(std::string_view text, bool& out_of_range) {
  const std::string_view s = without_plus(trim(text));
  double value = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (end == s.data() || (ec != std::errc() && ec != std::errc::result_out_of_range))
    return std::nullopt;
  const std::string_view rest = trim(s.substr(static_cast<std::size_t>(end - s.data())));
  if (rest.empty()) return std::nullopt;
  out_of_range = ec == std::errc::result_out_of_range;
  return NumberAndRest{value, rest};
}

// The rest of "5.56 MPa", "1e-3 1/s", "1e-3 /s", "2 %", "3 µm" looks like a unit (rather than
// a typo in the number): it starts with a letter, '/', '%', "1/" or a non-ASCII character.
bool looks_like_unit(std::string_view rest) {
  const auto c = static_cast<unsigned char>(rest.front());
  return std::isalpha(c) || c == '/' || c == '%' || c >= 0x80 || rest.starts_with("1/");
}

// The line that starts a second document in `text`, whose first document's content starts on
// line `first` (1-based): a '---' line after it, or content after a '...' line; 0 when there is
// none. (A document marker at column 0 cannot be inside a scalar of a mapping.) Found in the
// text because yaml-cpp's LoadAll loops for ever on some broken inputs (",s", a fuzz finding).
int second_document_line(std::string_view text, int first) {
  auto is_marker = [](std::string_view line, std::string_view marker) {
    return line.starts_with(marker) &&
           (line.size() == 3 || std::isspace(static_cast<unsigned char>(line[3])));
  };
  int line = 0;
  bool ended = false;  // after a '...' line
  for (std::size_t start = 0; start <= text.size();) {
    ++line;
    const std::size_t end = std::min(text.find('\n', start), text.size());
    const std::string_view raw = text.substr(start, end - start);
    start = end + 1;
    if (line <= first) continue;
    if (is_marker(raw, "---")) return line;
    const std::string_view content = trim(raw);
    if (ended && !content.empty() && !content.starts_with('#')) return line;
    ended = ended || is_marker(raw, "...");
  }
  return 0;
}

}  // namespace

std::optional<double> parse_number(std::string_view text) {
  return parse_double(text);
}

// ---------------------------------------------------------------- Range

Range::Range(double lo, bool lo_open, double hi, bool hi_open)
    : lo_(lo), hi_(hi), lo_open_(lo_open), hi_open_(hi_open) {}

Range Range::any() {
  return {-kInf, false, kInf, false};
}
Range Range::positive() {
  return {0.0, true, kInf, false};
}
Range Range::non_negative() {
  return {0.0, false, kInf, false};
}
Range Range::at_least(double lo) {
  return {lo, false, kInf, false};
}
Range Range::greater_than(double lo) {
  return {lo, true, kInf, false};
}
Range Range::at_most(double hi) {
  return {-kInf, false, hi, false};
}
Range Range::in_open_interval(double lo, double hi) {
  return {lo, true, hi, true};
}
Range Range::in_closed_interval(double lo, double hi) {
  return {lo, false, hi, false};
}

bool Range::contains(double x) const {
  const bool above = lo_open_ ? x > lo_ : x >= lo_;
  const bool below = hi_open_ ? x < hi_ : x <= hi_;
  return above && below;
}

std::string Range::describe() const {
  const bool has_lo = lo_ > -kInf, has_hi = hi_ < kInf;
  if (has_lo && has_hi) {
    return std::string("in ") + (lo_open_ ? "(" : "[") + format_number(lo_) + ", " +
           format_number(hi_) + (hi_open_ ? ")" : "]");
  }
  if (has_lo) return std::string(lo_open_ ? "> " : ">= ") + format_number(lo_);
  if (has_hi) return std::string(hi_open_ ? "< " : "<= ") + format_number(hi_);
  return {};
}

// ---------------------------------------------------------------- suggestions

std::size_t edit_distance(std::string_view a, std::string_view b) {
  // One row of the dynamic-programming table at a time.
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + cost});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::optional<std::string_view> nearest_name(std::string_view word,
                                             std::span<const std::string_view> candidates) {
  std::optional<std::string_view> best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_distance) {
      best = c;
      best_distance = d;
    }
  }
  if (!best) return std::nullopt;
  // A plausible typo: a couple of edits (more for long names), and not a complete rewrite.
  const std::size_t allowed = std::max<std::size_t>(2, word.size() / 3);
  const std::size_t longest = std::max(word.size(), best->size());
  if (best_distance <= allowed && best_distance < longest) return best;
  return std::nullopt;
}

std::string suggestion(std::string_view word, std::span<const std::string_view> candidates) {
  if (auto near = nearest_name(word, candidates)) return "did you mean " + in_quotes(*near) + "?";
  return "expected one of: " + join(candidates, ", ");
}

// ---------------------------------------------------------------- YamlDocument

YamlDocument::YamlDocument(std::shared_ptr<const SceneSources> sources, YAML::Node root)
    : sources_(std::move(sources)),
      origin_(std::make_shared<const SceneOrigin>(SceneOrigin{
          sources_->scene.file, std::filesystem::path(sources_->scene.file).parent_path(), true})),
      origins_(std::make_shared<Origins>()),
      root_(std::move(root)) {}

YamlDocument YamlDocument::copy() const {
  return compose(*sources_);
}

void YamlDocument::note_origin(const YAML::Node& node,
                               std::shared_ptr<const SceneOrigin> origin) const {
  origins_->emplace_back(node, std::move(origin));
}

YamlDocument YamlDocument::from_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path.string(), 0, "", "is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(path.string(), 0, "",
                     "cannot read file: " + std::string(std::strerror(errno)));
  std::ostringstream text;
  text << in.rdbuf();
  return from_string(text.str(), path.string());
}

YamlDocument YamlDocument::from_string(std::string bytes, std::string file_name) {
  auto file = std::make_shared<const std::string>(std::move(file_name));
  std::string text = decode_text(std::move(bytes), *file);  // UTF-8 from here on
  try {
    YAML::Node root = YAML::Load(text);
    // A second document (after a '---' line) would be ignored without a word: refused.
    const int second = line_of(root) > 0 ? second_document_line(text, line_of(root)) : 0;
    if (second > 0) {
      throw InputError(*file, second, "",
                       "a second YAML document starts here (a scene is one document): remove "
                       "the '---' line or split the file");
    }
    return YamlDocument(
        std::make_shared<const SceneSources>(SceneSources{{*file, std::move(text)}, {}, {}}),
        std::move(root));
  } catch (const YAML::DeepRecursion& e) {
    // (yaml-cpp gives this one the message "bad file".)
    throw InputError(*file, e.mark.is_null() ? 0 : e.mark.line + 1, "",
                     "YAML nested too deeply: hundreds of mappings or sequences inside one "
                     "another, beyond the parser's limit (a scene needs a few)");
  } catch (const YAML::Exception& e) {
    // e.msg is the bare message; e.what() repeats the position in yaml-cpp's own words.
    const int line = e.mark.is_null() ? 0 : e.mark.line + 1;
    throw InputError(*file, line, "", "YAML syntax error: " + e.msg);
  }
}

CheckedNode YamlDocument::root() const {
  return CheckedNode(root_, origin_, origins_, "", 0);
}

// ---------------------------------------------------------------- CheckedNode: basics

CheckedNode::CheckedNode(YAML::Node node, std::shared_ptr<const SceneOrigin> origin,
                         std::shared_ptr<const YamlDocument::Origins> origins, std::string path,
                         int key_line)
    : node_(std::move(node)),
      origin_(std::move(origin)),
      origins_(std::move(origins)),
      path_(std::move(path)),
      key_line_(key_line) {}

int CheckedNode::line() const {
  if (!origin_->has_lines) return 0;
  // An empty value is positioned by yaml-cpp after its key, often on the next line.
  if (is_null()) return key_line_;
  const int own = line_of(node_);
  return own > 0 ? own : key_line_;
}

std::shared_ptr<const SceneOrigin> CheckedNode::origin_of(const YAML::Node& n) const {
  if (origins_ && n.IsDefined()) {
    // The latest note first: a value set over one taken from a base is the setting's.
    for (auto it = origins_->rbegin(); it != origins_->rend(); ++it) {
      if (it->first.is(n)) return it->second;
    }
  }
  return origin_;
}

int CheckedNode::line_in_source(const YAML::Node& n) const {
  return origin_of(n)->has_lines ? line_of(n) : 0;
}

CheckedNode CheckedNode::renamed(std::string path) const {
  return CheckedNode(node_, origin_, origins_, std::move(path), key_line_);
}

InputError CheckedNode::error(const std::string& message) const {
  return InputError(origin_->label, line(), path_, message);
}

void CheckedNode::fail(const std::string& message) const {
  throw error(message);
}

bool CheckedNode::is_null() const {
  return !node_.IsDefined() || node_.IsNull();
}
bool CheckedNode::is_scalar() const {
  return node_.IsDefined() && node_.IsScalar();
}
bool CheckedNode::is_sequence() const {
  return node_.IsDefined() && node_.IsSequence();
}
bool CheckedNode::is_map() const {
  return node_.IsDefined() && node_.IsMap();
}

std::string CheckedNode::kind_name() const {
  if (is_null()) return "nothing (an empty value)";
  if (is_map()) return "a mapping";
  if (is_sequence()) return "a sequence";
  if (is_quoted(node_)) return "the quoted string " + quoted_value(node_.Scalar(), '"');
  return quoted_value(node_.Scalar());
}

void CheckedNode::expect_map() const {
  if (!is_map()) fail("expected a mapping (key: value), got " + kind_name());
}

void CheckedNode::expect_sequence() const {
  if (!is_sequence()) fail("expected a sequence ([a, b, ...] or a '- ' list), got " + kind_name());
}

void CheckedNode::expect_scalar(std::string_view expected) const {
  if (!is_scalar()) fail("expected " + std::string(expected) + ", got " + kind_name());
}

std::string CheckedNode::child_path(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

CheckedNode CheckedNode::child(const YAML::Node& key, const YAML::Node& value) const {
  // A key taken from another source brings its value; a value set anew keeps its key's line.
  std::shared_ptr<const SceneOrigin> origin = origin_of(value);
  if (origin == origin_) origin = origin_of(key);
  return CheckedNode(value, std::move(origin), origins_, child_path(key.Scalar()), line_of(key));
}

// ---------------------------------------------------------------- mappings

void CheckedNode::allow_keys(std::initializer_list<std::string_view> allowed) const {
  allow_keys(std::span<const std::string_view>(allowed.begin(), allowed.size()));
}

void CheckedNode::allow_keys(std::span<const std::string_view> allowed) const {
  expect_map();
  std::set<std::string, std::less<>> seen;
  InputErrorList errors;  // every bad key of the mapping
  for (const auto& kv : node_) {
    const YAML::Node& key = kv.first;
    const std::string& where = origin_of(key)->label;  // (a key a setting added names it)
    if (!key.IsScalar()) {
      errors.add(InputError(where, line_in_source(key), path_, "mapping keys must be plain names"));
      continue;
    }
    const std::string& name = key.Scalar();
    if (std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
      errors.add(InputError(where, line_in_source(key), child_path(name),
                            std::string(InputErrorList::kUnknownKey) + in_quotes(name) + "; " +
                                suggestion(name, allowed)));
    } else if (!seen.insert(name).second) {
      errors.add(InputError(where, line_in_source(key), child_path(name), "duplicate key"));
    }
  }
  errors.throw_if_any();
}

bool CheckedNode::has(std::string_view key) const {
  return optional(key).has_value();
}

std::optional<CheckedNode> CheckedNode::optional(std::string_view key) const {
  expect_map();
  for (const auto& kv : node_) {
    if (kv.first.IsScalar() && kv.first.Scalar() == key) return child(kv.first, kv.second);
  }
  return std::nullopt;
}

CheckedNode CheckedNode::required(std::string_view key) const {
  if (auto found = optional(key)) return *found;
  throw missing(key);
}

InputError CheckedNode::missing(std::string_view key, const std::string& message) const {
  // Located at the key that opened this mapping; the root mapping has no such line.
  const int at = path_.empty() ? 0 : line();
  return InputError(origin_->label, at, child_path(key), message);
}

std::vector<std::string> CheckedNode::keys() const {
  expect_map();
  std::vector<std::string> out;
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar())
      throw InputError(origin_->label, line_in_source(kv.first), path_,
                       "mapping keys must be plain names");
    out.push_back(kv.first.Scalar());
  }
  return out;
}

int CheckedNode::key_line(std::string_view key) const {
  if (!is_map()) return 0;
  for (const auto& kv : node_) {
    if (kv.first.IsScalar() && kv.first.Scalar() == key) return line_of(kv.first);
  }
  return 0;
}

std::optional<std::string> CheckedNode::one_of(std::initializer_list<std::string_view> group,
                                               bool required) const {
  std::optional<std::string> present;
  for (const auto& name : group) {
    if (!has(name)) continue;
    if (present) {
      throw InputError(
          origin_->label, origin_->has_lines ? key_line(name) : 0, child_path(name),
          "give either " + in_quotes(*present) + " or " + in_quotes(name) + ", not both");
    }
    present = std::string(name);
  }
  if (!present && required) {
    std::vector<std::string_view> names(group);
    fail("needs one of: " + join(names, ", "));
  }
  return present;
}

// ---------------------------------------------------------------- sequences

std::size_t CheckedNode::size() const {
  expect_sequence();
  return node_.size();
}

CheckedNode CheckedNode::element(std::size_t i) const {
  expect_sequence();
  const YAML::Node item = node_[i];
  const int at = line_of(item);
  return CheckedNode(item, origin_of(item), origins_, path_ + "[" + std::to_string(i) + "]",
                     at > 0 ? at : line());
}

std::vector<CheckedNode> CheckedNode::elements() const {
  std::vector<CheckedNode> out;
  const std::size_t n = size();
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(element(i));
  return out;
}

// ---------------------------------------------------------------- scalars

double CheckedNode::as_double(const Range& range) const {
  return as_quantity(Unit{dimension::none, {}, std::string(kUnitOne)}, range);
}

double CheckedNode::as_quantity(const Unit& unit, const Range& range) const {
  expect_scalar("a number");
  const std::string& text = node_.Scalar();
  const bool quoted = is_quoted(node_);
  std::optional<double> value = quoted ? std::nullopt : parse_double(text);
  std::string converted;  // " (60 mm/min)" when a value was written in another unit
  if (!value && !quoted && out_of_double_range(text))
    fail(text + " is out of the range of double precision");
  bool out_of_range = false;
  const auto split = value || quoted ? std::nullopt : split_number(text, out_of_range);
  if (split && looks_like_unit(split->rest)) {
    const std::string rest(split->rest);
    if (unit.dimension == dimension::none) {
      fail("expected a bare number, got " + kind_name() +
           ": this value is dimensionless (unit 1), write it without a unit");
    }
    const auto given = parse_unit(rest);
    const std::string takes = "this value's dimension is " + describe(unit.dimension) +
                              "; it takes " + units_for(unit.dimension);
    if (!given) {
      const auto names = unit_names_of(unit.dimension);
      const std::vector<std::string_view> views(names.begin(), names.end());
      const auto near = nearest_name(rest, views);
      fail("unknown unit " + in_quotes(rest) + "; " +
           (near ? "did you mean " + in_quotes(*near) + "? " : std::string()) + takes +
           " (supported: " + supported_units() + ")");
    }
    if (given->dimension != unit.dimension) {
      fail("'" + given->name + "' is a unit of " + describe(given->dimension) + ", but " + takes);
    }
    if (out_of_range) fail(text + " is out of the range of double precision");
    if (!std::isfinite(split->number)) fail("must be a finite number, got " + text);
    value = convert(split->number, given->scale, unit.scale);
    if (!std::isfinite(*value) || (*value == 0.0) != (split->number == 0.0) ||
        (split->number != 0.0 && std::abs(*value) < std::numeric_limits<double>::min())) {
      fail(text + " is out of the range of double precision once converted to " + unit.name);
    }
    if (given->name != unit.name) converted = " (" + format_number(*value) + " " + unit.name + ")";
  }
  if (!value) {
    fail("expected a number, got " + kind_name() + (quoted ? " (remove the quotes)" : ""));
  }
  if (!std::isfinite(*value)) fail("must be a finite number, got " + text);
  if (!range.contains(*value)) {
    const std::string unit_text = split || unit.dimension == dimension::none ? "" : " " + unit.name;
    fail("must be " + range.describe() + ", got " + text + unit_text + converted);
  }
  return *value;
}

int CheckedNode::as_int(const Range& range) const {
  expect_scalar("an integer");
  const auto value = is_quoted(node_) ? std::nullopt : parse_double(node_.Scalar());
  // 1e4 is accepted as an integer: only the value matters, not its spelling.
  const bool integral = value && std::isfinite(*value) && std::trunc(*value) == *value;
  if (!integral) fail("expected an integer, got " + kind_name());
  // An integer all the same, but beyond what this key is stored in: say so, with the limit.
  constexpr double kLargest = std::numeric_limits<int>::max();
  if (*value > kLargest) {
    fail(node_.Scalar() + " is above the largest value this key takes, " + format_number(kLargest));
  }
  if (*value < -kLargest) {
    fail(node_.Scalar() + " is below the smallest value this key takes, " +
         format_number(-kLargest));
  }
  if (!range.contains(*value)) fail("must be " + range.describe() + ", got " + node_.Scalar());
  return static_cast<int>(*value);
}

std::string CheckedNode::as_string() const {
  expect_scalar("a string");
  return node_.Scalar();
}

bool CheckedNode::as_bool() const {
  expect_scalar("true or false");
  const std::string& s = node_.Scalar();
  if (!is_quoted(node_)) {
    if (s == "true" || s == "True" || s == "TRUE") return true;
    if (s == "false" || s == "False" || s == "FALSE") return false;
  }
  fail("expected true or false, got " + kind_name());
}

std::string CheckedNode::as_choice(std::span<const std::string_view> choices) const {
  expect_scalar("one of: " + join(choices, ", "));
  const std::string& s = node_.Scalar();
  if (std::find(choices.begin(), choices.end(), s) != choices.end()) return s;
  fail("unknown value " + in_quotes(s) + "; " + suggestion(s, choices));
}

std::string CheckedNode::as_choice(std::initializer_list<std::string_view> choices) const {
  return as_choice(std::span<const std::string_view>(choices.begin(), choices.size()));
}

template <typename Read>
std::vector<double> CheckedNode::numbers(std::size_t size, Read read) const {
  expect_sequence();
  const std::size_t n = node_.size();
  if (size > 0 && n != size) {
    fail("expected " + std::to_string(size) + " numbers, got " + std::to_string(n));
  }
  if (n == 0) fail("expected at least one number, got an empty sequence");
  std::vector<double> out;
  out.reserve(n);
  for (const auto& e : elements()) out.push_back(read(e));
  return out;
}

std::vector<double> CheckedNode::as_doubles(const Range& range, std::size_t size) const {
  return numbers(size, [&](const CheckedNode& e) { return e.as_double(range); });
}

std::vector<double> CheckedNode::as_quantities(const Unit& unit, const Range& range,
                                               std::size_t size) const {
  return numbers(size, [&](const CheckedNode& e) { return e.as_quantity(unit, range); });
}

std::vector<std::string> CheckedNode::as_strings() const {
  std::vector<std::string> out;
  for (const auto& e : elements()) out.push_back(e.as_string());
  return out;
}

// ---------------------------------------------------------------- key shorthands

double CheckedNode::get_double(std::string_view key, const Range& range) const {
  return required(key).as_double(range);
}

double CheckedNode::get_double(std::string_view key, double fallback, const Range& range) const {
  const auto found = optional(key);
  return found ? found->as_double(range) : fallback;
}

double CheckedNode::get_quantity(std::string_view key, const Unit& unit, const Range& range) const {
  return required(key).as_quantity(unit, range);
}

double CheckedNode::get_quantity(std::string_view key, double fallback, const Unit& unit,
                                 const Range& range) const {
  const auto found = optional(key);
  return found ? found->as_quantity(unit, range) : fallback;
}

int CheckedNode::get_int(std::string_view key, const Range& range) const {
  return required(key).as_int(range);
}

int CheckedNode::get_int(std::string_view key, int fallback, const Range& range) const {
  const auto found = optional(key);
  return found ? found->as_int(range) : fallback;
}

std::string CheckedNode::get_string(std::string_view key) const {
  return required(key).as_string();
}

std::string CheckedNode::get_string(std::string_view key, std::string fallback) const {
  const auto found = optional(key);
  return found ? found->as_string() : fallback;
}

std::string CheckedNode::get_choice(std::string_view key,
                                    std::initializer_list<std::string_view> choices) const {
  return required(key).as_choice(choices);
}

std::string CheckedNode::get_choice(std::string_view key, std::string fallback,
                                    std::initializer_list<std::string_view> choices) const {
  const auto found = optional(key);
  return found ? found->as_choice(choices) : fallback;
}

}  // namespace subslip::io
