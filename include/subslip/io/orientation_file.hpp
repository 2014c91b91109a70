// Orientation files (see docs/orientations.md).
//
// Format: plain text, one orientation per line.
//
//   # subslip-orientations convention=bunge-euler-deg passive P=-1
//   # any further '#' line is a comment; blank lines are ignored
//   35.2644 45 0
//   90 35.2644 45
//
// - The first non-blank line must be the header: '#', the word subslip-orientations, then
//   convention=bunge-euler-deg or convention=quaternion, optionally followed by the words passive
//   and P=-1 (the only conventions supported; they are those of crystal/rotation.hpp, so active
//   and P=+1 are refused).
// - bunge-euler-deg: phi1 Phi phi2 in degrees; Phi in [0, 180], phi1 and phi2 in [-360, 360].
// - quaternion: w x y z. q and -q are the same rotation (w < 0 is flipped). A norm within 1e-3
//   of 1 is normalised silently; a larger deviation is an error (it is then a typo, not rounding).
// - An optional last column is a positive weight (default 1). Whether weights are present is
//   decided by the column count of the first data line and must be the same on every line.
// - Numbers are separated by spaces, tabs or commas; text after '#' on a data line is a comment.
//
// Every problem throws subslip::InputError "FILE:LINE: KEY: MESSAGE" with the 1-based line (0 for
// a missing or empty file), KEY naming the column or part at fault (header, convention, columns,
// phi1, Phi, phi2, w, x, y, z, quaternion, weight, orientations, file; in a table written by
// another tool the column's own label, e.g. 1_O).
//
// Files others write (OrientationFileLayout, docs/orientations.md): a headerless Bunge Euler list
// (units given by the caller), MTEX's text export (quaternion/export.m, EBSD/export.m: one line of
// column labels, then numbers) and DAMASK's ASCII table (Table.save: '#' comment lines, one line
// of column labels such as 1_O 2_O 3_O 4_O, then numbers). Same ranges, checks and messages.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <istream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "subslip/crystal/rotation.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/input_error.hpp"

namespace subslip::io {

enum class OrientationConvention { bunge_euler_deg, quaternion };

std::string_view to_string(OrientationConvention convention);  // "bunge-euler-deg", "quaternion"

// Who wrote the file, hence how it is laid out.
enum class OrientationFileKind {
  subslip,  // subslip's header line states the convention
  euler,    // no header: phi1 Phi phi2 [weight] per line, '#' comments, units from `angles`
  mtex,     // MTEX export: a line of column labels (phi1 Phi phi2 or a b c d), then numbers
  damask,   // DAMASK Table.save: '#' comments, a line of column labels, then numbers
};
enum class AngleUnit { degrees, radians };

struct OrientationFileLayout {
  OrientationFileKind kind = OrientationFileKind::subslip;
  // The unit of Euler angles in an euler, mtex or damask file. Required for euler; for mtex the
  // default is degrees and for damask radians (each tool's default when it writes them).
  std::optional<AngleUnit> angles;
  // damask: the label of the orientation column (DAMASK writes a vector column `O` as 1_O ... 4_O);
  // 4 components are a quaternion w x y z, 3 are Bunge Euler angles.
  std::string column = "O";
};

// "subslip", "euler", "mtex", "damask" (the scene's orientations.format values).
std::string_view to_string(OrientationFileKind kind);

// Reads a whole file. Weights are returned as written (not normalised to sum 1).
// `largest_euler_deg` (optional): set to the largest |Euler angle| read, -1 for quaternions.
// `largest_euler_deg` stays -1 for angles read as radians (they need no check for radians).
std::vector<crystal::Orientation> read_orientation_file(const std::string& path,
                                                        double* largest_euler_deg = nullptr,
                                                        const OrientationFileLayout& layout = {});
// The same from a stream; `file_name` is what error messages call it.
std::vector<crystal::Orientation> read_orientations(std::istream& in, const std::string& file_name,
                                                    double* largest_euler_deg = nullptr,
                                                    const OrientationFileLayout& layout = {});

// Streaming: `each` is called with every orientation in file order and nothing is kept (a file
// of more orientations than one process should hold: driver::share_root_orientations); the same
// checks and messages. Returns how many were read.
using OrientationVisitor = std::function<void(const crystal::Orientation&)>;
std::size_t read_orientation_file(const std::string& path, const OrientationVisitor& each,
                                  double* largest_euler_deg = nullptr,
                                  const OrientationFileLayout& layout = {});
std::size_t read_orientations(std::istream& in, const std::string& file_name,
                              const OrientationVisitor& each, double* largest_euler_deg = nullptr,
                              const OrientationFileLayout& layout = {});

// A file read by byte ranges, each by another process (MPI ranks, each its block of lines:
// driver/orientation_sharing.hpp), with the checks and messages of a whole read.
// Its start: every line up to and with the first orientation's (given to `first`), as bytes of
// the file. What is wrong with the file as a whole (no such file, no header, no orientation) is
// thrown here as read_orientation_file throws it. nullopt: a file whose first byte may begin a
// byte-order mark, which is converted whole before it is read (text_encoding.hpp), so that its
// bytes are not its lines.
std::optional<std::string> read_orientation_file_start(const std::string& path,
                                                       const OrientationVisitor& first,
                                                       const OrientationFileLayout& layout = {});
struct OrientationLines {
  std::size_t orientations = 0;     // given to `each`
  std::size_t lines = 0;            // read: those that start in the range
  bool complete = true;             // false: the file ended before the range (it changed)
  double largest_euler_deg = -1.0;  // of the start and these lines; -1: not Euler angles
};
// The lines of the file that start in its bytes [begin, end), read as they are after `start`
// (read_orientation_file_start's; begin >= start.size()): every orientation of them to `each`.
// A line that starts before `begin` and ends in the range is the previous range's. A problem
// throws what read_orientation_file throws for it, but with the line counted from the range's
// first line (1): the caller adds the lines before the range.
OrientationLines read_orientation_file_lines(const std::string& path, const std::string& start,
                                             std::uint64_t begin, std::uint64_t end,
                                             const OrientationVisitor& each,
                                             const OrientationFileLayout& layout = {});

// Whether `count` Euler angle sets, said to be degrees, whose largest |angle| is
// `largest_euler_deg`, were most likely written in radians (all within 2 pi, not all zero).
bool euler_angles_look_like_radians(double largest_euler_deg, std::size_t count);

struct OrientationFileFormat {
  OrientationConvention convention = OrientationConvention::bunge_euler_deg;
  int significant_digits = 6;
  // Write the weight column even when every weight is 1 (it is always written otherwise).
  bool always_write_weights = false;
  std::vector<std::string> comments;  // written as '# ' lines after the header
};

// The text of an orientation file (header, comments, one line per orientation).
std::string format_orientations(const std::vector<crystal::Orientation>& orientations,
                                const OrientationFileFormat& format = {});
// Writes format_orientations(...) to `path` and returns the text; an empty path writes nothing
// (the caller may print the text). Throws std::runtime_error when the file cannot be written.
std::string write_orientation_file(const std::string& path,
                                   const std::vector<crystal::Orientation>& orientations,
                                   const OrientationFileFormat& format = {});
// Generates the requested set (crystal::generate_orientations) and writes it as above, with a
// comment recording the request so that the file says how to regenerate it. This is what
// `subslip orientations --random N --seed S -o FILE` and `--component goss --spread 5` call.
std::string write_orientation_file(const std::string& path,
                                   const crystal::OrientationRequest& request,
                                   const OrientationFileFormat& format = {});

}  // namespace subslip::io
