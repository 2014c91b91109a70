#include "subslip/io/h5_writer.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <limits>
#include <random>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#ifdef H5_HAVE_PARALLEL
#include <mpi.h>
#endif

namespace subslip::io::h5 {

static_assert(std::is_same_v<hid_t, Id>, "h5::Id must be hid_t (HDF5 >= 1.10)");

bool parallel_hdf5() {
#ifdef H5_HAVE_PARALLEL
  return true;
#else
  return false;
#endif
}

namespace {

// The files this process has open for collective writes (File::open_write with MpiAccess) and
// its rank among their ranks: while one is open, every write is a collective one (every rank
// makes it; see "collective writes" in the header). One communicator per run, so one rank.
struct CollectiveFiles {
  int open = 0;
  int rank = 0;
  const void* communicator = nullptr;  // the ranks' MPI_Comm (MpiAccess), while one is open
  Handle transfer;  // the collective transfer properties, made at the first write, kept while open
};
CollectiveFiles& collective_files() {
  static CollectiveFiles files;
  return files;
}

// HDF5 prints its error stack to stderr by default; we report errors as exceptions instead
// (the stack goes to stderr only when asked for: print_error_stacks).
//
// No clean-up at exit either: HDF5 1.10 frees a file whose close failed (a full disk) but keeps
// its identifier, and its own atexit clean-up then closes it again and crashes (SIGSEGV after
// main returned). Every file is closed explicitly (File::close), so nothing is left to it.
void quiet_hdf5() {
  static const bool once = [] {
    H5dont_atexit();  // must come before any other call initialises the library
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)once;
}

std::atomic<bool> g_print_stacks{false};

// The descriptions on HDF5's error stack, from the API call down to the innermost failure.
std::vector<std::string> error_descriptions() {
  std::vector<std::string> out;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_DOWNWARD,
      [](unsigned, const H5E_error2_t* e, void* data) -> herr_t {
        if (e->desc != nullptr) static_cast<std::vector<std::string>*>(data)->emplace_back(e->desc);
        return 0;
      },
      &out);
  return out;
}

// HDF5's file drivers put the system's errno into the text of the entry that failed
// ("..., errno = 28, error message = 'No space left on device', ..."): that is the reason a
// user can act on, so it is preferred to HDF5's own words.
std::string system_reason(const std::vector<std::string>& descriptions) {
  static constexpr std::string_view kErrno = "errno = ";
  for (auto it = descriptions.rbegin(); it != descriptions.rend(); ++it) {
    const std::size_t at = it->find(kErrno);
    if (at == std::string::npos) continue;
    const int code = std::atoi(it->c_str() + at + kErrno.size());
    if (code > 0) return std::strerror(code);
  }
  return {};
}

// The outermost description (what the API call could not do) and the system's reason, if any.
std::string hdf5_reason() {
  if (g_print_stacks) H5Eprint2(H5E_DEFAULT, stderr);
  const std::vector<std::string> descriptions = error_descriptions();
  H5Eclear2(H5E_DEFAULT);
  const std::string system = system_reason(descriptions);
  if (!system.empty()) return system;
  return descriptions.empty() ? std::string() : descriptions.front();
}

[[noreturn]] void fail(const std::string& what) {
  throw Error(what, hdf5_reason());
}

void check(herr_t status, const std::string& what) {
  if (status < 0) fail(what);
}

// The path of an object in its file ("/cases/base/r_s"), for messages; "" when unknown.
std::string object_path(hid_t id) {
  char name[512] = {};
  const ssize_t n = H5Iget_name(id, name, sizeof name);
  if (n <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return {};
  }
  return name;
}

// "'r_s' in /cases/base": a member of the group or object `loc`.
std::string member(hid_t loc, const std::string& name) {
  const std::string parent = object_path(loc);
  return "'" + name + "'" + (parent.empty() ? "" : " in " + parent);
}

Handle own(hid_t id, Handle::Closer close, const std::string& what) {
  if (id < 0) fail(what);
  return Handle(id, close);
}

Handle make_property_list(hid_t cls) {
  return own(H5Pcreate(cls), H5Pclose, "create property list");
}

// Variable-length UTF-8 string type: what h5py reads back as `str`.
Handle string_type() {
  Handle t = own(H5Tcopy(H5T_C_S1), H5Tclose, "copy string type");
  check(H5Tset_size(t.get(), H5T_VARIABLE), "set string size");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "set string charset");
  return t;
}

