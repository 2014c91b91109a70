// The run model of a crystal scene (`scene: crystal`): its cases, each a crystal phase, a set of
// grain orientations (or this rank's block of them), a loading history under mixed control,
// the integrator's options and the output it asks for. io/crystal_scene.hpp makes one from a
// scene file; driver/crystal_run.hpp runs it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/grain_fields_table.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/model/case_common.hpp"
#include "subslip/model/series_compression.hpp"
#include "subslip/model/units.hpp"

namespace subslip::model {

// Aggregate (macroscopic) time series, in output order.
enum class MacroField { time, L, F, strain, stress, segment };
inline constexpr std::array<MacroField, 6> kAllMacroFields = {
    MacroField::time,   MacroField::L,      MacroField::F,
    MacroField::strain, MacroField::stress, MacroField::segment};
std::string_view to_string(MacroField f);

// Per-grain time series, in output order: names, widths, units and descriptions are those of
// crystal/grain_fields_table.hpp.
using crystal::GrainField;
using crystal::kAllGrainFields;
using crystal::to_string;

struct CrystalOutputSelection {
  std::vector<MacroField> macro;   // in kAllMacroFields order; always has time
  std::vector<GrainField> grains;  // in kAllGrainFields order; empty: no /grains group
  int checkpoint_every = -1;       // output.checkpoint_every: increments, 0 none, -1 not given
  // output.grains_at: for every output row (the initial state first), whether it has per-grain
  // rows; empty: every row has them.
  std::vector<bool> grain_rows;
};

// How the orientations were given, for the case attributes.
struct OrientationSource {
  std::string kind;                 // file | euler_deg | random | component
  std::string description;          // the file path as resolved, or the request
  double largest_euler_deg = -1.0;  // the largest |Euler angle| given; -1: not Euler angles
};

// A digest of a set of orientations, in order (quaternion and weight of each, FNV-1a 64 bit):
// "fnv1a64:<16 hex digits>". A restart checks that its orientations are those of the run.
class OrientationDigest {
 public:
  OrientationDigest() = default;
  // Continues the digest of the orientations before these (its state: MPI ranks reading a set
  // by blocks digest them in rank order).
  explicit OrientationDigest(std::uint64_t state) : hash_(state) {}
  void add(const crystal::Orientation& o);
  std::string text() const;
  std::uint64_t state() const { return hash_; }

 private:
  std::uint64_t hash_ = 14695981039346656037ull;
};
std::string orientations_digest(const std::vector<crystal::Orientation>& orientations);

using OrientationVisitor = std::function<void(const crystal::Orientation&)>;

// An orientation file a scene names. Reading it is the parser's: `read` visits every
// orientation in file order, returns how many and sets the largest |Euler angle| given (-1: not
// Euler angles); a problem is the input error naming the file, its line and column, and the
// scene key that named the file. Who reads which part is the driver's
// (driver/orientation_sharing.hpp).
// What one process read of an orientation file's lines (OrientationFile::read_lines).
struct OrientationLines {
  std::size_t orientations = 0;     // visited
  std::size_t lines = 0;            // read: those that start in the range
  bool complete = true;             // false: the file ended before the range (it changed)
  double largest_euler_deg = -1.0;  // of the file's start and these lines; -1: not Euler angles
  // The first problem in these lines (the reading stopped there): its line counted from the
  // range's first line (1; 0: none), and the key and message of the input error `read` gives.
  int problem_line = 0;
  std::string problem_key, problem_message;
};

struct OrientationFile {
  std::string path;  // as resolved against the scene file's directory
  std::function<std::size_t(const OrientationVisitor&, double& largest_euler_deg)> read;
  // The same read by byte ranges, each by another process: the file's start (every line up to
  // and with the first orientation's, which `first` is given), read once; nullopt where the file
  // must be read whole (a byte-order mark). Problems of the file as a whole throw here, as in
  // `read`.
  std::function<std::optional<std::string>(const OrientationVisitor& first)> read_start;
  // Then the lines that start in the bytes [begin, end) (begin >= start.size()), every
  // orientation to `each`, up to the first problem, which it returns.
  std::function<OrientationLines(const std::string& start, std::uint64_t begin, std::uint64_t end,
                                 const OrientationVisitor& each)>
      read_lines;
  // Throws the input error of a problem read_lines returned, at the file's line `line`.
  std::function<void(int line, const std::string& key, const std::string& message)> fail_line;
  // The input errors at the scene key: weights that sum past the largest double; a file that
  // did not give the same orientations when read again (it changed while it was read).
  std::function<void()> fail_weights;
  std::function<void()> fail_changed;
};

// Where a case's orientations come from, before they are read: a file, a generated texture
// (its request holds the count and the seed), or the Euler angles written in the scene.
struct OrientationOrigin {
  std::optional<OrientationFile> file;
  std::optional<crystal::OrientationRequest> generated;
  std::vector<crystal::Orientation> given;  // (the scene's own, already in memory)
};

// What the whole set of a case's orientations gives, where a process holds only its block of
// them (MPI ranks sharing the grains: driver/orientation_sharing.hpp).
struct OrientationBlock {
  std::size_t offset = 0;   // the grain index of the first orientation held
  std::size_t total = 0;    // every grain of the case
  double weight_sum = 0.0;  // of every grain's weight, summed in grain order
  std::string digest;       // orientations_digest of every grain
};

// One case of a crystal scene (the whole scene when it has no sweep).
struct CrystalCase {
  std::string name;                      // "base", or built from the sweep overrides
  std::vector<SweepOverride> overrides;  // this case's swept values
  crystal::PhaseDescription phase;
  std::string elasticity_type;  // cubic | hexagonal | isotropic (for the attributes)
  // Where the orientations come from; read into `orientations` by read_all_orientations (one
  // process holding them all) or by the driver (driver::read_orientations: each rank its block).
  OrientationOrigin orientation_origin;
  // Every grain's orientation, or only this process's block of them when `orientation_block`
  // is set (grain_count() is then the case's); empty until read.
  std::vector<crystal::Orientation> orientations;
  std::optional<OrientationBlock> orientation_block;
  OrientationSource orientation_source;
  std::vector<crystal::LoadSegment> segments;
  crystal::AggregateOptions options;
  CrystalOutputSelection output;
  std::vector<WrittenValue> magnitudes;  // for the plausibility warnings (scene_warnings.hpp)

  std::size_t grain_count() const {
    return orientation_block ? orientation_block->total : orientations.size();
  }
  std::string orientations_digest() const;  // of every grain of the case
};

struct CrystalScene {
  std::string file;    // as given
  std::string text;    // the YAML text, verbatim
  SceneMakeup makeup;  // its base scenes and settings, when it has any
  std::string title;   // "" when the scene has none
  Units units;  // stress and time; length is not used (slip is dimensionless): empty unless given
  SeriesCompression compression;   // of the finished file (output.compression)
  std::vector<CrystalCase> cases;  // in sweep order (first swept key slowest)
};

// Reads every orientation of `c` (or of every case of `scene`) into `orientations`, the whole
// set in this process; sets orientation_source.largest_euler_deg for a file. A problem in a file
// is its input error (OrientationFile::read).
void read_all_orientations(CrystalCase& c);
void read_all_orientations(CrystalScene& scene);

// The unit pairs of a crystal result file's /units group: ("stress", ...), ("time", ...).
std::vector<std::pair<std::string, std::string>> crystal_units(const Units& units);

// The number of states the aggregate reports for `segments` (the initial state included).
std::size_t crystal_output_count(const std::vector<crystal::LoadSegment>& segments);

}  // namespace subslip::model
