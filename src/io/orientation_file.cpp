#include "subslip/io/orientation_file.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "subslip/io/text_encoding.hpp"

namespace subslip::io {

namespace {

constexpr std::string_view kMagic = "subslip-orientations";
constexpr std::string_view kHeaderExample =
    "# subslip-orientations convention=bunge-euler-deg passive P=-1";
// Quaternions closer than this to unit norm are rounding noise and are normalised; farther ones
// are refused, since then a number is most likely mistyped.
constexpr double kNormTolerance = 1e-3;

constexpr std::array<const char*, 3> kEulerColumns{"phi1", "Phi", "phi2"};
constexpr std::array<const char*, 4> kQuaternionColumns{"w", "x", "y", "z"};
// The column labels of MTEX's export (quaternion/export.m via quaternion/Euler.m): Bunge Euler
// angles, or with the option 'quaternion' the components a b c d, which for the same Bunge angles
// are subslip's w x y z (MTEX's euler2quat gives the quaternion of euler_to_quaternion).
constexpr std::array<const char*, 3> kMtexEulerLabels{"phi1", "Phi", "phi2"};
constexpr std::array<const char*, 4> kMtexQuaternionLabels{"a", "b", "c", "d"};
// Radians written with few significant digits (MTEX writes %g: 6) may round past pi or 2 pi,
// e.g. 2 pi as 6.28319; up to half a unit in the sixth digit is rounding, not a wrong angle.
constexpr double kRadiansRounding = 1e-5;

// Joins message parts with append: GCC 12 warns falsely (-Wrestrict) on "literal" + std::string&&.
template <typename... Parts>
std::string concat(const Parts&... parts) {
  std::string text;
  (text.append(std::string_view(parts)), ...);
  return text;
}

bool is_blank(std::string_view text) {
  return text.find_first_not_of(" \t\r") == std::string_view::npos;
}

std::string_view trim_left(std::string_view text) {
  const std::size_t first = text.find_first_not_of(" \t\r");
  return first == std::string_view::npos ? std::string_view{} : text.substr(first);
}

std::vector<std::string> split_fields(std::string_view text) {
  std::vector<std::string> fields;
  std::size_t position = 0;
  while (true) {
    const std::size_t start = text.find_first_not_of(" \t\r,", position);
    if (start == std::string_view::npos) break;
    const std::size_t end = text.find_first_of(" \t\r,", start);
    fields.emplace_back(text.substr(start, end - start));
    if (end == std::string_view::npos) break;
    position = end;
  }
  return fields;
}

std::string format_number(double value, int digits) {
  char buffer[64];
  // + 0.0 turns -0 into 0 so that files never show "-0".
  std::snprintf(buffer, sizeof buffer, "%.*g", digits, value + 0.0);
  return buffer;
}

// Reads one orientation file line by line; throws InputError at the first problem.
class OrientationReader {
 public:
  // `each`: called with every orientation in file order (nothing is kept).
  OrientationReader(const std::string& file_name, const OrientationVisitor& each,
                    const OrientationFileLayout& layout)
      : file_(file_name), layout_(layout), each_(each) {
    if (layout_.kind == OrientationFileKind::euler) {
      if (!layout_.angles) {
        fail(0, "angles", "a headerless Euler list needs its unit: angles deg or rad");
      }
      convention_ = OrientationConvention::bunge_euler_deg;
    }
    unit_ = layout_.angles.value_or(
        layout_.kind == OrientationFileKind::damask ? AngleUnit::radians : AngleUnit::degrees);
  }

  // Returns the number of orientations read.
  std::size_t read(std::istream& in) {
    std::string text;
    while (std::getline(in, text)) read_line(text);
    finish();
    return count_;
  }

  // One line (without its '\n') of the file, the next after those read.
  void read_line(std::string& text) {
    ++line_;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    if (!convention_) {
      if (is_table()) {
        read_labels_line(text);
      } else {
        read_header_line(text);
      }
    } else {
      read_data_line(text);
    }
  }

