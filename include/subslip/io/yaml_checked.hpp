// A small schema-checking layer over yaml-cpp, shared by every scene kind.
//
// Why: a scene file is written by hand, and a typo must stop the run with the file, the line
// and the dotted key path of the problem ("law.overstress.eta_v", "loading[2].slide.speed")
// rather than run with a default. Every problem becomes one subslip::InputError.
//
// Usage pattern for a mapping (each mapping lists its keys once, so unknown keys are caught):
//
//   const CheckedNode law = root.required("law");
//   law.allow_keys({"friction", "subloading", "overstress"});
//   const double mu_s = law.required("friction").get_double("mu_s", Range::positive());
//
// CheckedNode is a cheap value (a yaml-cpp handle, the file name, the path, a line number).
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/io/input_error.hpp"
#include "subslip/io/units.hpp"

namespace subslip::io {

// An interval a number must lie in. Non-finite numbers are always rejected.
class Range {
 public:
  static Range any();
  static Range positive();                                // > 0
  static Range non_negative();                            // >= 0
  static Range at_least(double lo);                       // >= lo
  static Range greater_than(double lo);                   // > lo
  static Range at_most(double hi);                        // <= hi
  static Range in_open_interval(double lo, double hi);    // (lo, hi)
  static Range in_closed_interval(double lo, double hi);  // [lo, hi]

  bool contains(double x) const;
  // "> 0", ">= 1", "in (1, 2)", or "" for any().
  std::string describe() const;

 private:
  Range(double lo, bool lo_open, double hi, bool hi_open);
  double lo_, hi_;
  bool lo_open_, hi_open_;
};

// Levenshtein edit distance (insertions, deletions, substitutions).
std::size_t edit_distance(std::string_view a, std::string_view b);
// The candidate nearest to `word` when it is close enough to be a plausible typo.
std::optional<std::string_view> nearest_name(std::string_view word,
                                             std::span<const std::string_view> candidates);
// "did you mean 'eta_v'?" or "expected one of: a, b, c".
std::string suggestion(std::string_view word, std::span<const std::string_view> candidates);

// A plain YAML number ("1.5", "-2e3", "+4", ".inf", ".nan"); nullopt for anything else.
std::optional<double> parse_number(std::string_view text);

class CheckedNode;

// Where a part of a scene was written: a file (the scene, a base scene it names) or a command
// line argument (`--set PATH=VALUE`), so that an error names it.
struct SceneOrigin {
  std::string label;                // what messages name: the file, or "--set PATH=VALUE"
  std::filesystem::path directory;  // file names written there are relative to it
  bool has_lines = true;            // false for a command line argument: no line to name
};

// A scene file as read (text() of a YamlDocument: UTF-8).
struct SceneText {
  std::string file;
  std::string text;
};

// What a scene is made of (io/scene_compose.hpp): the scene file, the base scenes it names one
// after another (its base first), and the `--set PATH=VALUE` settings, in order.
struct SceneSources {
  SceneText scene;
  std::vector<SceneText> bases;
  std::vector<std::string> settings;
};

// A parsed YAML file with its name and text. Parse errors become InputError with the line. A
// composed scene (YamlDocument::compose) holds nodes of several sources; each node's errors
// name its own (CheckedNode::file()).
class YamlDocument {
 public:
  // Nodes of other sources than the scene file, each with where it was written.
  using Origins = std::vector<std::pair<YAML::Node, std::shared_ptr<const SceneOrigin>>>;

  static YamlDocument from_file(const std::filesystem::path& path);
  // `file_name` is what error messages show. The text is decoded first (text_encoding.hpp):
  // a byte-order mark is dropped, UTF-16/32 converted; text() is UTF-8.
  static YamlDocument from_string(std::string text, std::string file_name);
  // The scene `sources` make: the bases merged under the scene key by key, then the settings
  // applied (src/io/scene_compose.cpp; io/scene_compose.hpp says how).
  static YamlDocument compose(const SceneSources& sources);

  // The scene file's name and text (a composed scene's other sources: sources()).
  const std::string& file() const { return sources_->scene.file; }
  const std::string& text() const { return sources_->scene.text; }
  const SceneSources& sources() const { return *sources_; }
  CheckedNode root() const;
  // The same scene parsed anew from its sources: a tree of its own (each sweep case's).
  YamlDocument copy() const;
  // Errors at `node` and below name `origin` (a value taken from another source).
  void note_origin(const YAML::Node& node, std::shared_ptr<const SceneOrigin> origin) const;

 private:
  YamlDocument(std::shared_ptr<const SceneSources> sources, YAML::Node root);
  std::shared_ptr<const SceneSources> sources_;
  std::shared_ptr<const SceneOrigin> origin_;  // the scene file's
  std::shared_ptr<Origins> origins_;           // nodes from other sources, where each starts
  YAML::Node root_;
};

class CheckedNode {
 public:
  // `key_line` is the 1-based line of the key that introduced this node (0 for the root); it
  // locates "missing key" errors and empty values, which have no position of their own.
  // `origins`: the nodes of other sources below (YamlDocument::note_origin), or null.
  CheckedNode(YAML::Node node, std::shared_ptr<const SceneOrigin> origin,
              std::shared_ptr<const YamlDocument::Origins> origins, std::string path, int key_line);

  const std::string& path() const { return path_; }
  // The file (or command line argument) this node was written in, as messages name it.
  const std::string& file() const { return origin_->label; }
  // The directory file names written in this node are relative to.
  const std::filesystem::path& directory() const { return origin_->directory; }
  const std::shared_ptr<const SceneOrigin>& origin() const { return origin_; }
  // 1-based line of the value (or of its key when the value is empty); 0 = unknown.
  int line() const;
  const YAML::Node& yaml() const { return node_; }
  // The same node under another path (e.g. sweep keys, which contain dots themselves).
  CheckedNode renamed(std::string path) const;

