#include "subslip/io/h5_writer.hpp"

#include "h5_detail.hpp"

namespace subslip::io::h5 {

using namespace detail;

static_assert(std::is_same_v<hid_t, Id>, "h5::Id must be hid_t (HDF5 >= 1.10)");

bool parallel_hdf5() {
#ifdef H5_HAVE_PARALLEL
  return true;
#else
  return false;
#endif
}

// ---------------------------------------------------------------- paths and time

void check_output_path(const std::filesystem::path& path, bool overwrite) {
  namespace fs = std::filesystem;
  const std::string p = path.string();
  if (p.empty()) throw OutputPathError("empty output path");
  std::error_code ec;
  if (fs::exists(path, ec)) {
    if (fs::is_directory(path, ec)) throw OutputPathError(p + ": is a directory");
    if (!overwrite) throw OutputPathError(p + ": already exists; use --force to overwrite it");
    const int fd = ::open(p.c_str(), O_WRONLY);
    if (fd < 0) throw OutputPathError(p + ": cannot be overwritten: " + std::strerror(errno));
    ::close(fd);
  }
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::exists(dir, ec)) {
    fs::create_directories(dir, ec);
    if (ec)
      throw OutputPathError(p + ": cannot create directory " + dir.string() + ": " + ec.message());
  }
  if (!fs::is_directory(dir, ec))
    throw OutputPathError(p + ": " + dir.string() + " is not a directory");
  static std::atomic<int> counter{0};
  const fs::path probe =
      dir / (".subslip-probe-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
  const int fd = ::open(probe.c_str(), O_CREAT | O_EXCL | O_WRONLY, 0600);
  if (fd < 0) {
    throw OutputPathError(p + ": directory " + dir.string() +
                          " is not writable: " + std::strerror(errno));
  }
  ::close(fd);
  fs::remove(probe, ec);
}

void print_error_stacks(bool on) {
  g_print_stacks = on;
}

std::string iso8601_utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buf;
}

// ---------------------------------------------------------------- Handle

Handle& Handle::operator=(Handle&& o) noexcept {
  if (this != &o) {
    reset();
    id_ = std::exchange(o.id_, -1);
    close_ = o.close_;
  }
  return *this;
}

void Handle::reset() {
  if (id_ >= 0 && close_ != nullptr) close_(id_);
  id_ = -1;
}

// ---------------------------------------------------------------- Object: attributes

void Object::set_attribute(std::string_view name, double value) const {
  Handle space = scalar_space();
  replace_attribute(id(), std::string(name), H5T_IEEE_F64LE, space.get(), H5T_NATIVE_DOUBLE,
                    &value);
}

void Object::set_attribute(std::string_view name, long long value) const {
  Handle space = scalar_space();
  replace_attribute(id(), std::string(name), H5T_STD_I64LE, space.get(), H5T_NATIVE_LLONG, &value);
}

void Object::set_attribute(std::string_view name, std::string_view value) const {
  Handle space = scalar_space();
  Handle type = string_type();
  const std::string text(value);
  const char* data = text.c_str();
  replace_attribute(id(), std::string(name), type.get(), space.get(), type.get(), &data);
}

void Object::set_attribute(std::string_view name, std::span<const double> values) const {
  const hsize_t n[1] = {values.size()};
  Handle space = simple_space(n);
  replace_attribute(id(), std::string(name), H5T_IEEE_F64LE, space.get(), H5T_NATIVE_DOUBLE,
                    values.data());
}

void Object::set_attribute(std::string_view name, std::span<const double> values,
                           std::span<const std::size_t> shape) const {
  const std::vector<hsize_t> dims(shape.begin(), shape.end());
  std::size_t n = 1;
  for (std::size_t d : shape) n *= d;
  if (n != values.size())
    throw Error("HDF5: attribute '" + std::string(name) + "': values do not fit its shape");
  Handle space = simple_space(dims);
  replace_attribute(id(), std::string(name), H5T_IEEE_F64LE, space.get(), H5T_NATIVE_DOUBLE,
                    values.data());
}