  // The checks of a whole file, after its last line.
  void finish() const {
    if (!convention_) fail(0, "orientations", concat("empty file: expected ", expected_start()));
    if (count_ == 0) fail(0, "orientations", concat("no orientations ", after_what()));
  }

  std::size_t count() const { return count_; }
  int line() const { return line_; }
  // Lines read from here on are numbered from 1 (a block of the file's lines, read after its
  // start: what the lines before say is kept).
  void number_lines_from_here() { line_ = 0; }

 private:
  [[noreturn]] void fail(int line, const std::string& key, const std::string& message) const {
    throw InputError(file_, line, key, message);
  }
  [[noreturn]] void fail(const std::string& key, const std::string& message) const {
    fail(line_, key, message);
  }

  bool is_table() const {
    return layout_.kind == OrientationFileKind::mtex || layout_.kind == OrientationFileKind::damask;
  }

  std::string_view after_what() const {
    switch (layout_.kind) {
      case OrientationFileKind::subslip:
        return "after the header";
      case OrientationFileKind::euler:
        return "(every line is blank or a comment)";
      default:
        return "after the column labels";
    }
  }

  std::string expected_start() const {
    switch (layout_.kind) {
      case OrientationFileKind::mtex:
        return "a line of column labels (phi1 Phi phi2 or a b c d) and at least one orientation";
      case OrientationFileKind::damask:
        return concat("a line of column labels (with 1_", layout_.column, " 2_", layout_.column,
                      " ...) and at least one orientation");
      default:
        return concat("the header '", std::string(kHeaderExample),
                      "' and at least one orientation");
    }
  }

  static bool has_subslip_header(std::string_view text) {
    const std::string_view content = trim_left(text);
    if (!content.starts_with('#')) return false;
    return trim_left(content.substr(1)).starts_with(kMagic);
  }

  // A file in subslip's own format named with another format would be read against its header.
  void refuse_subslip_header(std::string_view text) const {
    if (has_subslip_header(text)) {
      fail("header", concat("this file has subslip's own header, yet it is read as format ",
                            to_string(layout_.kind), ": leave out the format"));
    }
  }

  void read_header_line(std::string_view text) {
    if (is_blank(text)) return;
    const std::string_view content = trim_left(text);
    std::istringstream words{std::string(content.starts_with('#') ? content.substr(1) : "")};
    std::string word;
    if (!(words >> word) || word != kMagic) {
      fail("header", concat("the first line must be the header '", kHeaderExample,
                            "' (or convention=quaternion); a file without it (a Euler list, an "
                            "MTEX or DAMASK table) needs its format named: docs/orientations.md"));
    }
    while (words >> word) read_header_word(word);
    if (!convention_) {
      fail("convention", "the header lacks convention=bunge-euler-deg or convention=quaternion");
    }
  }

  void read_header_word(const std::string& word) {
    if (word.starts_with("convention=")) {
      const std::string value = word.substr(std::string_view("convention=").size());
      if (value == "bunge-euler-deg") {
        convention_ = OrientationConvention::bunge_euler_deg;
      } else if (value == "quaternion") {
        convention_ = OrientationConvention::quaternion;
      } else {
        fail("convention",
             concat("unknown convention '", value, "'; valid: bunge-euler-deg, quaternion"));
      }
    } else if (word == "passive" || word == "P=-1") {
      // The only conventions there are; stating them is optional.
    } else if (word == "active") {
      fail("header",
           "active rotations are not supported: orientations are passive "
           "(sample -> crystal), Rowenhorst et al. 2015 with P=-1");
    } else if (word.starts_with("P=")) {
      fail("header", concat("only P=-1 is supported (Rowenhorst et al. 2015), got ", word));
    } else {
      fail("header",
           concat("unknown word '", word, "'; the header takes convention=..., passive, P=-1"));
    }
  }

