#include "subslip/io/sweep.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <set>

namespace subslip::io {

namespace {

// More cases than this is almost certainly a mistake in the sweep block.
constexpr std::size_t kMaxCases = 100000;

using detail::PathStep;

bool is_name_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
}

}  // namespace

namespace detail {

std::vector<PathStep> parse_path(const std::string& path, const CheckedNode& at,
                                 std::string_view what) {
  std::vector<PathStep> steps;
  std::size_t i = 0;
  auto bad = [&](const std::string& why) {
    at.fail("malformed " + std::string(what) + " path '" + path + "' at character " +
            std::to_string(i + 1) + ": " + why +
            " (use keys joined by '.', with [i] or [*] for sequence elements)");
  };
  auto read_name = [&] {
    const std::size_t start = i;
    while (i < path.size() && is_name_char(path[i])) ++i;
    if (i == start) bad("expected a key name");
    steps.push_back({PathStep::Kind::key, path.substr(start, i - start)});
  };
  read_name();
  while (i < path.size()) {
    if (path[i] == '.') {
      ++i;
      read_name();
    } else if (path[i] == '[') {
      ++i;
      if (i < path.size() && path[i] == '*') {
        ++i;
        steps.push_back({PathStep::Kind::all, {}});
      } else {
        std::size_t index = 0;
        const auto [end, ec] = std::from_chars(path.data() + i, path.data() + path.size(), index);
        if (ec != std::errc()) bad("expected an index or '*'");
        i = static_cast<std::size_t>(end - path.data());
        steps.push_back({PathStep::Kind::index, {}, index});
      }
      if (i >= path.size() || path[i] != ']') bad("expected ']'");
      ++i;
    } else {
      bad(std::string("unexpected '") + path[i] + "'");
    }
  }
  return steps;
}

}  // namespace detail

namespace {

using detail::parse_path;

std::vector<std::string> map_keys(const YAML::Node& node) {
  std::vector<std::string> keys;
  for (const auto& kv : node) keys.push_back(kv.first.Scalar());
  return keys;
}

// The nodes `steps` names in `root`; `at` locates errors (the sweep entry).
std::vector<YAML::Node> resolve(YAML::Node root, const std::vector<PathStep>& steps,
                                const CheckedNode& at) {
  std::vector<YAML::Node> nodes{root};
  std::string where;  // the part of the path resolved so far, for messages
  for (const PathStep& step : steps) {
    std::vector<YAML::Node> next;
    for (YAML::Node& node : nodes) {
      const std::string here = where.empty() ? "the scene" : "'" + where + "'";
      if (step.kind == PathStep::Kind::key) {
        if (!node.IsMap()) at.fail("sweep path: " + here + " is not a mapping");
        const auto keys = map_keys(node);
        if (std::find(keys.begin(), keys.end(), step.key) == keys.end()) {
          const std::vector<std::string_view> names(keys.begin(), keys.end());
          at.fail("sweep path: no key '" + step.key + "' in " + here + "; " +
                  suggestion(step.key, names));
        }
        next.push_back(node[step.key]);
      } else {
        if (!node.IsSequence()) at.fail("sweep path: " + here + " is not a sequence");
        if (step.kind == PathStep::Kind::index) {
          if (step.index >= node.size()) {
            at.fail("sweep path: " + here + " has " + std::to_string(node.size()) +
                    (node.size() == 1 ? " element" : " elements") + ", so no element " +
                    std::to_string(step.index));
          }
          next.push_back(node[step.index]);
        } else {
          for (std::size_t k = 0; k < node.size(); ++k) next.push_back(node[k]);
        }
      }
    }
    if (step.kind == PathStep::Kind::key) {
      where += (where.empty() ? "" : ".") + step.key;
    } else {
      where += step.kind == PathStep::Kind::all ? "[*]" : "[" + std::to_string(step.index) + "]";
    }
    nodes = std::move(next);
  }
  return nodes;
}

std::string value_text(const YAML::Node& value) {
  if (value.IsScalar()) return value.Scalar();
  YAML::Emitter out;
  out.SetSeqFormat(YAML::Flow);
  out.SetMapFormat(YAML::Flow);
  out << value;
  return out.c_str();
}

std::optional<double> number_of(const YAML::Node& value) {
  if (!value.IsScalar() || value.Tag() == "!") return std::nullopt;
  std::string_view s = value.Scalar();
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double x = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(x)) return std::nullopt;
  return x;
}

struct SweepEntry {
  std::string path;
  std::vector<PathStep> steps;
  std::size_t count = 0;  // number of values
  std::string label;      // the path's last key, or the whole path when that is ambiguous
  CheckedNode values;     // the value list, for error locations
};

// The path from its last key on: "speed" for "loading[0].slide.speed", and "L[0][1]" for
// "loading[0].L[0][1]" (indices after the last key say which element of it is swept).
std::string last_key(const std::vector<PathStep>& steps) {
  std::string label;
  for (auto it = steps.rbegin(); it != steps.rend(); ++it) {
    if (it->kind == PathStep::Kind::key) return it->key + label;
    // Built with append: GCC 12 gives a false -Wrestrict warning on "literal" + std::string&&.
    std::string step("[");
    step.append(it->kind == PathStep::Kind::all ? "*" : std::to_string(it->index)).append("]");
    label.insert(0, step);
  }
  return label;
}