Handle scalar_space() {
  return own(H5Screate(H5S_SCALAR), H5Sclose, "create scalar space");
}

Handle simple_space(std::span<const hsize_t> dims, const hsize_t* max_dims = nullptr) {
  return own(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), max_dims), H5Sclose,
             "create dataspace");
}

// Whose values a write stores: data every rank holds alike (stored once, by rank 0, when the
// write is collective), or this process's own part of a dataset.
enum class Part { shared, own };

// The transfer properties of a write: collective MPI-IO while a collective file is open, else
// the default (an invalid handle).
// (made once per collective file, not at every write)
hid_t write_transfer() {
  CollectiveFiles& files = collective_files();
  if (files.open == 0) return H5P_DEFAULT;
#ifdef H5_HAVE_PARALLEL
  if (!files.transfer.valid()) {
    Handle dxpl = own(H5Pcreate(H5P_DATASET_XFER), H5Pclose, "create transfer properties");
    check(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), "set collective transfer");
    files.transfer = std::move(dxpl);
  }
  return files.transfer.get();
#else
  return H5P_DEFAULT;
#endif
}

// H5Dwrite of `data` (in `memory_space`) into the selection `file_space` of `dataset`; on a
// collective write of shared values every rank but 0 takes part with an empty selection.
void write_selection(hid_t dataset, hid_t memory_type, hid_t memory_space, hid_t file_space,
                     const void* data, Part part, const std::string& what) {
  const hid_t transfer = write_transfer();
  if (transfer != H5P_DEFAULT && part == Part::shared && collective_files().rank != 0) {
    Handle nothing = own(H5Dget_space(dataset), H5Sclose, "dataset space");
    check(H5Sselect_none(nothing.get()), "select nothing");
    check(H5Dwrite(dataset, memory_type, nothing.get(), nothing.get(), transfer, data), what);
    return;
  }
  check(H5Dwrite(dataset, memory_type, memory_space, file_space, transfer, data), what);
}

// Groups (and the root) track creation order, so that readers list cases and attributes in
// the order they were written rather than alphabetically.
void track_creation_order(hid_t plist) {
  const unsigned flags = H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED;
  check(H5Pset_link_creation_order(plist, flags), "set link creation order");
  check(H5Pset_attr_creation_order(plist, flags), "set attribute creation order");
}

// True when the stored attribute has `file_type` and the extent of `space`, and is not a
// variable-length string: then H5Awrite rewrites its value where it is, which changes no
// metadata layout (a variable-length string would take new global-heap space).
bool rewritable_in_place(hid_t attr, hid_t file_type, hid_t space) {
  Handle stored_type = own(H5Aget_type(attr), H5Tclose, "attribute type");
  Handle stored_space = own(H5Aget_space(attr), H5Sclose, "attribute space");
  const htri_t same_type = H5Tequal(stored_type.get(), file_type);
  const htri_t variable = H5Tis_variable_str(file_type);
  const htri_t same_extent = H5Sextent_equal(stored_space.get(), space);
  if (same_type < 0 || variable < 0 || same_extent < 0) fail("compare attribute types");
  return same_type > 0 && variable == 0 && same_extent > 0;
}