  // The first line that is neither blank nor a '#' comment names the columns (DAMASK writes its
  // comments before it; MTEX writes none).
  void read_labels_line(std::string_view text) {
    refuse_subslip_header(text);
    if (is_blank(text) || trim_left(text).starts_with('#')) return;
    labels_ = split_fields(text);
    if (layout_.kind == OrientationFileKind::mtex) {
      find_mtex_columns();
    } else {
      find_damask_columns();
    }
    labels_line_ = line_;
  }

  std::string labels_list() const {
    std::string list;
    for (const std::string& label : labels_) list.append(list.empty() ? "" : " ").append(label);
    return list;
  }

  int label_index(std::string_view label) const {
    const auto found = std::find(labels_.begin(), labels_.end(), label);
    return found == labels_.end() ? -1 : int(found - labels_.begin());
  }

  // Every one of `wanted` present: their indices; otherwise empty.
  template <std::size_t N>
  std::vector<int> indices_of(const std::array<const char*, N>& wanted) const {
    std::vector<int> indices;
    for (const char* label : wanted) {
      const int index = label_index(label);
      if (index < 0) return {};
      indices.push_back(index);
    }
    return indices;
  }

  void find_mtex_columns() {
    if (auto euler = indices_of(kMtexEulerLabels); !euler.empty()) {
      columns_ = euler;
      convention_ = OrientationConvention::bunge_euler_deg;
    } else if (auto quaternion = indices_of(kMtexQuaternionLabels); !quaternion.empty()) {
      columns_ = quaternion;
      convention_ = OrientationConvention::quaternion;
    } else if (label_index("alpha") >= 0 || label_index("Psi") >= 0 || label_index("omega") >= 0) {
      fail("header", concat("the columns (", labels_list(),
                            ") are Euler angles of another convention than Bunge's; export "
                            "with the option 'Bunge' (MTEX's default) or 'quaternion'"));
    } else {
      fail("header", concat("expected MTEX's column labels phi1 Phi phi2 (Bunge Euler angles) "
                            "or a b c d (quaternion), found: ",
                            labels_list()));
    }
  }

  // DAMASK labels the components of a vector column v as 1_v 2_v ... (Table.save).
  void find_damask_columns() {
    const std::string& name = layout_.column;
    for (int component = 1;; ++component) {
      const int index = label_index(concat(std::to_string(component), "_", name));
      if (index < 0) break;
      columns_.push_back(index);
    }
    if (columns_.size() == 4) {
      convention_ = OrientationConvention::quaternion;
    } else if (columns_.size() == 3) {
      convention_ = OrientationConvention::bunge_euler_deg;
    } else if (columns_.empty()) {
      fail("header", concat("no column ", name, " (labels 1_", name, " 2_", name,
                            " ...) among the labels: ", labels_list(),
                            "; name the orientation column with orientations.column"));
    } else {
      fail("header", concat("column ", name, " has ", std::to_string(columns_.size()),
                            " components; expected 4 (quaternion w x y z) or 3 (Bunge Euler "
                            "angles phi1 Phi phi2)"));
    }
  }

  void read_data_line(std::string_view text) {
    if (layout_.kind == OrientationFileKind::euler && count_ == 0) refuse_subslip_header(text);
    const std::size_t comment = text.find('#');
    if (comment != std::string_view::npos) text = text.substr(0, comment);
    if (is_blank(text)) return;
    const std::vector<std::string> fields = split_fields(text);
    if (is_table()) {
      read_table_row(fields);
      return;
    }
    const bool has_weight = check_column_count(int(fields.size()));
    const int angle_columns = int(fields.size()) - (has_weight ? 1 : 0);

    std::vector<double> values;
    for (int i = 0; i < angle_columns; ++i)
      values.push_back(parse_number(fields[i], column_name(i)));
    const double weight = has_weight ? parse_number(fields.back(), "weight") : 1.0;
    if (!(weight > 0.0)) fail("weight", concat("weight must be positive, got ", fields.back()));

    std::vector<std::string> keys;
    for (int i = 0; i < angle_columns; ++i) keys.emplace_back(column_name(i));
    emit(values, fields, keys, weight);
  }

