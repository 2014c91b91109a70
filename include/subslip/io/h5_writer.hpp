// A small HDF5 layer on the C API, shared by every scene kind (and by readers such as tests).
//
// What it offers: RAII handles, files that refuse to overwrite, groups, scalar / array / string
// attributes, a text dataset, and extendible time series ([n] or [n, k]) that are chunked,
// gzip-compressed with shuffle and carry `unit` and `description` attributes. A series grows by
// one row per output step; File::flush_if_due() then flushes the file so that a killed run
// leaves a readable file holding everything up to the last flush.
//
// The header does not include hdf5.h: identifiers are carried as std::int64_t (hid_t in
// HDF5 >= 1.10), so users of this layer need neither HDF5's include path nor its macros.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace subslip::io::h5 {

// A failed HDF5 call (message: what was attempted, and HDF5's innermost reason).
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// An output path that cannot be used (exists, not writable, ...); message starts with the path.
struct OutputPathError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Call BEFORE any computation: refuses an existing `path` unless `overwrite`, creates missing
// parent directories, and proves the directory writable by creating and removing a probe file
// (access() says yes to root on read-only mounts; a real create does not lie).
void check_output_path(const std::filesystem::path& path, bool overwrite);

// The current time as ISO-8601 UTC, "2024-05-01T12:34:56Z".
std::string iso8601_utc_now();

using Id = std::int64_t;

// Owns one HDF5 identifier and closes it with the matching H5?close.
class Handle {
 public:
  using Closer = int (*)(Id);
  Handle() = default;
  Handle(Id id, Closer close) : id_(id), close_(close) {}
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, -1)), close_(o.close_) {}
  Handle& operator=(Handle&& o) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  Id get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  void reset();

 private:
  Id id_ = -1;
  Closer close_ = nullptr;
};

enum class Type { float64, int32 };

// Anything that carries attributes: a group or a dataset.
class Object {
 public:
  Id id() const { return handle_.get(); }

  // Writing an attribute that exists replaces it.
  void set_attribute(std::string_view name, double value) const;
  void set_attribute(std::string_view name, long long value) const;  // stored as int64
  void set_attribute(std::string_view name, int value) const {
    set_attribute(name, static_cast<long long>(value));
  }
  void set_attribute(std::string_view name, long value) const {
    set_attribute(name, static_cast<long long>(value));
  }
  void set_attribute(std::string_view name, std::string_view value) const;  // UTF-8 string
  void set_attribute(std::string_view name, const char* value) const {
    set_attribute(name, std::string_view(value));
  }
  void set_attribute(std::string_view name, std::span<const double> values) const;  // 1-D array
  void set_attribute(std::string_view name, const std::vector<std::string>& values) const;

  bool has_attribute(std::string_view name) const;
  std::vector<std::string> attribute_names() const;      // in creation order
  double attribute_double(std::string_view name) const;  // any numeric attribute, converted
  long long attribute_int(std::string_view name) const;
  std::string attribute_string(std::string_view name) const;  // variable or fixed length
  std::vector<double> attribute_doubles(std::string_view name) const;
  std::vector<std::string> attribute_strings(std::string_view name) const;

 protected:
  Object() = default;
  explicit Object(Handle h) : handle_(std::move(h)) {}
  Handle handle_;
};

class Dataset : public Object {
 public:
  explicit Dataset(Handle h) : Object(std::move(h)) {}
  std::vector<std::size_t> shape() const;
  std::vector<double> read_doubles() const;  // row-major, integers converted
  std::vector<long long> read_ints() const;
  std::string read_string() const;               // a scalar string dataset
  std::vector<std::size_t> chunk_shape() const;  // empty when not chunked
  std::vector<std::string> filters() const;      // e.g. {"shuffle", "deflate"}
};

// An extendible dataset, [n] (columns == 0), [n, columns] or [n, d1, d2, ...] (a row shape), that
// grows one row at a time; a row is row-major, of the row shape's size.
// Rows are gathered in a preallocated block and written by commit() (or when the block is
// full): one H5Dset_extent + H5Dwrite per block instead of per row, which is what HDF5 makes
// cheap. A writer commits its series before each File::flush(), so a flushed file holds every
// row appended so far.
class Series {
 public:
  Series(Dataset dataset, std::size_t columns, Type type, std::size_t block_rows);
  // A series whose rows have `row_shape` (empty: scalar rows); float64 only when rank > 2.
  Series(Dataset dataset, std::vector<std::size_t> row_shape, Type type, std::size_t block_rows);
  Series(Series&&) noexcept = default;
  Series& operator=(Series&&) = delete;  // would drop the target's uncommitted rows
  ~Series();  // commits what is left (errors are swallowed: commit() explicitly to see them)