// Writes an attribute: in place when it exists with the same type and shape (the only kind of
// attribute write a running case makes: see the header's crash-safety note), else created anew.
void replace_attribute(hid_t object, const std::string& name, hid_t file_type, hid_t space,
                       hid_t memory_type, const void* data) {
  const std::string where = "attribute " + member(object, name);
  const htri_t exists = H5Aexists(object, name.c_str());
  if (exists < 0) fail("check " + where);
  if (exists > 0) {
    Handle attr = own(H5Aopen(object, name.c_str(), H5P_DEFAULT), H5Aclose, "open " + where);
    if (rewritable_in_place(attr.get(), file_type, space)) {
      check(H5Awrite(attr.get(), memory_type, data), "write " + where);
      return;
    }
    attr.reset();
    check(H5Adelete(object, name.c_str()), "delete " + where);
  }
  Handle attr = own(H5Acreate2(object, name.c_str(), file_type, space, H5P_DEFAULT, H5P_DEFAULT),
                    H5Aclose, "create " + where);
  check(H5Awrite(attr.get(), memory_type, data), "write " + where);
}

// A fixed-length UTF-8 string type of `bytes` bytes, padded with NULs.
Handle fixed_string_type(std::size_t bytes) {
  Handle t = own(H5Tcopy(H5T_C_S1), H5Tclose, "copy string type");
  check(H5Tset_size(t.get(), std::max<std::size_t>(bytes, 1)), "set string size");
  check(H5Tset_strpad(t.get(), H5T_STR_NULLPAD), "set string padding");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "set string charset");
  return t;
}

// The first bytes of `text` that fit in `bytes`, cut at a UTF-8 character boundary.
std::string utf8_prefix(std::string_view text, std::size_t bytes) {
  if (text.size() <= bytes) return std::string(text);
  std::size_t n = bytes;
  while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80) --n;
  return std::string(text.substr(0, n));
}

Handle open_attribute(hid_t object, std::string_view name) {
  const std::string n(name);
  return own(H5Aopen(object, n.c_str(), H5P_DEFAULT), H5Aclose, "open attribute '" + n + "'");
}

hssize_t element_count(hid_t space) {
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  if (n < 0) fail("count elements");
  return n;
}

// Reads strings of `type` (variable or fixed length) stored in `count` elements.
template <class Read>
std::vector<std::string> read_strings(hid_t stored_type, std::size_t count, Read&& read) {
  std::vector<std::string> out;
  if (H5Tis_variable_str(stored_type) > 0) {
    Handle memory = string_type();
    std::vector<char*> raw(count, nullptr);
    check(read(memory.get(), raw.data()), "read strings");
    for (char* s : raw) {
      out.emplace_back(s != nullptr ? s : "");
      H5free_memory(s);
    }
    return out;
  }
  const std::size_t size = H5Tget_size(stored_type);
  if (size == 0) fail("string size");
  Handle memory = own(H5Tcopy(stored_type), H5Tclose, "copy string type");
  std::vector<char> raw(size * count + 1, '\0');
  check(read(memory.get(), raw.data()), "read strings");
  for (std::size_t i = 0; i < count; ++i) {
    std::string s(raw.data() + i * size, size);
    s.erase(s.find_last_not_of('\0') + 1);
    out.push_back(std::move(s));
  }
  return out;
}

ValueClass value_class_of(hid_t type) {
  switch (H5Tget_class(type)) {
    case H5T_NO_CLASS:
      fail("type class");
    case H5T_FLOAT:
      return ValueClass::floating;
    case H5T_INTEGER:
      return ValueClass::integer;
    case H5T_STRING:
      return ValueClass::string;
    default:
      return ValueClass::other;
  }
}

template <class T>
std::vector<T> read_attribute_numbers(hid_t object, std::string_view name, hid_t memory_type) {
  Handle attr = open_attribute(object, name);
  Handle space = own(H5Aget_space(attr.get()), H5Sclose, "attribute space");
  std::vector<T> out(static_cast<std::size_t>(element_count(space.get())));
  check(H5Aread(attr.get(), memory_type, out.data()), "read attribute '" + std::string(name) + "'");
  return out;
}