  // Only the orientation columns are read: the others may hold anything the tool wrote (a phase
  // name, coordinates, grain properties).
  void read_table_row(const std::vector<std::string>& fields) {
    if (fields.size() != labels_.size()) {
      fail("columns", concat("expected ", std::to_string(labels_.size()),
                             " values, one per column label on line ", std::to_string(labels_line_),
                             ", found ", std::to_string(fields.size())));
    }
    std::vector<double> values;
    std::vector<std::string> texts;
    std::vector<std::string> keys;
    for (int index : columns_) {
      values.push_back(parse_number(fields[index], labels_[index].c_str()));
      texts.push_back(fields[index]);
      keys.push_back(labels_[index]);
    }
    emit(values, texts, keys, 1.0);
  }

  void emit(const std::vector<double>& values, const std::vector<std::string>& texts,
            const std::vector<std::string>& keys, double weight) {
    crystal::Quaternion q;
    if (*convention_ == OrientationConvention::quaternion) {
      q = checked_quaternion(values);
    } else if (unit_ == AngleUnit::degrees) {
      q = quaternion_from_euler_degrees(values, texts, keys);
    } else {
      q = quaternion_from_euler_radians(values, texts, keys);
    }
    each_(crystal::Orientation::from_quaternion(q, weight));
    ++count_;
  }

  int angle_columns() const {
    return *convention_ == OrientationConvention::bunge_euler_deg ? 3 : 4;
  }

  const char* column_name(int i) const {
    return *convention_ == OrientationConvention::bunge_euler_deg ? kEulerColumns[i]
                                                                  : kQuaternionColumns[i];
  }

  // Returns whether the line has a weight column; fixes the layout on the first data line.
  bool check_column_count(int count) {
    const int base = angle_columns();
    if (count != base && count != base + 1) {
      fail("columns", concat("expected ", std::to_string(base), " numbers (",
                             base == 3 ? "phi1 Phi phi2" : "w x y z", ") or ",
                             std::to_string(base + 1), " (with a weight) for convention=",
                             to_string(*convention_), ", found ", std::to_string(count)));
    }
    if (first_data_line_ == 0) {
      first_data_line_ = line_;
      first_column_count_ = count;
    } else if (count != first_column_count_) {
      fail("columns",
           concat("found ", std::to_string(count), " numbers but line ",
                  std::to_string(first_data_line_), " has ", std::to_string(first_column_count_),
                  ": the weight column must be on every line or on none"));
    }
    return count == base + 1;
  }

  double parse_number(const std::string& token, const char* column) const {
    std::string_view digits = token;
    // One leading '+' is allowed (from_chars does not take it); "+-1" stays wrong.
    if (digits.starts_with('+') && !digits.substr(1).starts_with('-')) digits.remove_prefix(1);
    double value = 0.0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (error == std::errc::result_out_of_range) {
      fail(column, concat("'", token, "' is out of the range of double precision"));
    }
    if (error != std::errc{} || end != digits.data() + digits.size()) {
      fail(column, concat("'", token, "' is not a number"));
    }
    if (!std::isfinite(value)) {
      fail(column, concat("'", token, "' is not finite (NaN/Inf not allowed)"));
    }
    return value;
  }

