#include "subslip/io/h5_writer.hpp"

#include "h5_detail.hpp"

namespace subslip::io::h5 {

using namespace detail;

// ---------------------------------------------------------------- Dataset

ValueClass Dataset::value_class() const {
  Handle type = own(H5Dget_type(id()), H5Tclose, "dataset type");
  return value_class_of(type.get());
}

std::vector<std::size_t> Dataset::shape() const {
  Handle space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) fail("dataset rank");
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  if (H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0) fail("dataset extent");
  return {dims.begin(), dims.end()};
}

std::vector<double> Dataset::read_doubles() const {
  Handle space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  std::vector<double> out(static_cast<std::size_t>(element_count(space.get())));
  if (!out.empty()) {
    check(H5Dread(id(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()),
          "read dataset");
  }
  return out;
}

std::vector<long long> Dataset::read_ints() const {
  Handle space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  std::vector<long long> out(static_cast<std::size_t>(element_count(space.get())));
  if (!out.empty()) {
    check(H5Dread(id(), H5T_NATIVE_LLONG, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()),
          "read dataset");
  }
  return out;
}

std::string Dataset::read_string() const {
  Handle type = own(H5Dget_type(id()), H5Tclose, "dataset type");
  if (H5Tget_class(type.get()) != H5T_STRING) throw Error("HDF5: dataset is not a string");
  const auto v = read_strings(type.get(), 1, [&](hid_t memory, void* buf) {
    return H5Dread(id(), memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
  });
  return v.front();
}

std::vector<std::size_t> Dataset::chunk_shape() const {
  Handle plist = own(H5Dget_create_plist(id()), H5Pclose, "dataset creation properties");
  const H5D_layout_t layout = H5Pget_layout(plist.get());
  if (layout < 0) fail("dataset layout");
  if (layout != H5D_CHUNKED) return {};
  hsize_t dims[H5S_MAX_RANK];
  const int rank = H5Pget_chunk(plist.get(), H5S_MAX_RANK, dims);
  if (rank < 0) fail("chunk shape");
  return {dims, dims + rank};
}

void Dataset::write(std::span<const double> values) const {
  Handle space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  if (static_cast<std::size_t>(element_count(space.get())) != values.size())
    throw Error("HDF5: values do not fit the dataset");
  write_selection(id(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, values.data(), Part::shared,
                  "write dataset " + object_path(id()));
}

void Dataset::write(std::span<const long long> values) const {
  Handle space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  if (static_cast<std::size_t>(element_count(space.get())) != values.size())
    throw Error("HDF5: values do not fit the dataset");
  write_selection(id(), H5T_NATIVE_LLONG, H5S_ALL, H5S_ALL, values.data(), Part::shared,
                  "write dataset " + object_path(id()));
}

void Dataset::write_element(std::size_t index, long long value) const {
  Handle file_space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  const hsize_t start[1] = {index}, count[1] = {1};
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
        "select element");
  Handle memory_space = simple_space(std::span<const hsize_t>(count, 1));
  write_selection(id(), H5T_NATIVE_LLONG, memory_space.get(), file_space.get(), &value,
                  Part::shared, "write " + object_path(id()));
}

void Dataset::write_prefix(std::span<const double> values) const {
  Handle file_space = own(H5Dget_space(id()), H5Sclose, "dataset space");
  if (H5Sget_simple_extent_ndims(file_space.get()) != 1 ||
      static_cast<std::size_t>(element_count(file_space.get())) < values.size())
    throw Error("HDF5: values do not fit the dataset");
  if (values.empty()) return;
  const hsize_t start[1] = {0}, count[1] = {values.size()};
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
        "select elements");
  Handle memory_space = simple_space(std::span<const hsize_t>(count, 1));
  write_selection(id(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), values.data(),
                  Part::shared, "write dataset " + object_path(id()));
}

namespace {

// The values of one row (the product of the trailing dimensions) of a dataset's space.
std::size_t row_width(hid_t space) {
  const int rank = H5Sget_simple_extent_ndims(space);
  if (rank < 1) throw Error("HDF5: a scalar dataset has no rows");
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  std::size_t width = 1;
  for (std::size_t d = 1; d < dims.size(); ++d) width *= dims[d];
  return width;
}

// The rows [first, first + count) of a dataset, selected in its space.
Handle rows_of(hid_t dataset, std::size_t first, std::size_t count) {
  Handle space = own(H5Dget_space(dataset), H5Sclose, "dataset space");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
  if (rank >= 1) H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  if (rank < 1 || dims[0] < first + count)
    throw Error("HDF5: rows " + std::to_string(first) + ".." + std::to_string(first + count) +
                " are not in dataset " + object_path(dataset));
  if (count == 0) {
    check(H5Sselect_none(space.get()), "select nothing");
    return space;
  }
  std::vector<hsize_t> start(dims.size(), 0), n = dims;
  start[0] = first;
  n[0] = count;
  check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start.data(), nullptr, n.data(), nullptr),
        "select rows");
  return space;
}

