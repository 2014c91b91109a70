// What the HDF5 wrapper's parts (h5_writer.cpp: attributes, groups and files; h5_dataset.cpp:
// datasets and series; h5_copy.cpp: exact copies) share: HDF5's error stack turned into
// exceptions, owned handles, dataspaces and types, the collective transfer, attribute
// helpers. Internal to src/io/.
#pragma once

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

namespace subslip::io::h5::detail {

// The files this process has open for collective writes (File::open_write with MpiAccess) and
// its rank among their ranks: while one is open, every write is a collective one (every rank
// makes it; see "collective writes" in the header). One communicator per run, so one rank.
struct CollectiveFiles {
  int open = 0;
  int rank = 0;
  const void* communicator = nullptr;  // the ranks' MPI_Comm (MpiAccess), while one is open
  Handle transfer;  // the collective transfer properties, made at the first write, kept while open
};
inline CollectiveFiles& collective_files() {
  static CollectiveFiles files;
  return files;
}

// HDF5 prints its error stack to stderr by default; we report errors as exceptions instead
// (the stack goes to stderr only when asked for: print_error_stacks).
//
// No clean-up at exit either: HDF5 1.10 frees a file whose close failed (a full disk) but keeps
// its identifier, and its own atexit clean-up then closes it again and crashes (SIGSEGV after
// main returned). Every file is closed explicitly (File::close), so nothing is left to it.
inline void quiet_hdf5() {
  static const bool once = [] {
    H5dont_atexit();  // must come before any other call initialises the library
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)once;
}

inline std::atomic<bool> g_print_stacks{false};

// The descriptions on HDF5's error stack, from the API call down to the innermost failure.
inline std::vector<std::string> error_descriptions() {
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
inline std::string system_reason(const std::vector<std::string>& descriptions) {
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
inline std::string hdf5_reason() {
  if (g_print_stacks) H5Eprint2(H5E_DEFAULT, stderr);
  const std::vector<std::string> descriptions = error_descriptions();
  H5Eclear2(H5E_DEFAULT);
  const std::string system = system_reason(descriptions);
  if (!system.empty()) return system;
  return descriptions.empty() ? std::string() : descriptions.front();
}

[[noreturn]] inline void fail(const std::string& what) {
  throw Error(what, hdf5_reason());
}

inline void check(herr_t status, const std::string& what) {
  if (status < 0) fail(what);
}

// The path of an object in its file ("/cases/base/r_s"), for messages; "" when unknown.
inline std::string object_path(hid_t id) {
  char name[512] = {};
  const ssize_t n = H5Iget_name(id, name, sizeof name);
  if (n <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return {};
  }
  return name;
}

// "'r_s' in /cases/base": a member of the group or object `loc`.
inline std::string member(hid_t loc, const std::string& name) {
  const std::string parent = object_path(loc);
  return "'" + name + "'" + (parent.empty() ? "" : " in " + parent);
}

inline Handle own(hid_t id, Handle::Closer close, const std::string& what) {
  if (id < 0) fail(what);
  return Handle(id, close);
}

inline Handle make_property_list(hid_t cls) {
  return own(H5Pcreate(cls), H5Pclose, "create property list");
}

// Variable-length UTF-8 string type: what h5py reads back as `str`.
inline Handle string_type() {
  Handle t = own(H5Tcopy(H5T_C_S1), H5Tclose, "copy string type");
  check(H5Tset_size(t.get(), H5T_VARIABLE), "set string size");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "set string charset");
  return t;
}

inline Handle scalar_space() {
  return own(H5Screate(H5S_SCALAR), H5Sclose, "create scalar space");
}

inline Handle simple_space(std::span<const hsize_t> dims, const hsize_t* max_dims = nullptr) {
  return own(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), max_dims), H5Sclose,
             "create dataspace");
}

// Whose values a write stores: data every rank holds alike (stored once, by rank 0, when the
// write is collective), or this process's own part of a dataset.
enum class Part { shared, own };