  crystal::Quaternion quaternion_from_euler_degrees(const std::vector<double>& degrees,
                                                    const std::vector<std::string>& fields,
                                                    const std::vector<std::string>& keys) {
    for (int i : {0, 2}) {
      if (degrees[i] < -360.0 || degrees[i] > 360.0) {
        fail(keys[i], concat(fields[i], " deg is outside [-360, 360]"));
      }
    }
    if (degrees[1] < 0.0 || degrees[1] > 180.0) {
      fail(keys[1], concat(fields[1], " deg is outside [0, 180]"));
    }
    const Eigen::Vector3d euler(degrees[0], degrees[1], degrees[2]);
    largest_euler_deg_ = std::max(largest_euler_deg_, euler.cwiseAbs().maxCoeff());
    return crystal::euler_to_quaternion(crystal::degrees_to_radians(euler));
  }

  // The ranges of degrees, in radians; an angle beyond them was most likely written in degrees.
  crystal::Quaternion quaternion_from_euler_radians(const std::vector<double>& radians,
                                                    const std::vector<std::string>& fields,
                                                    const std::vector<std::string>& keys) const {
    constexpr double pi = std::numbers::pi;
    const auto outside = [](double value, double low, double high) {
      const double slack = kRadiansRounding * std::max(std::abs(low), std::abs(high));
      return !(value >= low - slack && value <= high + slack);
    };
    const char* hint = ": were the angles written in degrees? (then angles: deg)";
    for (int i : {0, 2}) {
      if (outside(radians[i], -2.0 * pi, 2.0 * pi)) {
        fail(keys[i], concat(fields[i], " rad is outside [-2 pi, 2 pi]", hint));
      }
    }
    if (outside(radians[1], 0.0, pi)) {
      fail(keys[1], concat(fields[1], " rad is outside [0, pi]", hint));
    }
    return crystal::euler_to_quaternion(Eigen::Vector3d(radians[0], radians[1], radians[2]));
  }

  crystal::Quaternion checked_quaternion(const std::vector<double>& v) const {
    const crystal::Quaternion q{v[0], v[1], v[2], v[3]};
    const double norm = q.norm();
    if (!(std::abs(norm - 1.0) <= kNormTolerance)) {
      fail("quaternion", concat("norm ", format_number(norm, 8),
                                " differs from 1 by more than 1e-3 (deviations up to 1e-3 are "
                                "normalised silently; larger ones are refused)"));
    }
    return q.normalized().canonical();
  }

  std::string file_;
  OrientationFileLayout layout_;
  AngleUnit unit_ = AngleUnit::degrees;
  int line_ = 0;
  std::optional<OrientationConvention> convention_;
  std::vector<std::string> labels_;  // a table's column labels
  std::vector<int> columns_;         // the indices of its orientation columns
  int labels_line_ = 0;
  int first_data_line_ = 0;
  int first_column_count_ = 0;
  const OrientationVisitor& each_;
  std::size_t count_ = 0;

