// A small HDF5 layer on the C API, shared by every scene kind (and by readers such as tests).
//
// What it offers: RAII handles, files that refuse to overwrite, groups, scalar / array / string
// attributes, a text dataset, extendible time series ([n], [n, k], [n, d1, d2]) with `unit` and
// `description` attributes, fixed arrays rewritten in place (checkpoints), and the /progress
// table of a result file.
//
// Crash safety (a run killed by SIGKILL at any moment). HDF5 1.10 writes its metadata (links,
// object headers, chunk indices, free space, the end-of-file address) in no particular order
// and in several writes, so a kill that lands in a flush after a structural change (a group,
// dataset or attribute created or deleted, an extent changed) can leave a file that does not
// open (measured: 2-4 % of random kills of a two-case crystal run, when case groups were
// created and attributes replaced while the run went). Hence a result file is laid out whole
// before any computation: every case group with its attributes (the summary ones as NaN / 0
// placeholders, `failed` as a reserved fixed-length string), every series with its rows
// reserved (allocated at once, filled with NaN); then one flush and `layout_complete = 1`.
// While the run goes, only values are written, in place: rows of a series (no compression, no
// chunk cache, no sieve buffer, so each row is in the file when commit() returns), the
// /progress table, and attributes of unchanged type and shape. The one structural change left
// is a series that outgrows its reservation (an adaptive run taking more output steps than its
// scene plans): its extent is doubled and flushed, and a kill inside that flush can damage
// that series of the running case. When the run has ended, write_exact_copy makes the finished
// file without the reservation, in a new file that replaces this one by a rename
// (io/result_file.hpp): the working file itself is never trimmed.
//
// Write failures (a full disk, a file-size limit). Every HDF5 call is checked and becomes an
// Error naming the object and the system's reason (errno, which HDF5's file driver records).
// After the layout only a growth needs new space; it claims that space from the file system
// first (posix_fallocate), so that a full disk stops it before HDF5 changes anything: the file
// stays consistent, its valid rows readable, and a message can still be written in place.
//
// Collective writes (MPI ranks sharing one file, parallel HDF5: File::open_write with an
// MpiAccess). The file is laid out by one process first (the layout above, sec2 driver); the
// ranks then open it together through MPI-IO and write values only: every rank makes the same
// calls in the same order with the same values (attributes, /progress, macro rows: HDF5's
// metadata is replicated, so they must agree), and the data themselves are stored by rank 0,
// except where a rank names its own part: the grains of a per-grain series
// (Series::select_grains) and rows of an array (Dataset::write_rows). The rows of a
// per-grain series are thus written by every rank at once, each its block of grains
// (a collective hyperslab write). A growth claims its space with MPI_File_preallocate.
//
// The header does not include hdf5.h: identifiers are carried as std::int64_t (hid_t in
// HDF5 >= 1.10), so users of this layer need neither HDF5's include path nor its macros.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/driver/sink_error.hpp"

namespace subslip::io::h5 {

// A failed HDF5 call. what(): "HDF5: ACTION: REASON"; `action` says what was attempted and on
// which object ("write rows 0..255 of dataset /cases/base/time"), `reason` is the operating
// system's (errno: "No space left on device") when HDF5 recorded one, else HDF5's own words.
// A sink's failed write (driver::SinkWriteError), which the drivers pass on between ranks.
struct Error : driver::SinkWriteError {
  explicit Error(const std::string& message) : driver::SinkWriteError(message, message, "") {}
  Error(const std::string& what_failed, const std::string& why)
      : driver::SinkWriteError("HDF5: " + what_failed + (why.empty() ? "" : ": " + why),
                               what_failed, why) {}
};

// HDF5's own error stack is not printed (errors become Error); with `on`, every failed call
// prints it to stderr before it is turned into an Error (subslip run --verbose).
void print_error_stacks(bool on);

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
  void reset();  // closes; a failure to close is ignored (File::close checks its own)
  Id release() { return std::exchange(id_, -1); }  // the caller closes

 private:
  Id id_ = -1;
  Closer close_ = nullptr;
};

enum class Type { float64, int32, int64 };  // int64: fixed arrays only

// What a stored attribute or dataset holds, for readers that do not know the layout in advance.
enum class ValueClass { floating, integer, string, other };

// Anything that carries attributes: a group or a dataset.
class Object {
 public:
  Id id() const { return handle_.get(); }