Handle memory_of(std::size_t count) {
  const hsize_t n[1] = {std::max<std::size_t>(count, 1)};
  Handle space = simple_space(std::span<const hsize_t>(n, 1));
  if (count == 0) check(H5Sselect_none(space.get()), "select nothing");
  return space;
}

std::size_t rows_in(hid_t dataset, std::size_t values) {
  Handle space = own(H5Dget_space(dataset), H5Sclose, "dataset space");
  const std::size_t width = row_width(space.get());
  if (width == 0 || values % width != 0)
    throw Error("HDF5: values do not fill whole rows of dataset " + object_path(dataset));
  return values / width;
}

}  // namespace

void Dataset::write_rows(std::size_t first, std::span<const double> values) const {
  const std::size_t count = rows_in(id(), values.size());
  const Handle file_space = rows_of(id(), first, count);
  const Handle memory_space = memory_of(values.size());
  const double unused = 0.0;  // (HDF5 wants a buffer even for no values)
  write_selection(id(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(),
                  values.empty() ? &unused : values.data(), Part::own,
                  "write rows " + std::to_string(first) + ".." + std::to_string(first + count) +
                      " of dataset " + object_path(id()));
}

std::vector<double> Dataset::read_rows(std::size_t first, std::size_t count) const {
  const Handle file_space = rows_of(id(), first, count);
  std::size_t width = 0;
  {
    Handle space = own(H5Dget_space(id()), H5Sclose, "dataset space");
    width = row_width(space.get());
  }
  const Handle memory_space = memory_of(count * width);
  std::vector<double> out(std::max<std::size_t>(count * width, 1));
  check(H5Dread(id(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), H5P_DEFAULT,
                out.data()),
        "read rows of dataset " + object_path(id()));
  out.resize(count * width);
  return out;
}

std::vector<std::string> Dataset::filters() const {
  Handle plist = own(H5Dget_create_plist(id()), H5Pclose, "dataset creation properties");
  const int n = H5Pget_nfilters(plist.get());
  if (n < 0) fail("dataset filters");
  std::vector<std::string> out;
  for (int i = 0; i < n; ++i) {
    unsigned flags = 0, config = 0;
    std::size_t n_values = 0;
    char name[64] = {};
    const H5Z_filter_t f = H5Pget_filter2(plist.get(), static_cast<unsigned>(i), &flags, &n_values,
                                          nullptr, sizeof name, name, &config);
    if (f < 0) fail("dataset filter");
    if (f == H5Z_FILTER_SHUFFLE)
      out.emplace_back("shuffle");
    else if (f == H5Z_FILTER_DEFLATE)
      out.emplace_back("deflate");
    else
      out.emplace_back(name);
  }
  return out;
}

// ---------------------------------------------------------------- Series

Series::Series(Dataset dataset, Type type, std::size_t block_rows, std::size_t rows)
    : dataset_(std::move(dataset)), type_(type), block_rows_(std::max<std::size_t>(block_rows, 1)) {
  const auto shape = dataset_.shape();
  row_shape_.assign(shape.begin() + 1, shape.end());
  width_ = product(row_shape_);
  capacity_ = shape.front();
  const auto chunk = dataset_.chunk_shape();
  chunk_rows_ = chunk.empty() ? 1 : std::max<std::size_t>(chunk.front(), 1);
  committed_ = std::min(rows, capacity_);
  if (type_ == Type::float64) {
    if (block_rows_ > 1) block_.resize(block_rows_ * width_);
  } else {
    if (width_ != 1) throw Error("HDF5: an int32 series must be 1-D");
    int_block_.resize(block_rows_);
  }
}

Series::~Series() {
  try {
    if (dataset_.id() >= 0) commit();
  } catch (...) {
    // A destructor must not throw; commit() explicitly to see errors.
  }
}

void Series::append(std::span<const double> row) {
  if (type_ != Type::float64 || row.size() != width_) {
    throw Error("HDF5: row does not match the series' type or width");
  }
  if (block_rows_ == 1) {
    // Written from the caller's row: a per-grain row is large (its series gathers one row at a
    // time), and a copy of it in every series would hold an output state of every grain twice.
    write_rows(row.data(), 1);
    return;
  }
  std::copy(row.begin(), row.end(),
            block_.begin() + static_cast<std::ptrdiff_t>(pending_ * width_));
  if (++pending_ == block_rows_) commit();
}

void Series::append_int(int value) {
  if (type_ != Type::int32) throw Error("HDF5: not an int32 series");
  int_block_[pending_] = value;
  if (++pending_ == block_rows_) commit();
}

void Series::set_extent(std::size_t rows) {
  std::vector<hsize_t> extent{rows};
  extent.insert(extent.end(), row_shape_.begin(), row_shape_.end());
  check(H5Dset_extent(dataset_.id(), extent.data()),
        "grow dataset " + object_path(dataset_.id()) + " to " + std::to_string(rows) + " rows");
  capacity_ = rows;
}

namespace {

// Room for the metadata a growth adds (chunk index nodes, object header messages) beyond the
// chunks themselves (HDF5 allocates metadata in blocks of 2 kB); what is claimed and not used is
// given back after the flush.
constexpr std::uint64_t kGrowthMetadataBytes = 64 << 10;

// HDF5 cannot take back a structural change that fails half-way: a full disk in the middle of
// growing a dataset leaves metadata it can never write, and every later flush (even of a
// message saying so) and the close fail. So the space a growth takes is first claimed from the
// file system, past the end of the file: if that fails, nothing has changed in the file, and the
// error names the system's reason. HDF5 gives back what it does not use when it next flushes
// (it truncates the file to its allocated end).
// The end of the file as HDF5 knows it (what it allocated or wrote), and its descriptor.
struct FileEnd {
  hsize_t size = 0;
  int fd = -1;
};
FileEnd file_end(hid_t object, const std::string& what) {
  Handle file = own(H5Iget_file_id(object), H5Fclose, what + ": file of the dataset");
  FileEnd end;
  check(H5Fget_filesize(file.get(), &end.size), what + ": file size");
  void* handle = nullptr;
  check(H5Fget_vfd_handle(file.get(), H5P_DEFAULT, &handle), what + ": file descriptor");
  end.fd = *static_cast<int*>(handle);  // the sec2 driver (the default) holds an fd
  return end;
}

// The outcome of posix_fallocate for a growth: EINVAL / EOPNOTSUPP mean a file system that
// cannot say in advance, and the growth is tried; any other error stops it.
void check_claim(int error, const std::string& what) {
  if (error != 0 && error != EINVAL && error != EOPNOTSUPP) throw Error(what, std::strerror(error));
}

#ifdef H5_HAVE_PARALLEL
void check_mpi(int error, const std::string& what) {
  if (error == MPI_SUCCESS) return;
  char reason[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(error, reason, &length);
  throw Error(what, std::string(reason, static_cast<std::size_t>(length)));
}

// Claims `bytes` past `end` of the file that holds `object`, through a descriptor of its own:
// 0 or the system's error number (never throws: the other ranks wait for the outcome).
int claim_space_past(hid_t object, std::uint64_t end, std::uint64_t bytes) noexcept {
  const ssize_t length = H5Fget_name(object, nullptr, 0);
  if (length <= 0) return EBADF;
  std::vector<char> path(static_cast<std::size_t>(length) + 1, '\0');
  if (H5Fget_name(object, path.data(), path.size()) < 0) return EBADF;
  const int fd = ::open(path.data(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) return errno;
  const int error = ::posix_fallocate(fd, static_cast<off_t>(end), static_cast<off_t>(bytes));
  ::close(fd);
  return error;
}
#endif

// A collective file: rank 0 claims the space through a descriptor of its own and tells every
// rank the outcome, so that all of them either grow the dataset or stop with the same error.
// (MPI_File_preallocate is no substitute: Open MPI's OMPIO fails it on all but one rank, with
// MPI_ERR_OTHER, and a rank that leaves the collective sequence of a growth hangs the others;
// HDF5 1.10's H5Fget_filesize fails on an MPI-IO file.) The end is the largest size any rank
// sees: each looks at its own moment, and another may already be writing the next rows. Space
// claimed and not used stays until HDF5 truncates the file to its end when it closes it.
void claim_collective_file_space([[maybe_unused]] hid_t object,
                                 [[maybe_unused]] std::uint64_t bytes, const std::string& what) {
#ifdef H5_HAVE_PARALLEL
  Handle file = own(H5Iget_file_id(object), H5Fclose, what + ": file of the dataset");
  void* handle = nullptr;
  check(H5Fget_vfd_handle(file.get(), H5P_DEFAULT, &handle), what + ": MPI-IO file handle");
  const MPI_Comm comm = *static_cast<const MPI_Comm*>(collective_files().communicator);
  // [size seen, MPI error of that]: no rank throws before the reduction, which every rank makes.
  long long seen[2] = {0, 0};
  MPI_Offset size = 0;
  seen[1] = MPI_File_get_size(*static_cast<MPI_File*>(handle), &size);
  seen[0] = static_cast<long long>(size);
  long long agreed[2] = {0, 0};
  check_mpi(MPI_Allreduce(seen, agreed, 2, MPI_LONG_LONG, MPI_MAX, comm),
            what + ": file size over the ranks");
  check_mpi(static_cast<int>(seen[1]), what + ": file size");  // (MPI error codes are >= 0)
  if (agreed[1] != MPI_SUCCESS) throw Error(what + ": file size", "unknown on another rank");
  int error = 0;
  if (collective_files().rank == 0)
    error = claim_space_past(file.get(), static_cast<std::uint64_t>(agreed[0]), bytes);
  check_mpi(MPI_Bcast(&error, 1, MPI_INT, 0, comm), what + ": outcome over the ranks");
  check_claim(error, what);
#else
  throw Error(what, "collective writes need parallel HDF5");
#endif
}

void claim_file_space(hid_t object, std::uint64_t bytes, const std::string& what) {
  if (collective_files().open > 0) return claim_collective_file_space(object, bytes, what);
  const FileEnd end = file_end(object, what);
  const int error =
      ::posix_fallocate(end.fd, static_cast<off_t>(end.size), static_cast<off_t>(bytes));
  check_claim(error, what);
}

// Gives back what a growth claimed and HDF5 did not use: the file ends where HDF5's data do.
void release_unused_space(hid_t object, const std::string& what) {
  if (collective_files().open > 0) return;  // (see claim_collective_file_space)
  const FileEnd end = file_end(object, what);
  struct stat st {};
  if (::fstat(end.fd, &st) == 0 && static_cast<hsize_t>(st.st_size) > end.size &&
      ::ftruncate(end.fd, static_cast<off_t>(end.size)) != 0)
    throw Error(what + ": give back unused space", std::strerror(errno));
}

}  // namespace

void Series::reserve(std::size_t rows) {
  if (rows <= capacity_) return;
  const std::size_t extent = std::max(rows, 2 * capacity_);
  const std::size_t chunks =
      (extent + chunk_rows_ - 1) / chunk_rows_ - (capacity_ + chunk_rows_ - 1) / chunk_rows_;
  const std::size_t value_bytes = type_ == Type::float64 ? sizeof(double) : sizeof(int);
  // Whole rows: the chunks hold every grain, also where this rank writes a block of them (rank
  // 0 claims for all; its block alone, 19 of 37 grains under 2 ranks, let HDF5 run out of space
  // inside the growth on one rank while another waited in it for good).
  const std::size_t row_values = product(row_shape_);
  claim_file_space(
      dataset_.id(), chunks * chunk_rows_ * row_values * value_bytes + kGrowthMetadataBytes,
      "grow dataset " + object_path(dataset_.id()) + " to " + std::to_string(extent) + " rows");
  set_extent(extent);
  // The new extent (and its chunks) must be in the file before rows that use it are counted.
  check(H5Fflush(dataset_.id(), H5F_SCOPE_LOCAL),
        "flush file after growing dataset " + object_path(dataset_.id()));
  release_unused_space(dataset_.id(), "grow dataset " + object_path(dataset_.id()));
}

void Series::select_grains(std::size_t offset, std::size_t count) {
  if (row_shape_.empty() || offset + count > row_shape_[0] || pending_ > 0 ||
      type_ != Type::float64)
    throw Error("HDF5: grains " + std::to_string(offset) + ".." + std::to_string(offset + count) +
                " of dataset " + object_path(dataset_.id()) + " cannot be selected");
  grains_.emplace(offset, count);
  width_ = count * product(std::span<const std::size_t>(row_shape_).subspan(1));
  if (block_rows_ > 1) block_.assign(block_rows_ * std::max<std::size_t>(width_, 1), 0.0);
}

void Series::commit() {
  if (pending_ == 0) return;
  write_rows(type_ == Type::float64 ? static_cast<const void*>(block_.data())
                                    : static_cast<const void*>(int_block_.data()),
             pending_);
  pending_ = 0;
}

void Series::write_rows(const void* data, std::size_t rows) {
  reserve(committed_ + rows);
  // [rows, row_shape...]: the selection and the memory block share the trailing dims (of this
  // process's grains, when it writes a block of them).
  std::vector<hsize_t> count{rows};
  count.insert(count.end(), row_shape_.begin(), row_shape_.end());
  std::vector<hsize_t> start(count.size(), 0);
  start[0] = committed_;
  if (grains_) {
    start[1] = grains_->first;
    count[1] = grains_->second;
  }
  Handle file_space = own(H5Dget_space(dataset_.id()), H5Sclose, "dataset space");
  Handle memory_space;
  if (width_ == 0) {  // a block of no grains: this rank takes part in the write with nothing
    check(H5Sselect_none(file_space.get()), "select nothing");
    memory_space = own(H5Scopy(file_space.get()), H5Sclose, "memory space");
  } else {
    check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                              nullptr),
          "select rows");
    memory_space = simple_space(count);
  }
  const hid_t memory_type = type_ == Type::float64 ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT;
  write_selection(dataset_.id(), memory_type, memory_space.get(), file_space.get(), data,
                  grains_ ? Part::own : Part::shared,
                  "write rows " + std::to_string(committed_) + ".." +
                      std::to_string(committed_ + rows - 1) + " of dataset " +
                      object_path(dataset_.id()));
  committed_ += rows;
}

void Series::truncate(std::size_t rows) {
  pending_ = 0;
  committed_ = std::min(committed_, rows);
}

void Series::finish() {
  commit();
}
}  // namespace subslip::io::h5