  // An error located at this node.
  InputError error(const std::string& message) const;
  [[noreturn]] void fail(const std::string& message) const;

  bool is_null() const;
  bool is_scalar() const;
  bool is_sequence() const;
  bool is_map() const;
  // "a number", "a mapping", ... for messages.
  std::string kind_name() const;
  void expect_map() const;
  void expect_sequence() const;

  // ---- mappings
  // Rejects keys not in `allowed` (with the nearest valid key as a suggestion), non-scalar
  // keys and duplicated keys, all of them at once (InputErrors when several). Also requires
  // this node to be a mapping. A mapping with a bad key is read no further by the parsers: a
  // misspelt key would make its correct spelling look missing.
  void allow_keys(std::initializer_list<std::string_view> allowed) const;
  void allow_keys(std::span<const std::string_view> allowed) const;
  bool has(std::string_view key) const;
  CheckedNode required(std::string_view key) const;  // error when missing
  std::optional<CheckedNode> optional(std::string_view key) const;
  // The keys in file order.
  std::vector<std::string> keys() const;
  // Line of `key` itself (1-based), 0 if absent.
  int key_line(std::string_view key) const;
  // An error for a missing key, located at this mapping.
  InputError missing(std::string_view key,
                     const std::string& message = std::string(InputErrorList::kMissingKey)) const;
  // Of the keys in `group`, exactly one (or, when !required, at most one) may appear. Returns
  // the one present.
  std::optional<std::string> one_of(std::initializer_list<std::string_view> group,
                                    bool required) const;

  // ---- sequences
  std::size_t size() const;  // of a sequence (error otherwise)
  CheckedNode element(std::size_t i) const;
  std::vector<CheckedNode> elements() const;

  // ---- scalars (type errors and range errors name the expected type / range)
  // A dimensionless number (a unit written after it is refused).
  double as_double(const Range& range = Range::any()) const;
  // A number in `unit`: bare, it is read in `unit`; followed by a unit of the same dimension
  // ("168.4 GPa", "60 min", "1 mm/min"), it is converted into `unit`. The range applies to the
  // converted value. An unknown unit or one of another dimension is an error naming the units
  // this key takes; a dimensionless `unit` ("1") takes bare numbers only.
  double as_quantity(const Unit& unit, const Range& range = Range::any()) const;
  int as_int(const Range& range = Range::any()) const;
  std::string as_string() const;  // any non-empty scalar, quoted or not
  bool as_bool() const;           // true / false
  // A string from a fixed set, with a suggestion on a typo.
  std::string as_choice(std::span<const std::string_view> choices) const;
  std::string as_choice(std::initializer_list<std::string_view> choices) const;
  template <class Enum>
  Enum as_enum(std::initializer_list<std::pair<std::string_view, Enum>> choices) const;
  // A sequence of numbers, each in `range`; `size` = required length (0: any non-empty).
  std::vector<double> as_doubles(const Range& range = Range::any(), std::size_t size = 0) const;
  // The same with every element read by as_quantity.
  std::vector<double> as_quantities(const Unit& unit, const Range& range = Range::any(),
                                    std::size_t size = 0) const;
  std::vector<std::string> as_strings() const;

  // ---- key shorthands: required(key).as_X(...) or, with a fallback, optional.
  double get_double(std::string_view key, const Range& range = Range::any()) const;
  double get_double(std::string_view key, double fallback, const Range& range) const;
  double get_quantity(std::string_view key, const Unit& unit,
                      const Range& range = Range::any()) const;
  double get_quantity(std::string_view key, double fallback, const Unit& unit,
                      const Range& range) const;
  int get_int(std::string_view key, const Range& range = Range::any()) const;
  int get_int(std::string_view key, int fallback, const Range& range) const;
  std::string get_string(std::string_view key) const;
  std::string get_string(std::string_view key, std::string fallback) const;
  std::string get_choice(std::string_view key,
                         std::initializer_list<std::string_view> choices) const;
  std::string get_choice(std::string_view key, std::string fallback,
                         std::initializer_list<std::string_view> choices) const;

 private:
  CheckedNode child(const YAML::Node& key, const YAML::Node& value) const;
  // Where `n` (a node below this one) was written: its own origin if noted, else this node's.
  std::shared_ptr<const SceneOrigin> origin_of(const YAML::Node& n) const;
  int line_in_source(const YAML::Node& n) const;
  std::string child_path(std::string_view key) const;
  void expect_scalar(std::string_view expected) const;
  // A sequence of `size` numbers (any count >= 1 when 0), each read by `read`.
  template <typename Read>
  std::vector<double> numbers(std::size_t size, Read read) const;

  YAML::Node node_;
  std::shared_ptr<const SceneOrigin> origin_;
  std::shared_ptr<const YamlDocument::Origins> origins_;
  std::string path_;
  int key_line_;
};

template <class Enum>
Enum CheckedNode::as_enum(std::initializer_list<std::pair<std::string_view, Enum>> choices) const {
  std::vector<std::string_view> names;
  for (const auto& c : choices) names.push_back(c.first);
  const std::string chosen = as_choice(names);
  for (const auto& c : choices) {
    if (c.first == chosen) return c.second;
  }
  fail("internal error: unmatched choice");  // as_choice only returns listed names
}

}  // namespace subslip::io