// Names visited by H5Literate / H5Aiterate, in creation order when tracked, else by name.
herr_t collect_name(hid_t, const char* name, const void*, void* data) {
  static_cast<std::vector<std::string>*>(data)->emplace_back(name);
  return 0;
}

}  // namespace

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

namespace {

std::vector<std::size_t> shape_of_columns(std::size_t columns) {
  return columns == 0 ? std::vector<std::size_t>{} : std::vector<std::size_t>{columns};
}

std::size_t product(std::span<const std::size_t> shape) {
  std::size_t n = 1;
  for (std::size_t d : shape) n *= d;
  return n;
}

// Series datasets are opened without a chunk cache: a write goes to the file at once, in
// program order (the row counter in /progress is written after the rows it counts).
Handle uncached_access() {
  Handle dapl = make_property_list(H5P_DATASET_ACCESS);
  check(H5Pset_chunk_cache(dapl.get(), 0, 0, 1.0), "disable chunk cache");
  return dapl;
}

}  // namespace

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
    block_.resize(block_rows_ * width_);
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
  block_.assign(block_rows_ * std::max<std::size_t>(width_, 1), 0.0);
}

void Series::commit() {
  if (pending_ == 0) return;
  reserve(committed_ + pending_);
  // [rows, row_shape...]: the selection and the memory block share the trailing dims (of this
  // process's grains, when it writes a block of them).
  std::vector<hsize_t> count{pending_};
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
  const void* data = type_ == Type::float64 ? static_cast<const void*>(block_.data())
                                            : static_cast<const void*>(int_block_.data());
  write_selection(dataset_.id(), memory_type, memory_space.get(), file_space.get(), data,
                  grains_ ? Part::own : Part::shared,
                  "write rows " + std::to_string(committed_) + ".." +
                      std::to_string(committed_ + pending_ - 1) + " of dataset " +
                      object_path(dataset_.id()));
  committed_ += pending_;
  pending_ = 0;
}

void Series::truncate(std::size_t rows) {
  pending_ = 0;
  committed_ = std::min(committed_, rows);
}