  // Appends one row: `row.size()` must be the row width (columns, or the product of the row
  // shape; 1 for a 1-D series). No allocation.
  void append(std::span<const double> row);
  void append(double value) { append(std::span<const double>(&value, 1)); }
  void append_int(int value);  // an int32 series
  // Writes the gathered rows to the file.
  void commit();
  std::size_t rows() const { return committed_ + pending_; }
  const Dataset& dataset() const { return dataset_; }

 private:
  Dataset dataset_;
  std::vector<std::size_t> row_shape_;  // {} for [n], {k} for [n, k], {d1, d2} for [n, d1, d2]
  std::size_t width_;                   // elements per row
  Type type_;
  std::size_t block_rows_;
  std::size_t committed_ = 0;
  std::size_t pending_ = 0;
  std::vector<double> block_;   // float64: block_rows x width
  std::vector<int> int_block_;  // int32: block_rows
};

struct SeriesSpec {
  std::string name;
  std::size_t columns = 0;  // 0: 1-D [n]; k: 2-D [n, k]
  Type type = Type::float64;
  std::string unit;         // attribute `unit` ("1" for dimensionless)
  std::string description;  // attribute `description`
  std::size_t chunk_rows = 1024;
  std::size_t block_rows = 256;  // rows gathered in memory between writes
  // When non-empty, replaces `columns`: the dataset is [n, row_shape...] (e.g. [n, grains, k]
  // for per-grain fields), chunked as [chunk_rows, row_shape...].
  std::vector<std::size_t> row_shape = {};
};

class Group : public Object {
 public:
  explicit Group(Handle h) : Object(std::move(h)) {}
  Group create_group(std::string_view name) const;
  Group open_group(std::string_view name) const;
  Dataset open_dataset(std::string_view name) const;
  bool has(std::string_view name) const;     // a direct member of this name exists
  std::vector<std::string> members() const;  // names of direct members
  // A scalar UTF-8 string dataset (with a `description` attribute).
  Dataset write_text(std::string_view name, std::string_view text,
                     std::string_view description) const;
  Series create_series(const SeriesSpec& spec) const;
  // A fixed float64 array of `shape` (row-major `values`, size = product of shape) with `unit`
  // and `description` attributes; for data that do not change during a run.
  Dataset write_array(std::string_view name, std::span<const std::size_t> shape,
                      std::span<const double> values, std::string_view unit,
                      std::string_view description) const;
};

class File {
 public:
  // Creates `path`; fails if it exists unless `overwrite` (then truncates).
  static File create(const std::filesystem::path& path, bool overwrite);
  static File open_read(const std::filesystem::path& path);

  Group root() const;
  const std::filesystem::path& path() const { return path_; }
  // H5Fflush: everything written so far reaches the file, which is then readable even if the
  // process dies before close.
  void flush();
  // Whether `interval` has passed since the last flush (always true for 0). Why not flush at
  // every output step: each flush recompresses every partly filled gzip chunk, ~0.1 ms per
  // dataset; once per step that dominates a run (seconds per case against milliseconds).
  void set_flush_interval(std::chrono::duration<double> interval) { flush_interval_ = interval; }
  bool flush_due() const;
  void close();

 private:
  File(Handle h, std::filesystem::path path);
  Handle handle_;
  std::filesystem::path path_;
  std::chrono::duration<double> flush_interval_{0.0};
  std::chrono::steady_clock::time_point last_flush_;
};

// The part of a result file every scene kind shares.
struct ResultHeader {
  std::string scene_kind;  // "contact", "crystal", ...
  std::string scene_file;  // as given on the command line
  std::string scene_text;  // the YAML text, verbatim
  std::string title;
  std::vector<std::pair<std::string, std::string>> units;  // ("stress", "MPa"), ...
};

// Root attributes format = "subslip", format_version = 1, program_version, scene_kind,
// scene_file, title, created (ISO-8601 UTC), completed = 0; dataset /scene; group /units with
// one string attribute per unit. Flushes.
void write_result_header(File& file, const ResultHeader& header);
// Sets completed = 1 and flushes.
void mark_completed(File& file);

inline constexpr int kFormatVersion = 1;

}  // namespace subslip::io::h5
