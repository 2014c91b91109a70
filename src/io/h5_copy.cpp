#include "subslip/io/h5_writer.hpp"

#include "h5_detail.hpp"

namespace subslip::io::h5 {

using namespace detail;

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
void copy_rows(hid_t from, hid_t to_group, const std::string& name, std::size_t rows,
               int gzip_level) {
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
  // (The source's own filters, if any, give way to those asked for here.)
  check(H5Premove_filter(dcpl.get(), H5Z_FILTER_ALL), what + ": filters");
  if (gzip_level > 0) {
    // The shuffle groups the bytes of equal significance (doubles of a series share their
    // leading bytes), which deflate then finds.
    check(H5Pset_shuffle(dcpl.get()), what + ": shuffle filter");
    check(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(gzip_level)), what + ": deflate");
  }
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

void copy_group(hid_t from, hid_t to, const std::string& path, const RowsToKeep& rows,
                int gzip_level) {
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
      copy_group(source.get(), target.get(), child, rows, gzip_level);
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
        copy_rows(source.get(), to, name, keep ? *keep : static_cast<std::size_t>(dims[0]),
                  gzip_level);
        continue;
      }
    }
    check(H5Ocopy(from, name.c_str(), to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT), "copy " + child);
  }
}

}  // namespace

void write_exact_copy(const File& source, const File& target, const RowsToKeep& rows,
                      int gzip_level) {
  const Group from = source.root();
  const Group to = target.root();
  if (gzip_level > 0 && H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) gzip_level = 0;
  copy_group(from.id(), to.id(), "/", rows, gzip_level);
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