  // Writing an attribute that exists with the same type and shape rewrites its value in place
  // (no metadata change); otherwise the attribute is replaced (layout time only).
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
  // An array of `shape` (row-major `values`, size = product of shape): [3, 3] for a tensor.
  void set_attribute(std::string_view name, std::span<const double> values,
                     std::span<const std::size_t> shape) const;
  void set_attribute(std::string_view name, const std::vector<std::string>& values) const;

  // A fixed-length UTF-8 string attribute of `bytes` bytes, empty (NUL-padded): a message
  // written later, while the run goes, by write_reserved_string (in place; longer text is cut
  // at a character boundary).
  void reserve_string_attribute(std::string_view name, std::size_t bytes) const;
  void write_reserved_string(std::string_view name, std::string_view value) const;

  bool has_attribute(std::string_view name) const;
  std::vector<std::string> attribute_names() const;      // in creation order
  double attribute_double(std::string_view name) const;  // any numeric attribute, converted
  long long attribute_int(std::string_view name) const;
  std::string attribute_string(std::string_view name) const;  // variable or fixed length
  std::vector<double> attribute_doubles(std::string_view name) const;
  std::vector<std::string> attribute_strings(std::string_view name) const;
  ValueClass attribute_class(std::string_view name) const;
  std::size_t attribute_size(std::string_view name) const;  // elements (1 for a scalar)

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
  ValueClass value_class() const;
  std::vector<std::string> filters() const;  // e.g. {"shuffle", "deflate"}
  // Overwrite the whole dataset in place (size = number of elements); see Group::create_fixed.
  void write(std::span<const double> values) const;
  void write(std::span<const long long> values) const;
  // Overwrite element `index` of a 1-D integer dataset in place.
  void write_element(std::size_t index, long long value) const;
  // Overwrite the first values.size() elements of a 1-D float64 dataset in place.
  void write_prefix(std::span<const double> values) const;
  // This process's part of a float64 dataset: the rows [first, first + n) of its first axis,
  // n = values.size() / (the values of a row) (collective: every rank of a parallel file calls
  // it, each with its own part, maybe none). A 1-D dataset's rows are its elements.
  void write_rows(std::size_t first, std::span<const double> values) const;
  std::vector<double> read_rows(std::size_t first, std::size_t count) const;
};

// An extendible dataset, [n] (columns == 0), [n, columns] or [n, d1, d2, ...] (a row shape), that
// grows one row at a time; a row is row-major, of the row shape's size.
// Rows are gathered in a block in memory and written in place by commit() (or when the block is
// full) into rows reserved ahead; a series that outgrows its reservation doubles it (and
// flushes). The dataset's extent is its reservation: rows beyond the valid ones (/progress
// rows) read as NaN (int32: kInt32Fill); they are not trimmed in place, since a trim is a
// structural change (see the crash-safety note): the finished file is a trimmed copy.
class Series {
 public:
  // A series whose rows have `row_shape` (empty: scalar rows); float64 only when rank > 2.
  // The dataset (created by Group::create_series) holds `rows` valid rows.
  Series(Dataset dataset, Type type, std::size_t block_rows, std::size_t rows = 0);
  Series(Series&&) noexcept = default;
  Series& operator=(Series&&) = delete;  // would drop the target's uncommitted rows
  ~Series();  // commits what is left (errors are swallowed: commit() explicitly to see them)

  // Appends one row: `row.size()` must be the row width (columns, or the product of the row
  // shape; 1 for a 1-D series). No allocation.
  void append(std::span<const double> row);
  void append(double value) { append(std::span<const double>(&value, 1)); }
  void append_int(int value);  // an int32 series
  // Writes the gathered rows to the file: on return they are there (nothing is cached).
  void commit();
  // Forgets every row from `rows` on (later appends overwrite them): a restart from a checkpoint.
  void truncate(std::size_t rows);
  // Commits what is left (the end of a case; the reservation is kept).
  void finish();
  // A per-grain series ([n, grains, ...]) of which this process writes the grains
  // [offset, offset + count) only: a row appended is that block (count x the trailing shape).
  // Call before appending. Other ranks write the other blocks of the same rows.
  void select_grains(std::size_t offset, std::size_t count);
  std::size_t rows() const { return committed_ + pending_; }
  std::size_t capacity() const { return capacity_; }
  const Dataset& dataset() const { return dataset_; }

 private:
  void reserve(std::size_t rows);  // extent >= rows; allocates, fills, flushes
  // Writes `rows` rows of `data` after the committed ones, which then count them.
  void write_rows(const void* data, std::size_t rows);
  void set_extent(std::size_t rows);

