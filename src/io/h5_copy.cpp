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

// The chunk of a finished series of `rows` rows of `row_bytes` each (`chunk`: the source's):
// whole rows, at least the source's and up to about kFinishedChunkBytes (fewer, larger chunks
// than a run writing row by row needs), never more than the rows. A row larger than that (a
// per-grain series of many grains) is cut along its second axis, the grains, too: no chunk
// grows with the aggregate, and ranks that write a series together, each its block of grains,
// each compress the chunks of their own block (a chunk is filtered by one rank).
void finished_chunk(std::vector<hsize_t>& chunk, const std::vector<hsize_t>& dims, std::size_t rows,
                    std::size_t row_bytes) {
  if (dims.size() >= 2 && row_bytes > kFinishedChunkBytes && dims[1] > 0) {
    // Pieces of equal size: HDF5 stores the last chunk of an axis whole, however little of it
    // the dataset covers (1 MB pieces: 3 % more plain storage at 2e5 grains).
    const std::size_t pieces = (row_bytes + kFinishedChunkBytes - 1) / kFinishedChunkBytes;
    chunk[0] = 1;
    chunk[1] = std::max<hsize_t>((dims[1] + pieces - 1) / pieces, 1);
    return;
  }
  const hsize_t wide = kFinishedChunkBytes / std::max<std::size_t>(row_bytes, 1);
  chunk[0] = std::clamp<hsize_t>(rows, 1, std::max(chunk[0], wide));
}

// An extendible dataset (a series): its first `rows` rows, chunked as finished_chunk says;
// attributes copied. With `values` false the dataset is made but its values are left to
// the writers of a SharedValues (copy_block_of).
void copy_rows(hid_t from, hid_t to_group, const std::string& name, std::size_t rows,
               int gzip_level, bool values = true) {
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
  Handle dcpl = own(H5Dget_create_plist(from), H5Pclose, what);
  std::vector<hsize_t> chunk(dims.size());
  if (H5Pget_chunk(dcpl.get(), rank, chunk.data()) != rank) fail(what + ": chunk shape");
  finished_chunk(chunk, dims, rows, row_bytes);
  check(H5Pset_chunk(dcpl.get(), rank, chunk.data()), what + ": chunk");
  check(H5Pset_alloc_time(dcpl.get(), H5D_ALLOC_TIME_INCR), what + ": allocation time");
  // (Every value of the copy is written: a fill would only be written twice.)
  check(H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER), what + ": fill time");
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
  if (!values) {
    copy_attributes(from, out.id());
    return;
  }
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

// A fixed (not extendible) dataset made like `from` (type, shape, storage), its attributes
// copied, its values left to the writers of a SharedValues.
void make_like(hid_t from, hid_t to_group, const std::string& name) {
  const std::string what = "create dataset " + member(to_group, name);
  Handle type = own(H5Dget_type(from), H5Tclose, what);
  Handle space = own(H5Dget_space(from), H5Sclose, what);
  Handle dcpl = own(H5Dget_create_plist(from), H5Pclose, what);
  check(H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER), what + ": fill time");
  Dataset out(own(H5Dcreate2(to_group, name.c_str(), type.get(), space.get(), H5P_DEFAULT,
                             dcpl.get(), H5P_DEFAULT),
                  H5Dclose, what));
  copy_attributes(from, out.id());
}

struct CopyPlan {
  RowsToKeep rows;
  int gzip_level = 0;
  SharesValues shares;                   // whose values the ranks write (none: every value here)
  std::vector<SharedDataset>* shared{};  // those, as they are made
};

// A dataset of `from` (at `child`) into `to`.
void copy_dataset(hid_t from, hid_t to, const std::string& name, const std::string& child,
                  const CopyPlan& plan) {
  Handle source = own(H5Dopen2(from, name.c_str(), H5P_DEFAULT), H5Dclose, "open dataset " + child);
  const bool later = plan.shares && plan.shares(child);
  if (extendible(source.get())) {
    const auto keep = plan.rows ? plan.rows(child) : std::nullopt;
    Handle space = own(H5Dget_space(source.get()), H5Sclose, "dataset space");
    hsize_t dims[H5S_MAX_RANK];
    const int rank = H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    if (rank < 0) fail("extent of " + child);
    copy_rows(source.get(), to, name, keep ? *keep : static_cast<std::size_t>(dims[0]),
              plan.gzip_level, !later);
    if (later) plan.shared->push_back({child, rank >= 2 ? 1 : 0});
    return;
  }
  if (later) {
    make_like(source.get(), to, name);
    plan.shared->push_back({child, 0});
    return;
  }
  check(H5Ocopy(from, name.c_str(), to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT), "copy " + child);
}

void copy_group(hid_t from, hid_t to, const std::string& path, const CopyPlan& plan) {
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
      copy_group(source.get(), target.get(), child, plan);
      continue;
    }
    if (info.type == H5O_TYPE_DATASET) {
      copy_dataset(from, to, name, child, plan);
      continue;
    }
    check(H5Ocopy(from, name.c_str(), to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT), "copy " + child);
  }
}

}  // namespace