std::vector<SweepEntry> read_entries(const CheckedNode& root, const CheckedNode& sweep,
                                     std::span<const std::string_view> sweepable) {
  std::vector<SweepEntry> entries;
  for (const std::string& path : sweep.keys()) {
    const CheckedNode values = sweep.required(path).renamed("sweep[\"" + path + "\"]");
    if (values.size() == 0) values.fail("a sweep needs at least one value");
    auto steps = parse_path(path, values, "sweep");
    const std::string& first = steps.front().key;
    if (std::find(sweepable.begin(), sweepable.end(), first) == sweepable.end()) {
      values.fail("'" + first + "' cannot be swept; sweepable: " + [&] {
        std::string list;
        for (auto s : sweepable) list += (list.empty() ? "" : ", ") + std::string(s);
        return list;
      }());
    }
    resolve(root.yaml(), steps, values);  // the path must exist in the scene as written
    entries.push_back({path, std::move(steps), values.size(), {}, values});
  }
  for (auto& e : entries) {
    e.label = last_key(e.steps);
    const auto same = std::count_if(entries.begin(), entries.end(), [&](const SweepEntry& o) {
      return last_key(o.steps) == e.label;
    });
    if (same > 1) e.label = e.path;
  }
  return entries;
}

SweepCase make_case(const YamlDocument& scene, const std::vector<SweepEntry>& entries,
                    const std::vector<std::size_t>& choice) {
  SweepCase out{{}, {}, scene.copy()};
  // A fresh parse per case keeps each case's tree (and its line numbers) separate.
  const YAML::Node root = out.document.root().yaml();
  const YAML::Node sweep = root["sweep"];
  for (std::size_t k = 0; k < entries.size(); ++k) {
    const SweepEntry& e = entries[k];
    YAML::Node value = sweep[e.path][choice[k]];
    out.document.note_origin(value, e.values.origin());  // (a sweep block of a base scene)
    for (YAML::Node target : resolve(root, e.steps, e.values)) {
      // Node assignment makes the target share the sweep value's node, line number included.
      target = value;
    }
    const std::string text = value_text(value);
    out.overrides.push_back({e.path, text, number_of(value)});
    out.name += (out.name.empty() ? "" : ",") + e.label + "=" + text;
  }
  return out;
}

}  // namespace

namespace detail {

namespace {

// " (in sweep case 'a')", " (in sweep cases 'a', 'b', 'c' and 4 more)".
std::string case_tag(const std::vector<std::string>& names) {
  constexpr std::size_t kListed = 3;
  std::string tag = names.size() == 1 ? " (in sweep case " : " (in sweep cases ";
  for (std::size_t k = 0; k < names.size() && k < kListed; ++k)
    tag.append(k > 0 ? ", '" : "'").append(names[k]).append("'");
  if (names.size() > kListed)
    tag.append(" and " + std::to_string(names.size() - kListed) + " more");
  return tag + ")";
}

}  // namespace

void throw_case_errors(const std::vector<SweepCase>& cases,
                       const std::vector<std::vector<InputError>>& errors, bool stopped) {
  struct Seen {
    InputError error;
    std::vector<std::string> cases;  // the names of the cases that have it
  };
  std::vector<Seen> seen;
  for (std::size_t k = 0; k < cases.size(); ++k) {
    for (const InputError& e : errors[k]) {
      auto it = std::find_if(seen.begin(), seen.end(),
                             [&](const Seen& s) { return InputErrorList::same(s.error, e); });
      if (it == seen.end()) it = seen.insert(seen.end(), {e, {}});
      it->cases.push_back(cases[k].name);
    }
  }
  std::vector<InputError> out;
  for (const Seen& s : seen) {
    const InputError& e = s.error;
    if (s.cases.size() == cases.size()) {
      out.push_back(e);
    } else {
      out.emplace_back(e.file, e.line, e.key, e.message + case_tag(s.cases));
    }
  }
  InputErrorList list;
  for (const InputError& e : out) list.add(e);  // (throws at the limit)
  if (stopped) throw InputErrors(list.errors(), true);
  list.throw_if_any();
  throw InputError(cases.front().document.file(), 0, "", "internal error: no case failed");
}

}  // namespace detail

std::string case_group_name(std::string name) {
  std::replace(name.begin(), name.end(), '/', '_');
  return name;
}

std::vector<SweepCase> expand_sweep(const YamlDocument& scene,
                                    std::span<const std::string_view> sweepable) {
  const CheckedNode root = scene.root();
  if (!root.is_map() || !root.has("sweep")) return {SweepCase{"base", {}, scene}};
  const CheckedNode sweep = root.required("sweep");
  sweep.expect_map();
  const auto entries = read_entries(root, sweep, sweepable);
  if (entries.empty()) return {SweepCase{"base", {}, scene}};

  std::size_t total = 1;
  for (const auto& e : entries) {
    total *= e.count;
    if (total > kMaxCases) sweep.fail("more than " + std::to_string(kMaxCases) + " cases");
  }
  std::vector<SweepCase> cases;
  cases.reserve(total);
  std::set<std::string> groups;
  std::vector<std::size_t> choice(entries.size(), 0);
  for (std::size_t c = 0; c < total; ++c) {
    // Mixed-radix digits of c, the last entry varying fastest.
    std::size_t rest = c;
    for (std::size_t k = entries.size(); k-- > 0;) {
      choice[k] = rest % entries[k].count;
      rest /= entries[k].count;
    }
    cases.push_back(make_case(scene, entries, choice));
    const std::string& name = cases.back().name;
    if (!groups.insert(case_group_name(name)).second) {
      const bool same = std::any_of(cases.begin(), cases.end() - 1,
                                    [&](const SweepCase& c) { return c.name == name; });
      sweep.fail(same ? "two cases would both be named '" + name + "' (repeated value?)"
                      : "two cases would both be stored as group '" + case_group_name(name) +
                            "' (their names differ only in '/' and '_')");
    }
  }
  return cases;
}

}  // namespace subslip::io
