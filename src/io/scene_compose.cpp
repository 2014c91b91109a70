#include "subslip/io/scene_compose.hpp"

#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string_view>
#include <utility>

#include "subslip/io/sweep.hpp"

namespace subslip::io {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kBaseKey = "base";
// More bases than this in one chain is a mistake (a loop is caught on its own).
constexpr std::size_t kMaxBases = 16;

// The file the `base:` key of `scene` names, resolved against the directory of the file that
// names it, with the key (for errors); nullopt when the scene names none.
std::optional<std::pair<std::string, CheckedNode>> base_of(const YamlDocument& scene) {
  const CheckedNode root = scene.root();
  if (!root.is_map()) return std::nullopt;
  const auto key = root.optional(kBaseKey);
  if (!key) return std::nullopt;
  const fs::path name(key->as_string());
  const fs::path file = name.is_absolute() ? name : root.directory() / name;
  return std::pair{file.string(), *key};
}

// The identity of `file` on the disk, to find a base named twice (by other spellings too).
fs::path identity(const std::string& file) {
  std::error_code ec;
  const fs::path canonical = fs::weakly_canonical(file, ec);
  return ec ? fs::path(file).lexically_normal() : canonical;
}

YamlDocument read_base(const std::string& file, const CheckedNode& key) {
  try {
    return YamlDocument::from_file(file);
  } catch (const InputError& e) {
    if (e.line > 0) throw;  // (inside the base: its own file and line)
    key.fail("cannot read the base scene " + file + ": " + e.message);
  }
}

// Keys of `bottom` (a mapping written in `origin`) that `top` lacks are added to `top`, noted
// as written there; a mapping in both is merged the same way. `top_level`: the `base` key of
// a base is its own business, not the scene's.
void merge_under(YAML::Node top, const YAML::Node& bottom,
                 const std::shared_ptr<const SceneOrigin>& origin, const YamlDocument& doc,
                 bool top_level) {
  for (const auto& kv : bottom) {
    if (!kv.first.IsScalar()) continue;  // (refused where the merged mapping is read)
    const std::string& key = kv.first.Scalar();
    if (top_level && key == kBaseKey) continue;
    bool present = false;
    for (const auto& own : top)
      present = present || (own.first.IsScalar() && own.first.Scalar() == key);
    if (!present) {
      // The base's own key and value nodes: their lines stay those of the base file.
      top.force_insert(kv.first, kv.second);
      doc.note_origin(kv.first, origin);
      doc.note_origin(kv.second, origin);
      continue;
    }
    YAML::Node mine = top[key];
    if (mine.IsMap() && kv.second.IsMap()) merge_under(mine, kv.second, origin, doc, false);
  }
}

// The node of `map` under `key`, created (as an empty mapping, or as `value` when given) and
// noted as the setting's when the map has none.
YAML::Node child_or_new(YAML::Node map, const std::string& key, const YamlDocument& doc,
                        const std::shared_ptr<const SceneOrigin>& origin) {
  for (const auto& kv : map) {
    if (kv.first.IsScalar() && kv.first.Scalar() == key) return kv.second;
  }
  map[key] = YAML::Node(YAML::NodeType::Map);
  for (const auto& kv : map) {
    if (kv.first.IsScalar() && kv.first.Scalar() == key) {
      doc.note_origin(kv.first, origin);  // an unknown key is refused naming the setting
      doc.note_origin(kv.second, origin);
      return kv.second;
    }
  }
  return map[key];  // (not reached: the key was just added)
}

// The nodes `steps` name below `node`, keys a mapping lacks added (the last one's value is set
// next); `at` locates errors. `done` is the part of the path resolved so far.
std::vector<YAML::Node> setting_targets(YAML::Node node, const std::vector<detail::PathStep>& steps,
                                        const YamlDocument& doc, const CheckedNode& at) {
  using Kind = detail::PathStep::Kind;
  std::vector<YAML::Node> nodes{std::move(node)};
  std::string done;
  for (const detail::PathStep& step : steps) {
    const std::string here = done.empty() ? "the scene" : "'" + done + "'";
    std::vector<YAML::Node> next;
    for (YAML::Node& n : nodes) {
      if (step.kind == Kind::key) {
        if (!n.IsMap()) at.fail(here + " is not a mapping, so it has no key '" + step.key + "'");
        next.push_back(child_or_new(n, step.key, doc, at.origin()));
        continue;
      }
      if (!n.IsSequence()) at.fail(here + " is not a sequence");
      if (step.kind == Kind::index && step.index >= n.size()) {
        at.fail(here + " has " + std::to_string(n.size()) +
                (n.size() == 1 ? " element" : " elements") + ", so no element " +
                std::to_string(step.index));
      }
      for (std::size_t k = 0; k < n.size(); ++k) {
        if (step.kind == Kind::all || k == step.index) next.push_back(n[k]);
      }
    }
    done += step.kind == Kind::key   ? (done.empty() ? "" : ".") + step.key
            : step.kind == Kind::all ? "[*]"
                                     : "[" + std::to_string(step.index) + "]";
    nodes = std::move(next);
  }
  return nodes;
}

// Applies one `PATH=VALUE` setting: the value (YAML, as it would be written in the scene)
// replaces the one at PATH or is added there.
void apply_setting(const std::string& setting, const YamlDocument& doc) {
  const auto origin =
      std::make_shared<const SceneOrigin>(SceneOrigin{"--set " + setting, {}, false});
  const std::size_t equals = setting.find('=');
  if (equals == std::string::npos) {
    throw InputError(origin->label, 0, "",
                     "expected PATH=VALUE: a key path as in a sweep (loading[0].increments), "
                     "'=' and a value as the scene would write it");
  }
  const std::string path = setting.substr(0, equals);
  YAML::Node value;
  try {
    value = YAML::Load(setting.substr(equals + 1));
  } catch (const YAML::Exception& e) {
    throw InputError(origin->label, 0, path, "the value is no YAML value: " + e.msg);
  }
  const CheckedNode at(value, origin, nullptr, path, 0);
  const auto steps = detail::parse_path(path, at, "--set");
  for (YAML::Node target : setting_targets(doc.root().yaml(), steps, doc, at)) {
    // Node assignment makes the target share the value's node, so that it names the setting.
    target = value;
  }
  doc.note_origin(value, origin);
}

}  // namespace