std::vector<SharedDataset> write_exact_copy(const File& source, const File& target,
                                            const RowsToKeep& rows, int gzip_level,
                                            const SharesValues& shares) {
  const Group from = source.root();
  const Group to = target.root();
  if (gzip_level > 0 && H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) gzip_level = 0;
  std::vector<SharedDataset> shared;
  copy_group(from.id(), to.id(), "/", CopyPlan{rows, gzip_level, shares, &shared});
  return shared;
}

// ---------------------------------------------------------------- a shared dataset's blocks

BlockCopy::BlockCopy(const File& source, const File& target, const SharedDataset& shared,
                     std::size_t first, std::size_t count, std::size_t widest)
    : what_("dataset " + shared.path),
      from_(own(H5Dopen2(source.root().id(), shared.path.c_str(), H5P_DEFAULT), H5Dclose,
                "open dataset " + shared.path + " of " + source.path().string())),
      to_(own(H5Dopen2(target.root().id(), shared.path.c_str(), H5P_DEFAULT), H5Dclose,
              "open dataset " + shared.path + " of " + target.path().string())),
      axis_(static_cast<std::size_t>(shared.axis)),
      first_(first),
      count_(count) {
  Handle space = own(H5Dget_space(to_.get()), H5Sclose, "copy " + what_);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank <= shared.axis) fail("copy " + what_ + ": no axis " + std::to_string(shared.axis));
  dims_.resize(static_cast<std::size_t>(rank));
  check(H5Sget_simple_extent_dims(space.get(), dims_.data(), nullptr), "copy " + what_);
  Handle type = own(H5Dget_type(to_.get()), H5Tclose, "copy " + what_);
  memory_ = own(H5Tget_native_type(type.get(), H5T_DIR_DEFAULT), H5Tclose, "copy " + what_);
  // The bytes of one index of the split axis within one row of the first (for axis 1: a
  // grain's values in one output row; for axis 0: a whole row).
  item_bytes_ = H5Tget_size(memory_.get());
  for (std::size_t d = axis_ + 1; d < dims_.size(); ++d) item_bytes_ *= dims_[d];
  // Steps of at most kCopyBlockBytes of the widest block, whole chunks of rows where the
  // series is split along its second axis: the same number on every rank.
  const std::size_t widest_bytes = std::max<std::size_t>(widest * item_bytes_, 1);
  if (axis_ == 0) {
    step_ = std::max<std::size_t>(kCopyBlockBytes / item_bytes_, 1);
    steps_ = (widest + step_ - 1) / step_;
  } else {
    Handle dcpl = own(H5Dget_create_plist(to_.get()), H5Pclose, "copy " + what_);
    std::vector<hsize_t> chunk(dims_.size(), 1);
    if (H5Pget_chunk(dcpl.get(), rank, chunk.data()) != rank)
      fail("copy " + what_ + ": chunk shape");
    const std::size_t whole = std::max<std::size_t>(chunk[0], 1);
    step_ = std::max<std::size_t>(kCopyBlockBytes / widest_bytes / whole, 1) * whole;
    steps_ = (dims_[0] + step_ - 1) / step_;
  }
}

// This rank's part of step `k`: [start, start + count) of the dataset, maybe nothing.
std::pair<std::vector<hsize_t>, std::vector<hsize_t>> BlockCopy::part(std::size_t k) const {
  std::vector<hsize_t> start(dims_.size(), 0), count = dims_;
  if (axis_ == 0) {
    const std::size_t from = std::min(k * step_, count_);
    start[0] = first_ + from;
    count[0] = std::min(step_, count_ - from);
  } else {
    start[0] = k * step_;
    count[0] = std::min<hsize_t>(step_, dims_[0] - start[0]);
    start[1] = first_;
    count[1] = count_;
  }
  return {start, count};
}

// The selection of this rank's part of step `k` in `dataset`, and the memory space of its
// values (nothing selected in either when it has none).
std::pair<Handle, Handle> BlockCopy::spaces(hid_t dataset, std::size_t k) const {
  const auto [start, count] = part(k);
  Handle file_space = own(H5Dget_space(dataset), H5Sclose, "copy " + what_);
  hsize_t n = 1;
  for (hsize_t c : count) n *= c;
  if (n == 0) {
    check(H5Sselect_none(file_space.get()), "select nothing");
    Handle memory = own(H5Scopy(file_space.get()), H5Sclose, "copy " + what_);
    return {std::move(file_space), std::move(memory)};
  }
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                            nullptr),
        "copy " + what_);
  return {std::move(file_space), simple_space(count)};
}

void BlockCopy::read(std::size_t k) {
  auto [file_space, memory_space] = spaces(from_.get(), k);
  const hssize_t n = H5Sget_select_npoints(memory_space.get());
  buffer_.resize(static_cast<std::size_t>(std::max<hssize_t>(n, 0)) * H5Tget_size(memory_.get()));
  if (n <= 0) return;
  check(H5Dread(from_.get(), memory_.get(), memory_space.get(), file_space.get(), H5P_DEFAULT,
                buffer_.data()),
        "read " + what_);
}

void BlockCopy::write(std::size_t k) {
  auto [file_space, memory_space] = spaces(to_.get(), k);
  write_selection(to_.get(), memory_.get(), memory_space.get(), file_space.get(), buffer_.data(),
                  Part::own, "write " + what_);
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