 public:
  double largest_euler_deg_ = -1.0;  // the largest |angle| read; -1: not Euler angles
};

std::string format_line(const crystal::Orientation& orientation,
                        const OrientationFileFormat& format, bool with_weight) {
  const int digits = format.significant_digits;
  std::string line;
  if (format.convention == OrientationConvention::bunge_euler_deg) {
    Eigen::Vector3d degrees =
        crystal::radians_to_degrees(crystal::quaternion_to_euler(orientation.q));
    // pi * (180 / pi) may round a hair above 180, which the reader would refuse.
    degrees[1] = std::clamp(degrees[1], 0.0, 180.0);
    line = concat(format_number(degrees[0], digits), " ", format_number(degrees[1], digits), " ",
                  format_number(degrees[2], digits));
  } else {
    const crystal::Quaternion q = orientation.q.normalized().canonical();
    line = concat(format_number(q.w, digits), " ", format_number(q.x, digits), " ",
                  format_number(q.y, digits), " ", format_number(q.z, digits));
  }
  if (with_weight) line.append(" ").append(format_number(orientation.weight, digits));
  return line.append("\n");
}

}  // namespace

std::string_view to_string(OrientationConvention convention) {
  return convention == OrientationConvention::bunge_euler_deg ? "bunge-euler-deg" : "quaternion";
}

std::string_view to_string(OrientationFileKind kind) {
  switch (kind) {
    case OrientationFileKind::euler:
      return "euler";
    case OrientationFileKind::mtex:
      return "mtex";
    case OrientationFileKind::damask:
      return "damask";
    default:
      return "subslip";
  }
}

namespace {

// Whether a file's first byte may begin a byte-order mark (or is a NUL of UTF-16/32 text):
// without_byte_order_mark then reads the whole file before its first line.
bool may_need_conversion(std::istream& in) {
  const int first = in.peek();
  return first == 0xEF || first == 0xFF || first == 0xFE || first == 0x00;
}

// A byte-order mark at the start of `in` (editors on Windows write one): a UTF-8 one is
// skipped; with a UTF-16/32 one the whole file is converted (text_encoding.hpp) into `converted`,
// which is then the stream to read. Other files are read as they come, a line at a time.
std::istream& without_byte_order_mark(std::istream& in, const std::string& file_name,
                                      std::istringstream& converted) {
  if (!may_need_conversion(in)) return in;
  std::ostringstream bytes;
  bytes << in.rdbuf();
  const std::string text = bytes.str();
  const bool marked = text.starts_with("\xEF\xBB\xBF") || text.starts_with("\xFF\xFE") ||
                      text.starts_with("\xFE\xFF") ||
                      text.starts_with(std::string_view("\0\0\xFE\xFF", 4));
  converted.str(marked ? decode_text(text, file_name) : text);
  return converted;
}

}  // namespace

std::size_t read_orientations(std::istream& in, const std::string& file_name,
                              const OrientationVisitor& each, double* largest_euler_deg,
                              const OrientationFileLayout& layout) {
  OrientationReader reader(file_name, each, layout);
  std::istringstream converted;
  const std::size_t count = reader.read(without_byte_order_mark(in, file_name, converted));
  if (largest_euler_deg != nullptr) *largest_euler_deg = reader.largest_euler_deg_;
  return count;
}

std::vector<crystal::Orientation> read_orientations(std::istream& in, const std::string& file_name,
                                                    double* largest_euler_deg,
                                                    const OrientationFileLayout& layout) {
  std::vector<crystal::Orientation> orientations;
  read_orientations(
      in, file_name, [&](const crystal::Orientation& o) { orientations.push_back(o); },
      largest_euler_deg, layout);
  return orientations;
}

bool euler_angles_look_like_radians(double largest_euler_deg, std::size_t count) {
  // One orientation, or all at zero (cube), could be meant in degrees.
  return count >= 2 && largest_euler_deg > 0.0 && largest_euler_deg <= 2.0 * std::numbers::pi;
}

namespace {

// The checks read_orientation_file makes before it reads.
std::ifstream opened_orientation_file(const std::string& path) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    throw InputError(
        path, 0, "file",
        std::filesystem::exists(path, error) ? "not a regular file" : "no such orientation file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "file", "cannot open orientation file for reading");
  return in;
}

}  // namespace

std::vector<crystal::Orientation> read_orientation_file(const std::string& path,
                                                        double* largest_euler_deg,
                                                        const OrientationFileLayout& layout) {
  std::vector<crystal::Orientation> orientations;
  read_orientation_file(
      path, [&](const crystal::Orientation& o) { orientations.push_back(o); }, largest_euler_deg,
      layout);
  return orientations;
}

std::size_t read_orientation_file(const std::string& path, const OrientationVisitor& each,
                                  double* largest_euler_deg, const OrientationFileLayout& layout) {
  std::ifstream in = opened_orientation_file(path);
  return read_orientations(in, path, each, largest_euler_deg, layout);
}

std::optional<std::string> read_orientation_file_start(const std::string& path,
                                                       const OrientationVisitor& first,
                                                       const OrientationFileLayout& layout) {
  std::ifstream in = opened_orientation_file(path);
  if (may_need_conversion(in)) return std::nullopt;
  OrientationReader reader(path, first, layout);
  std::string start, text;
  while (reader.count() == 0 && std::getline(in, text)) {
    start.append(text);
    if (!in.eof()) start.push_back('\n');
    reader.read_line(text);
  }
  if (reader.count() == 0) reader.finish();  // (throws: no header, or no orientation)
  return start;
}

OrientationLines read_orientation_file_lines(const std::string& path, const std::string& start,
                                             std::uint64_t begin, std::uint64_t end,
                                             const OrientationVisitor& each,
                                             const OrientationFileLayout& layout) {
  bool replaying = true;
  const OrientationVisitor forward = [&](const crystal::Orientation& o) {
    if (!replaying) each(o);
  };
  OrientationReader reader(path, forward, layout);
  // The start again, from memory: the header, the column labels, the first data line's columns.
  std::string text;
  for (std::size_t at = 0; at < start.size();) {
    const std::size_t newline = std::min(start.find('\n', at), start.size());
    text.assign(start, at, newline - at);
    reader.read_line(text);
    at = newline + 1;
  }
  replaying = false;
  const std::size_t before = reader.count();
  reader.number_lines_from_here();
  OrientationLines read;
  if (begin < end) {
    std::ifstream in(path, std::ios::binary);
    char previous = '\n';
    in.seekg(static_cast<std::streamoff>(begin - 1));
    if (!in.get(previous)) read.complete = false;
    std::uint64_t at = begin;
    // A line that starts before `begin` is the previous range's.
    if (read.complete && previous != '\n' && std::getline(in, text)) at += text.size() + 1;
    while (read.complete && at < end && std::getline(in, text)) {
      at += text.size() + 1;
      reader.read_line(text);
    }
    if (at < end) read.complete = false;  // (the file ended early: it changed)
  }
  read.orientations = reader.count() - before;
  read.lines = static_cast<std::size_t>(reader.line());
  read.largest_euler_deg = reader.largest_euler_deg_;
  return read;
}

std::string format_orientations(const std::vector<crystal::Orientation>& orientations,
                                const OrientationFileFormat& format) {
  if (format.significant_digits < 1 || format.significant_digits > 17) {
    throw std::invalid_argument("significant_digits must be in [1, 17]");
  }
  const bool with_weight =
      format.always_write_weights ||
      std::any_of(orientations.begin(), orientations.end(),
                  [](const crystal::Orientation& o) { return o.weight != 1.0; });
  std::string text =
      concat("# ", kMagic, " convention=", to_string(format.convention), " passive P=-1\n");
  for (const std::string& comment : format.comments) text.append(concat("# ", comment, "\n"));
  const std::string columns = format.convention == OrientationConvention::bunge_euler_deg
                                  ? "phi1 Phi phi2 (deg)"
                                  : "w x y z";
  text.append(concat("# columns: ", columns, with_weight ? " weight" : "", "\n"));
  for (const crystal::Orientation& orientation : orientations) {
    text += format_line(orientation, format, with_weight);
  }
  return text;
}

std::string write_orientation_file(const std::string& path,
                                   const std::vector<crystal::Orientation>& orientations,
                                   const OrientationFileFormat& format) {
  std::string text = format_orientations(orientations, format);
  if (path.empty()) return text;
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) throw std::runtime_error(concat("cannot write orientation file '", path, "'"));
  return text;
}

std::string write_orientation_file(const std::string& path,
                                   const crystal::OrientationRequest& request,
                                   const OrientationFileFormat& format) {
  OrientationFileFormat with_provenance = format;
  with_provenance.comments.insert(with_provenance.comments.begin(),
                                  concat("generated by subslip: ", crystal::describe(request)));
  return write_orientation_file(path, crystal::generate_orientations(request), with_provenance);
}

}  // namespace subslip::io