void Object::set_attribute(std::string_view name, const std::vector<std::string>& values) const {
  const hsize_t n[1] = {values.size()};
  Handle space = simple_space(n);
  Handle type = string_type();
  std::vector<const char*> data;
  for (const auto& v : values) data.push_back(v.c_str());
  replace_attribute(id(), std::string(name), type.get(), space.get(), type.get(), data.data());
}

void Object::reserve_string_attribute(std::string_view name, std::size_t bytes) const {
  Handle space = scalar_space();
  Handle type = fixed_string_type(bytes);
  const std::string empty(std::max<std::size_t>(bytes, 1), '\0');
  replace_attribute(id(), std::string(name), type.get(), space.get(), type.get(), empty.data());
}

void Object::write_reserved_string(std::string_view name, std::string_view value) const {
  Handle attr = open_attribute(id(), name);
  Handle type = own(H5Aget_type(attr.get()), H5Tclose, "attribute type");
  if (H5Tget_class(type.get()) != H5T_STRING)
    throw Error("HDF5: attribute '" + std::string(name) + "' is not a reserved string");
  if (H5Tis_variable_str(type.get()) > 0) {
    // A finished file keeps its messages as plain strings (write_exact_copy); this is written
    // only when such a file is continued again, before the run writes anything else.
    attr.reset();
    set_attribute(name, value);
    return;
  }
  const std::size_t bytes = H5Tget_size(type.get());
  if (bytes == 0) fail("size of attribute " + member(id(), std::string(name)));
  std::string text = utf8_prefix(value, bytes);
  text.resize(bytes, '\0');
  check(H5Awrite(attr.get(), type.get(), text.data()),
        "write attribute " + member(id(), std::string(name)));
}

bool Object::has_attribute(std::string_view name) const {
  const htri_t exists = H5Aexists(id(), std::string(name).c_str());
  if (exists < 0) fail("check attribute '" + std::string(name) + "'");
  return exists > 0;
}

std::vector<std::string> Object::attribute_names() const {
  std::vector<std::string> names;
  auto visit = [](hid_t loc, const char* name, const H5A_info_t* info, void* data) -> herr_t {
    return collect_name(loc, name, info, data);
  };
  if (H5Aiterate2(id(), H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, visit, &names) < 0) {
    H5Eclear2(H5E_DEFAULT);
    names.clear();
    check(H5Aiterate2(id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, visit, &names), "list attributes");
  }
  return names;
}

double Object::attribute_double(std::string_view name) const {
  const auto v = read_attribute_numbers<double>(id(), name, H5T_NATIVE_DOUBLE);
  if (v.size() != 1) throw Error("HDF5: attribute '" + std::string(name) + "' is not a scalar");
  return v.front();
}

long long Object::attribute_int(std::string_view name) const {
  const auto v = read_attribute_numbers<long long>(id(), name, H5T_NATIVE_LLONG);
  if (v.size() != 1) throw Error("HDF5: attribute '" + std::string(name) + "' is not a scalar");
  return v.front();
}

std::vector<double> Object::attribute_doubles(std::string_view name) const {
  return read_attribute_numbers<double>(id(), name, H5T_NATIVE_DOUBLE);
}

std::vector<std::string> Object::attribute_strings(std::string_view name) const {
  Handle attr = open_attribute(id(), name);
  Handle type = own(H5Aget_type(attr.get()), H5Tclose, "attribute type");
  if (H5Tget_class(type.get()) != H5T_STRING) {
    throw Error("HDF5: attribute '" + std::string(name) + "' is not a string");
  }
  Handle space = own(H5Aget_space(attr.get()), H5Sclose, "attribute space");
  const auto count = static_cast<std::size_t>(element_count(space.get()));
  return read_strings(type.get(), count,
                      [&](hid_t memory, void* buf) { return H5Aread(attr.get(), memory, buf); });
}

std::string Object::attribute_string(std::string_view name) const {
  const auto v = attribute_strings(name);
  if (v.size() != 1) throw Error("HDF5: attribute '" + std::string(name) + "' is not a scalar");
  return v.front();
}

ValueClass Object::attribute_class(std::string_view name) const {
  Handle attr = open_attribute(id(), name);
  Handle type = own(H5Aget_type(attr.get()), H5Tclose, "attribute type");
  return value_class_of(type.get());
}