// The transfer properties of a write: collective MPI-IO while a collective file is open, else
// the default (an invalid handle).
// (made once per collective file, not at every write)
inline hid_t write_transfer() {
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

#ifdef H5_HAVE_PARALLEL
// `text` of rank `owner` on every rank of `comm`.
inline void share_text(std::string& text, int owner, MPI_Comm comm) {
  unsigned long long length = text.size();
  MPI_Bcast(&length, 1, MPI_UNSIGNED_LONG_LONG, owner, comm);
  text.resize(static_cast<std::size_t>(length));
  MPI_Bcast(text.data(), static_cast<int>(length), MPI_CHAR, owner, comm);
}
#endif

// The outcome of a collective write (`status` on this rank), agreed among the ranks: when it
// failed on any rank, every rank throws the Error of the lowest rank it failed on. (A rank that
// threw alone would leave the sequence of collective calls the others go on with, the next
// write's and HDF5's own reductions in it, and every rank would wait for ever: measured, a
// file-size limit on one rank of two.) Collective.
inline void check_collective(herr_t status, const std::string& what) {
#ifdef H5_HAVE_PARALLEL
  std::string action, reason;
  if (status < 0) {
    action = what;
    reason = hdf5_reason();
  }
  const MPI_Comm comm = *static_cast<const MPI_Comm*>(collective_files().communicator);
  int ranks = 0;
  MPI_Comm_size(comm, &ranks);
  const int mine = status < 0 ? collective_files().rank : ranks;
  int first = ranks;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == ranks) return;
  share_text(action, first, comm);
  share_text(reason, first, comm);
  throw Error(action, reason);
#else
  check(status, what);
#endif
}

// H5Dwrite of `data` (in `memory_space`) into the selection `file_space` of `dataset`; on a
// collective write of shared values every rank but 0 takes part with an empty selection, and
// its outcome is agreed (check_collective).
inline void write_selection(hid_t dataset, hid_t memory_type, hid_t memory_space, hid_t file_space,
                            const void* data, Part part, const std::string& what) {
  const hid_t transfer = write_transfer();
  if (transfer == H5P_DEFAULT) {
    check(H5Dwrite(dataset, memory_type, memory_space, file_space, transfer, data), what);
    return;
  }
  if (part == Part::shared && collective_files().rank != 0) {
    Handle nothing = own(H5Dget_space(dataset), H5Sclose, "dataset space");
    check(H5Sselect_none(nothing.get()), "select nothing");
    check_collective(H5Dwrite(dataset, memory_type, nothing.get(), nothing.get(), transfer, data),
                     what);
    return;
  }
  check_collective(H5Dwrite(dataset, memory_type, memory_space, file_space, transfer, data), what);
}

// Groups (and the root) track creation order, so that readers list cases and attributes in
// the order they were written rather than alphabetically.
inline void track_creation_order(hid_t plist) {
  const unsigned flags = H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED;
  check(H5Pset_link_creation_order(plist, flags), "set link creation order");
  check(H5Pset_attr_creation_order(plist, flags), "set attribute creation order");
}

// True when the stored attribute has `file_type` and the extent of `space`, and is not a
// variable-length string: then H5Awrite rewrites its value where it is, which changes no
// metadata layout (a variable-length string would take new global-heap space).
inline bool rewritable_in_place(hid_t attr, hid_t file_type, hid_t space) {
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
inline void replace_attribute(hid_t object, const std::string& name, hid_t file_type, hid_t space,
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
inline Handle fixed_string_type(std::size_t bytes) {
  Handle t = own(H5Tcopy(H5T_C_S1), H5Tclose, "copy string type");
  check(H5Tset_size(t.get(), std::max<std::size_t>(bytes, 1)), "set string size");
  check(H5Tset_strpad(t.get(), H5T_STR_NULLPAD), "set string padding");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "set string charset");
  return t;
}

// The first bytes of `text` that fit in `bytes`, cut at a UTF-8 character boundary.
inline std::string utf8_prefix(std::string_view text, std::size_t bytes) {
  if (text.size() <= bytes) return std::string(text);
  std::size_t n = bytes;
  while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80) --n;
  return std::string(text.substr(0, n));
}

inline Handle open_attribute(hid_t object, std::string_view name) {
  const std::string n(name);
  return own(H5Aopen(object, n.c_str(), H5P_DEFAULT), H5Aclose, "open attribute '" + n + "'");
}

inline hssize_t element_count(hid_t space) {
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

inline ValueClass value_class_of(hid_t type) {
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
inline herr_t collect_name(hid_t, const char* name, const void*, void* data) {
  static_cast<std::vector<std::string>*>(data)->emplace_back(name);
  return 0;
}

inline std::vector<std::size_t> shape_of_columns(std::size_t columns) {
  return columns == 0 ? std::vector<std::size_t>{} : std::vector<std::size_t>{columns};
}

inline std::size_t product(std::span<const std::size_t> shape) {
  std::size_t n = 1;
  for (std::size_t d : shape) n *= d;
  return n;
}

// Series datasets are opened without a chunk cache: a write goes to the file at once, in
// program order (the row counter in /progress is written after the rows it counts).
inline Handle uncached_access() {
  Handle dapl = make_property_list(H5P_DATASET_ACCESS);
  check(H5Pset_chunk_cache(dapl.get(), 0, 0, 1.0), "disable chunk cache");
  return dapl;
}

}  // namespace subslip::io::h5::detail