YamlDocument YamlDocument::compose(const SceneSources& sources) {
  YamlDocument doc = from_string(sources.scene.text, sources.scene.file);
  auto all = std::make_shared<SceneSources>(sources);
  all->scene = doc.sources_->scene;  // (decoded)
  doc.sources_ = all;
  if (!doc.root_.IsMap()) return doc;  // (the parsers say what a scene must be)
  for (const SceneText& base : sources.bases) {
    const YamlDocument under = from_string(base.text, base.file);
    if (under.root_.IsMap()) merge_under(doc.root_, under.root_, under.origin_, doc, true);
  }
  // (a scene read without its bases keeps the key, which its parser then refuses)
  if (!sources.bases.empty()) doc.root_.remove(std::string(kBaseKey));
  for (const std::string& setting : sources.settings) apply_setting(setting, doc);
  return doc;
}

SceneSources read_scene_sources(const YamlDocument& scene, std::vector<std::string> settings) {
  SceneSources sources{{scene.file(), scene.text()}, {}, std::move(settings)};
  std::set<fs::path> seen{identity(scene.file())};
  std::optional<YamlDocument> current;
  for (auto base = base_of(scene); base; base = base_of(*current)) {
    const auto& [file, key] = *base;
    if (!seen.insert(identity(file)).second)
      key.fail(file + " is already a base of this scene (the bases name each other in a loop)");
    if (sources.bases.size() == kMaxBases)
      key.fail("more than " + std::to_string(kMaxBases) + " bases, one over another");
    current.emplace(read_base(file, key));
    sources.bases.push_back({current->file(), current->text()});
  }
  return sources;
}

YamlDocument compose_scene(const YamlDocument& scene, std::vector<std::string> settings) {
  return YamlDocument::compose(read_scene_sources(scene, std::move(settings)));
}

model::SceneMakeup makeup_of(const YamlDocument& document) {
  model::SceneMakeup makeup;
  for (const SceneText& base : document.sources().bases)
    makeup.bases.emplace_back(base.file, base.text);
  makeup.settings = document.sources().settings;
  return makeup;
}

}  // namespace subslip::io