std::size_t Object::attribute_size(std::string_view name) const {
  Handle attr = open_attribute(id(), name);
  Handle space = own(H5Aget_space(attr.get()), H5Sclose, "attribute space");
  return static_cast<std::size_t>(element_count(space.get()));
}

// ---------------------------------------------------------------- Group

Group Group::create_group(std::string_view name) const {
  const std::string n(name);
  Handle gcpl = make_property_list(H5P_GROUP_CREATE);
  track_creation_order(gcpl.get());
  return Group(own(H5Gcreate2(id(), n.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose,
                   "create group " + member(id(), n)));
}

Group Group::open_group(std::string_view name) const {
  const std::string n(name);
  return Group(own(H5Gopen2(id(), n.c_str(), H5P_DEFAULT), H5Gclose, "open group '" + n + "'"));
}

Dataset Group::open_dataset(std::string_view name) const {
  const std::string n(name);
  return Dataset(own(H5Dopen2(id(), n.c_str(), H5P_DEFAULT), H5Dclose, "open dataset '" + n + "'"));
}

bool Group::has(std::string_view name) const {
  const htri_t exists = H5Lexists(id(), std::string(name).c_str(), H5P_DEFAULT);
  if (exists < 0) fail("check member '" + std::string(name) + "'");
  return exists > 0;
}

bool Group::is_group(std::string_view name) const {
  const std::string n(name);
  Handle object = own(H5Oopen(id(), n.c_str(), H5P_DEFAULT), H5Oclose, "open member '" + n + "'");
  const H5I_type_t type = H5Iget_type(object.get());
  if (type == H5I_BADID) fail("type of member '" + n + "'");
  return type == H5I_GROUP;
}

std::vector<std::string> Group::members() const {
  std::vector<std::string> names;
  auto visit = [](hid_t loc, const char* name, const H5L_info_t* info, void* data) -> herr_t {
    return collect_name(loc, name, info, data);
  };
  if (H5Literate(id(), H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, visit, &names) < 0) {
    H5Eclear2(H5E_DEFAULT);
    names.clear();
    check(H5Literate(id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, visit, &names), "list members");
  }
  return names;
}

Dataset Group::write_text(std::string_view name, std::string_view text,
                          std::string_view description) const {
  const std::string n(name);
  Handle type = string_type();
  Handle space = scalar_space();
  Dataset ds(own(
      H5Dcreate2(id(), n.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
      H5Dclose, "create dataset " + member(id(), n)));
  const std::string copy(text);
  const char* data = copy.c_str();
  check(H5Dwrite(ds.id(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &data),
        "write dataset " + member(id(), n));
  ds.set_attribute("description", description);
  return ds;
}

Dataset Group::write_strings(std::string_view name, const std::vector<std::string>& values,
                             std::string_view description) const {
  const std::string n(name);
  Handle type = string_type();
  const hsize_t count[1] = {values.size()};
  Handle space = simple_space(count);
  Dataset ds(own(
      H5Dcreate2(id(), n.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
      H5Dclose, "create dataset " + member(id(), n)));
  std::vector<const char*> pointers;
  for (const auto& v : values) pointers.push_back(v.c_str());
  if (!values.empty()) {
    check(H5Dwrite(ds.id(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, pointers.data()),
          "write dataset " + member(id(), n));
  }
  ds.set_attribute("description", description);
  return ds;
}

// Reserved rows are allocated at once and filled (NaN / kInt32Fill), so that writing a row
// later changes no metadata. No compression: a compressed chunk is rewritten elsewhere when it
// grows, and HDF5 may reuse the space it frees while the file still points there.
Series Group::create_series(const SeriesSpec& spec) const {
  const std::vector<std::size_t> row_shape =
      spec.row_shape.empty() ? shape_of_columns(spec.columns) : spec.row_shape;
  const int rank = 1 + static_cast<int>(row_shape.size());
  const hsize_t chunk_rows = std::max<hsize_t>(spec.chunk_rows, 1);
  std::vector<hsize_t> dims{spec.capacity > 0 ? spec.capacity : chunk_rows};
  std::vector<hsize_t> max_dims{H5S_UNLIMITED}, chunk{chunk_rows};
  for (std::size_t d : row_shape) {
    dims.push_back(d);
    max_dims.push_back(d);
    chunk.push_back(std::max<hsize_t>(d, 1));
  }
  Handle space = simple_space(dims, max_dims.data());
  Handle dcpl = make_property_list(H5P_DATASET_CREATE);
  check(H5Pset_chunk(dcpl.get(), rank, chunk.data()), "set chunk");
  check(H5Pset_alloc_time(dcpl.get(), H5D_ALLOC_TIME_EARLY), "set allocation time");
  check(H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_ALLOC), "set fill time");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const int int_fill = kInt32Fill;
  const bool real = spec.type == Type::float64;
  if (spec.type == Type::int64) throw Error("HDF5: '" + spec.name + "': no int64 series");
  check(H5Pset_fill_value(dcpl.get(), real ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT,
                          real ? static_cast<const void*>(&nan) : &int_fill),
        "set fill value");
  const hid_t stored = real ? H5T_IEEE_F64LE : H5T_STD_I32LE;
  Handle dapl = uncached_access();
  Dataset ds(own(
      H5Dcreate2(id(), spec.name.c_str(), stored, space.get(), H5P_DEFAULT, dcpl.get(), dapl.get()),
      H5Dclose, "create dataset " + member(id(), spec.name)));
  ds.set_attribute("unit", spec.unit);
  ds.set_attribute("description", spec.description);
  return Series(std::move(ds), spec.type, spec.block_rows);
}

Series Group::open_series(std::string_view name, Type type, std::size_t rows,
                          std::size_t block_rows) const {
  const std::string n(name);
  Handle dapl = uncached_access();
  Dataset ds(own(H5Dopen2(id(), n.c_str(), dapl.get()), H5Dclose, "open dataset '" + n + "'"));
  return Series(std::move(ds), type, block_rows, rows);
}

namespace {

// A float64 or int64 dataset of `shape` (empty: a scalar) in `group`, allocated now and filled
// with NaN or 0, so that writing its values later changes no metadata.
Handle allocated_dataset(hid_t group, const std::string& name, std::span<const std::size_t> shape,
                         Type type) {
  const std::vector<hsize_t> dims(shape.begin(), shape.end());
  Handle space = dims.empty() ? scalar_space() : simple_space(dims);
  Handle dcpl = make_property_list(H5P_DATASET_CREATE);
  check(H5Pset_alloc_time(dcpl.get(), H5D_ALLOC_TIME_EARLY), "set allocation time");
  check(H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_ALLOC), "set fill time");
  const bool real = type == Type::float64;
  if (type == Type::int32) throw Error("HDF5: '" + name + "': fixed arrays are float64 or int64");
  if (real) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    check(H5Pset_fill_value(dcpl.get(), H5T_NATIVE_DOUBLE, &nan), "set fill value");
  }
  return own(H5Dcreate2(group, name.c_str(), real ? H5T_IEEE_F64LE : H5T_STD_I64LE, space.get(),
                        H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
             H5Dclose, "create dataset " + member(group, name));
}

}  // namespace

Dataset Group::create_fixed(std::string_view name, std::span<const std::size_t> shape, Type type,
                            std::string_view description) const {
  Dataset ds(allocated_dataset(id(), std::string(name), shape, type));
  ds.set_attribute("description", description);
  return ds;
}

Dataset Group::reserve_array(std::string_view name, std::span<const std::size_t> shape,
                             std::string_view unit, std::string_view description) const {
  Dataset ds(allocated_dataset(id(), std::string(name), shape, Type::float64));
  ds.set_attribute("unit", unit);
  ds.set_attribute("description", description);
  return ds;
}

void Group::remove(std::string_view name) const {
  const std::string n(name);
  check(H5Ldelete(id(), n.c_str(), H5P_DEFAULT), "remove '" + n + "'");
}

Dataset Group::write_array(std::string_view name, std::span<const std::size_t> shape,
                           std::span<const double> values, std::string_view unit,
                           std::string_view description) const {
  const std::string n(name);
  if (product(shape) != values.size()) throw Error("HDF5: '" + n + "': values do not fit shape");
  const std::vector<hsize_t> dims(shape.begin(), shape.end());
  Handle space = simple_space(dims);
  Dataset ds(own(H5Dcreate2(id(), n.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                            H5P_DEFAULT),
                 H5Dclose, "create dataset " + member(id(), n)));
  if (!values.empty()) {
    check(H5Dwrite(ds.id(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
          "write dataset " + member(id(), n));
  }
  ds.set_attribute("unit", unit);
  ds.set_attribute("description", description);
  return ds;
}

// ---------------------------------------------------------------- File

File::File(Handle h, std::filesystem::path path, bool collective)
    : handle_(std::move(h)), path_(std::move(path)), collective_(collective) {
  if (collective_) ++collective_files().open;
}

File::File(File&& o) noexcept
    : handle_(std::move(o.handle_)),
      path_(std::move(o.path_)),
      collective_(std::exchange(o.collective_, false)) {}

File& File::operator=(File&& o) noexcept {
  if (this == &o) return *this;
  close_quietly();
  handle_ = std::move(o.handle_);
  path_ = std::move(o.path_);
  collective_ = std::exchange(o.collective_, false);
  return *this;
}

File::~File() {
  close_quietly();
}

void File::forget_collective() noexcept {
  CollectiveFiles& files = collective_files();
  if (collective_ && --files.open == 0) {
    files.transfer.reset();
    files.communicator = nullptr;
  }
  collective_ = false;
}

void File::close_quietly() noexcept {
  handle_.reset();
  forget_collective();
}

namespace {

// No sieve buffer: a write into a contiguous dataset (/progress, checkpoints) goes to the file
// at once, in program order.
Handle unbuffered_file_access() {
  Handle fapl = make_property_list(H5P_FILE_ACCESS);
  check(H5Pset_sieve_buf_size(fapl.get(), 0), "disable sieve buffer");
  return fapl;
}

}  // namespace

File File::create(const std::filesystem::path& path, bool overwrite) {
  quiet_hdf5();
  Handle fcpl = make_property_list(H5P_FILE_CREATE);
  track_creation_order(fcpl.get());
  Handle fapl = unbuffered_file_access();
  const hid_t id =
      H5Fcreate(path.c_str(), overwrite ? H5F_ACC_TRUNC : H5F_ACC_EXCL, fcpl.get(), fapl.get());
  return File(own(id, H5Fclose, "create file " + path.string()), path);
}

File File::open_write(const std::filesystem::path& path, const MpiAccess* mpi) {
  quiet_hdf5();
  Handle fapl = unbuffered_file_access();
  const std::string what = "open file " + path.string() + " for writing";
  if (mpi != nullptr) {
#ifdef H5_HAVE_PARALLEL
    check(H5Pset_fapl_mpio(fapl.get(), *static_cast<const MPI_Comm*>(mpi->communicator),
                           MPI_INFO_NULL),
          what + ": MPI-IO access");
    collective_files().rank = mpi->rank;
    collective_files().communicator = mpi->communicator;
#else
    throw Error(what + " by MPI ranks", "this build's HDF5 library is serial");
#endif
  }
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl.get());
  return File(own(id, H5Fclose, what), path, mpi != nullptr);
}

File File::open_read(const std::filesystem::path& path) {
  quiet_hdf5();
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  return File(own(id, H5Fclose, "open file " + path.string()), path);
}

Group File::root() const {
  return Group(own(H5Gopen2(handle_.get(), "/", H5P_DEFAULT), H5Gclose, "open root group"));
}

void File::flush(std::string_view what) {
  check(H5Fflush(handle_.get(), H5F_SCOPE_LOCAL), "write " + std::string(what) + " to the file");
}

// ---------------------------------------------------------------- WritePacer

bool WritePacer::due() const {
  const auto since = std::chrono::steady_clock::now() - last_;
  return since >= floor_ && since >= cost_ratio_ * cost_;
}

// A file's metadata reaches the disk in the flush at the latest; the close is checked as well,
// since a close that fails (a full disk) leaves a file that may not open.
void File::close() {
  if (!handle_.valid()) return;
  flush();
  const herr_t closed = H5Fclose(handle_.release());
  forget_collective();
  check(closed, "close file " + path_.string());
}

}  // namespace subslip::io::h5