  Dataset dataset_;
  std::vector<std::size_t> row_shape_;  // {} for [n], {k} for [n, k], {d1, d2} for [n, d1, d2]
  std::size_t width_;                   // elements per row (of this process's block)
  // select_grains: this process's grains (axis 1 of the dataset); nullopt: every value.
  std::optional<std::pair<std::size_t, std::size_t>> grains_;
  Type type_;
  std::size_t block_rows_;
  std::size_t committed_ = 0;
  std::size_t pending_ = 0;
  std::size_t capacity_ = 0;    // the dataset's extent
  std::size_t chunk_rows_ = 1;  // rows per chunk (a growth allocates whole chunks)
  std::vector<double> block_;   // float64: block_rows x width (none for one row: not copied)
  std::vector<int> int_block_;  // int32: block_rows
};

// The fill of unwritten int32 rows (float64 rows read as NaN).
inline constexpr int kInt32Fill = -2147483647 - 1;

struct SeriesSpec {
  std::string name;
  std::size_t columns = 0;  // 0: 1-D [n]; k: 2-D [n, k]
  Type type = Type::float64;
  std::string unit;         // attribute `unit` ("1" for dimensionless)
  std::string description;  // attribute `description`
  std::size_t chunk_rows = 1024;
  std::size_t block_rows = 256;  // rows gathered in memory between writes
  std::size_t capacity = 0;      // rows reserved at creation (0: chunk_rows)
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
  bool has(std::string_view name) const;       // a direct member of this name exists
  bool is_group(std::string_view name) const;  // the member `name` (which must exist) is a group
  std::vector<std::string> members() const;    // names of direct members
  // A scalar UTF-8 string dataset (with a `description` attribute).
  Dataset write_text(std::string_view name, std::string_view text,
                     std::string_view description) const;
  // A [n] dataset of UTF-8 strings (with a `description` attribute).
  Dataset write_strings(std::string_view name, const std::vector<std::string>& values,
                        std::string_view description) const;
  Series create_series(const SeriesSpec& spec) const;
  // A series that already exists (a restart), holding `rows` valid rows.
  Series open_series(std::string_view name, Type type, std::size_t rows,
                     std::size_t block_rows = 256) const;
  // A float64 or int64 array of `shape` (empty: a scalar), allocated now and filled with NaN
  // or 0; Dataset::write() overwrites it in place (no metadata change: safe at any moment).
  Dataset create_fixed(std::string_view name, std::span<const std::size_t> shape, Type type,
                       std::string_view description) const;
  // A float64 array of `shape` allocated now and filled with NaN, with `unit` and `description`
  // attributes (as write_array), whose values its writers give later (Dataset::write_rows).
  Dataset reserve_array(std::string_view name, std::span<const std::size_t> shape,
                        std::string_view unit, std::string_view description) const;
  // Unlinks a member (its space is not reclaimed; h5repack does that).
  void remove(std::string_view name) const;
  // A fixed float64 array of `shape` (row-major `values`, size = product of shape) with `unit`
  // and `description` attributes; for data that do not change during a run.
  Dataset write_array(std::string_view name, std::span<const std::size_t> shape,
                      std::span<const double> values, std::string_view unit,
                      std::string_view description) const;
};

// The ranks of an MPI communicator opening a file together (parallel HDF5 through MPI-IO):
// `communicator` points at an MPI_Comm (parallel::Team::mpi_communicator()), `rank` is this
// process's rank in it. See the note on collective writes at the top.
struct MpiAccess {
  const void* communicator = nullptr;
  int rank = 0;
};

// Whether this build's HDF5 library can open files through MPI-IO (parallel HDF5).
bool parallel_hdf5();

class File {
 public:
  // Creates `path`; fails if it exists unless `overwrite` (then truncates).
  static File create(const std::filesystem::path& path, bool overwrite);
  static File open_read(const std::filesystem::path& path);
  // An existing file, for writing (a restart). With `mpi`, every rank of its communicator
  // opens the file together (collective writes; Error when this HDF5 is not parallel).
  static File open_write(const std::filesystem::path& path, const MpiAccess* mpi = nullptr);
  File(File&& o) noexcept;
  File& operator=(File&& o) noexcept;
  ~File();
  // Opened by the ranks of a communicator: every call that writes is collective.
  bool collective() const { return collective_; }

  Group root() const;
  const std::filesystem::path& path() const { return path_; }
  // H5Fflush: every metadata change so far reaches the file (rows of a series and fixed
  // arrays need no flush: they are written in place when committed).
  void flush(std::string_view what = "the metadata");  // `what`: for the error message
  // Flushes and closes; throws Error when either fails (the file may then lack metadata).
  void close();
  // Closes without checking (after a failed write, whose Error is the one to report).
  void close_quietly() noexcept;