void Series::finish() {
  commit();
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

// ---------------------------------------------------------------- exact copies

namespace {

// Reads every attribute of `from` and writes it to `to`, in creation order. Fixed-length
// strings (reserved messages) become variable-length strings, NUL padding dropped.
void copy_attributes(hid_t from, hid_t to) {
  std::vector<std::string> names;
  auto visit = [](hid_t loc, const char* name, const H5A_info_t* info, void* data) -> herr_t {
    return collect_name(loc, name, info, data);
  };
  if (H5Aiterate2(from, H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, visit, &names) < 0) {
    H5Eclear2(H5E_DEFAULT);
    names.clear();
    check(H5Aiterate2(from, H5_INDEX_NAME, H5_ITER_INC, nullptr, visit, &names),
          "list attributes of " + object_path(from));
  }
  for (const std::string& name : names) {
    const std::string where = "attribute " + member(from, name);
    Handle attr = open_attribute(from, name);
    Handle type = own(H5Aget_type(attr.get()), H5Tclose, "type of " + where);
    Handle space = own(H5Aget_space(attr.get()), H5Sclose, "space of " + where);
    const auto count = static_cast<std::size_t>(element_count(space.get()));
    if (H5Tget_class(type.get()) == H5T_STRING) {
      std::vector<std::string> text = read_strings(type.get(), count, [&](hid_t memory, void* buf) {
        return H5Aread(attr.get(), memory, buf);
      });
      Handle vlen = string_type();
      std::vector<const char*> data;
      for (const auto& t : text) data.push_back(t.c_str());
      Handle attr_out =
          own(H5Acreate2(to, name.c_str(), vlen.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose, "create copy of " + where);
      check(H5Awrite(attr_out.get(), vlen.get(), data.data()), "write copy of " + where);
      continue;
    }
    if (H5Tdetect_class(type.get(), H5T_VLEN) > 0)
      throw Error("HDF5: " + where + ": variable-length data are not copied");
    Handle memory =
        own(H5Tget_native_type(type.get(), H5T_DIR_DEFAULT), H5Tclose, "native type of " + where);
    std::vector<unsigned char> raw(std::max<std::size_t>(count, 1) * H5Tget_size(memory.get()));
    check(H5Aread(attr.get(), memory.get(), raw.data()), "read " + where);
    Handle attr_out =
        own(H5Acreate2(to, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
            H5Aclose, "create copy of " + where);
    check(H5Awrite(attr_out.get(), memory.get(), raw.data()), "write copy of " + where);
  }
}

// At most this many bytes of rows are read and written at a time.
constexpr std::size_t kCopyBlockBytes = std::size_t{16} << 20;
// The chunk size a finished series aims at (whole rows; at least one).
constexpr std::size_t kFinishedChunkBytes = std::size_t{1} << 20;

// An extendible dataset (a series): its first `rows` rows, chunked as in `from` but with
// chunks of at most `rows` rows; attributes copied.
void copy_rows(hid_t from, hid_t to_group, const std::string& name, std::size_t rows) {
  const std::string what = "copy rows of dataset " + object_path(from);
  Handle space = own(H5Dget_space(from), H5Sclose, what);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 1) fail(what);
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank)), max_dims(dims.size());
  check(H5Sget_simple_extent_dims(space.get(), dims.data(), max_dims.data()), what);
  rows = std::min<std::size_t>(rows, dims[0]);
  Handle type = own(H5Dget_type(from), H5Tclose, what);
  Handle memory = own(H5Tget_native_type(type.get(), H5T_DIR_DEFAULT), H5Tclose, what);
  std::size_t row_bytes = H5Tget_size(memory.get());
  for (std::size_t d = 1; d < dims.size(); ++d) row_bytes *= dims[d];
  // Chunks of at least the source's rows and up to about kFinishedChunkBytes (fewer, larger
  // chunks than a run writing row by row needs), never longer than the rows.
  Handle dcpl = own(H5Dget_create_plist(from), H5Pclose, what);
  std::vector<hsize_t> chunk(dims.size());
  if (H5Pget_chunk(dcpl.get(), rank, chunk.data()) != rank) fail(what + ": chunk shape");
  const hsize_t wide = kFinishedChunkBytes / std::max<std::size_t>(row_bytes, 1);
  chunk[0] = std::clamp<hsize_t>(rows, 1, std::max(chunk[0], wide));
  check(H5Pset_chunk(dcpl.get(), rank, chunk.data()), what + ": chunk");
  check(H5Pset_alloc_time(dcpl.get(), H5D_ALLOC_TIME_INCR), what + ": allocation time");
  std::vector<hsize_t> new_dims = dims;
  new_dims[0] = rows;
  Handle new_space = simple_space(new_dims, max_dims.data());
  Dataset out(own(H5Dcreate2(to_group, name.c_str(), type.get(), new_space.get(), H5P_DEFAULT,
                             dcpl.get(), H5P_DEFAULT),
                  H5Dclose, "create dataset " + member(to_group, name)));
  const std::size_t block =
      std::max<std::size_t>(kCopyBlockBytes / std::max<std::size_t>(row_bytes, 1), 1);
  std::vector<unsigned char> buffer(std::min(block, std::max<std::size_t>(rows, 1)) * row_bytes);
  for (std::size_t first = 0; first < rows; first += block) {
    std::vector<hsize_t> start(dims.size(), 0), count = new_dims;
    start[0] = first;
    count[0] = std::min(block, rows - first);
    Handle from_space = own(H5Dget_space(from), H5Sclose, what);
    check(H5Sselect_hyperslab(from_space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                              nullptr),
          what);
    Handle to_space = own(H5Dget_space(out.id()), H5Sclose, what);
    check(H5Sselect_hyperslab(to_space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                              nullptr),
          what);
    Handle block_space = simple_space(count);
    check(H5Dread(from, memory.get(), block_space.get(), from_space.get(), H5P_DEFAULT,
                  buffer.data()),
          "read rows of dataset " + object_path(from));
    check(H5Dwrite(out.id(), memory.get(), block_space.get(), to_space.get(), H5P_DEFAULT,
                   buffer.data()),
          "write rows of dataset " + object_path(out.id()));
  }
  copy_attributes(from, out.id());
}

// True for a chunked dataset whose first dimension is unlimited (a Series).
bool extendible(hid_t dataset) {
  Handle space = own(H5Dget_space(dataset), H5Sclose, "dataset space");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 1) return false;
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank)), max_dims(dims.size());
  check(H5Sget_simple_extent_dims(space.get(), dims.data(), max_dims.data()), "dataset extent");
  return max_dims[0] == H5S_UNLIMITED;
}