 private:
  File(Handle h, std::filesystem::path path, bool collective = false);
  void forget_collective() noexcept;  // the file is closed
  Handle handle_;
  std::filesystem::path path_;
  bool collective_ = false;
};

// When a writer commits the rows it gathered: after every output step, unless committing
// costs more than 1/kCostRatio of the computation between steps; then as soon as the time
// since the last commit is kCostRatio times the last commit's cost (or `floor`, if longer).
// A killed run so loses at most the last few milliseconds of computation, for an overhead of
// at most ~5 %. Every output step of a crystal run of a few hundred grains is committed.
class WritePacer {
 public:
  static constexpr double kCostRatio = 20.0;
  // cost_ratio 0: after every output step, whatever it costs.
  explicit WritePacer(std::chrono::duration<double> floor = {}, double cost_ratio = kCostRatio)
      : floor_(floor), cost_ratio_(cost_ratio) {}
  bool due() const;
  // Times `commit` (a callable) and remembers its cost.
  template <class Commit>
  void commit(Commit&& c) {
    const auto start = std::chrono::steady_clock::now();
    c();
    last_ = std::chrono::steady_clock::now();
    cost_ = last_ - start;
  }

 private:
  std::chrono::duration<double> floor_;
  double cost_ratio_;
  std::chrono::duration<double> cost_{0.0};
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// The rows to keep of an extendible dataset (a Series) at `path` ("/cases/base/time") when a
// file is copied by write_exact_copy; nullopt: every row of its extent.
using RowsToKeep = std::function<std::optional<std::size_t>(const std::string& path)>;

// The datasets (by path) whose values the ranks that share the grains write together into a
// copy (write_exact_copy makes them, with their attributes, and leaves their values).
using SharesValues = std::function<bool(const std::string& path)>;
// One of them: its values are split among the ranks along `axis` (0: rows; 1: the second axis
// of a series [n, grains, ...], the grains).
struct SharedDataset {
  std::string path;
  int axis = 0;
};

// Copies every group, dataset and attribute of `source` into `target` (an empty file), in
// creation order, except that an extendible dataset holds only the rows `rows` gives (in
// chunks of whole rows up to about 1 MB, a row larger than that cut along its second axis,
// the grains) and a fixed-length string attribute (a reserved message: `failed`,
// `write_error`) becomes a variable-length one (h5py reads it as str). Datasets are copied in
// blocks of at most a few MB. `target` stays open. With `gzip_level` 1 ... 9 the extendible
// datasets' chunks are stored compressed (byte shuffle, then deflate at that level), where
// this HDF5 has the deflate filter; readers decompress them unasked. The datasets `shares`
// names are made (storage, attributes) without their values: returned, in creation order,
// for BlockCopy.
std::vector<SharedDataset> write_exact_copy(const File& source, const File& target,
                                            const RowsToKeep& rows, int gzip_level = 0,
                                            const SharesValues& shares = {});

// One rank's part of the values of a SharedDataset: the indices [first, first + count) of its
// axis, copied from `source` (opened by this process alone) into `target` (opened by every
// rank: File::open_write with MpiAccess) in steps of at most a few MB of the widest rank's
// block (at least one row of it), the same number of steps on every rank (`widest`: the
// largest count of any rank).
// read(k) reads this rank's part of step k; write(k) writes it (collective: every rank calls
// it for every step, in order, a rank without a part too).
class BlockCopy {
 public:
  BlockCopy(const File& source, const File& target, const SharedDataset& shared, std::size_t first,
            std::size_t count, std::size_t widest);
  std::size_t steps() const { return steps_; }
  void read(std::size_t k);
  void write(std::size_t k);

 private:
  std::pair<std::vector<unsigned long long>, std::vector<unsigned long long>> part(
      std::size_t k) const;
  std::pair<Handle, Handle> spaces(Id dataset, std::size_t k) const;

  std::string what_;  // "dataset <path>", for messages
  Handle from_, to_, memory_;
  std::vector<unsigned long long> dims_;
  std::size_t axis_, first_, count_;
  std::size_t item_bytes_ = 0, step_ = 1, steps_ = 0;
  std::vector<unsigned char> buffer_;
};

// fsync of the file and of its directory (after a rename into it), so that what was written
// survives a crash of the machine too. Throws Error naming the file.
void sync_to_disk(const std::filesystem::path& file);

}  // namespace subslip::io::h5