void copy_group(hid_t from, hid_t to, const std::string& path, const RowsToKeep& rows) {
  copy_attributes(from, to);
  for (const std::string& name :
       Group(own(H5Gopen2(from, ".", H5P_DEFAULT), H5Gclose, "open group " + path)).members()) {
    const std::string child = (path == "/" ? "" : path) + "/" + name;
    H5O_info_t info{};
    check(H5Oget_info_by_name2(from, name.c_str(), &info, H5O_INFO_BASIC, H5P_DEFAULT),
          "inspect " + child);
    if (info.type == H5O_TYPE_GROUP) {
      Handle source = own(H5Gopen2(from, name.c_str(), H5P_DEFAULT), H5Gclose, "open " + child);
      // (Not the source's creation properties: HDF5 1.10 carries the source group's storage
      // addresses in them, which mean nothing in another file.)
      Handle gcpl = make_property_list(H5P_GROUP_CREATE);
      track_creation_order(gcpl.get());
      Handle target = own(H5Gcreate2(to, name.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT),
                          H5Gclose, "create group " + child);
      copy_group(source.get(), target.get(), child, rows);
      continue;
    }
    if (info.type == H5O_TYPE_DATASET) {
      Handle source =
          own(H5Dopen2(from, name.c_str(), H5P_DEFAULT), H5Dclose, "open dataset " + child);
      if (extendible(source.get())) {
        const auto keep = rows ? rows(child) : std::nullopt;
        Handle space = own(H5Dget_space(source.get()), H5Sclose, "dataset space");
        hsize_t dims[H5S_MAX_RANK];
        if (H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0) fail("extent of " + child);
        copy_rows(source.get(), to, name, keep ? *keep : static_cast<std::size_t>(dims[0]));
        continue;
      }
    }
    check(H5Ocopy(from, name.c_str(), to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT), "copy " + child);
  }
}

}  // namespace

void write_exact_copy(const File& source, const File& target, const RowsToKeep& rows) {
  const Group from = source.root();
  const Group to = target.root();
  copy_group(from.id(), to.id(), "/", rows);
}

void sync_to_disk(const std::filesystem::path& file) {
  for (const std::filesystem::path& p :
       {file, file.has_parent_path() ? file.parent_path() : std::filesystem::path(".")}) {
    const int fd = ::open(p.c_str(), O_RDONLY);
    if (fd < 0) throw Error("sync " + p.string() + " to disk", std::strerror(errno));
    const int status = ::fsync(fd);
    const int error = errno;
    ::close(fd);
    // (A directory on a file system that cannot sync one says EINVAL: nothing to do there.)
    if (status != 0 && !(p != file && error == EINVAL))
      throw Error("sync " + p.string() + " to disk", std::strerror(error));
  }
}

}  // namespace subslip::io::h5
