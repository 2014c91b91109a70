#include "subslip/driver/orientation_sharing.hpp"

#include "subslip/driver/crystal_run.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>

namespace subslip::driver {

namespace {

// An orientation as the doubles a rank sends another (bit for bit: q, g, weight) and back.
constexpr std::size_t kOrientationValues = 14;
void pack(const crystal::Orientation& o, std::vector<double>& out) {
  out.insert(out.end(), {o.q.w, o.q.x, o.q.y, o.q.z});
  out.insert(out.end(), o.g.data(), o.g.data() + 9);
  out.push_back(o.weight);
}
std::vector<crystal::Orientation> unpacked(std::span<const double> values) {
  std::vector<crystal::Orientation> out(values.size() / kOrientationValues);
  for (std::size_t k = 0; k < out.size(); ++k) {
    const double* v = values.data() + kOrientationValues * k;
    out[k].q = {v[0], v[1], v[2], v[3]};
    std::copy(v + 4, v + 13, out[k].g.data());
    out[k].weight = v[13];
  }
  return out;
}

// Rank 0's second pass over the set: each rank's block, sent to it in rank order (its own
// kept); every rank gets exactly one message, whatever happens. Returns rank 0's block; sets
// `complete` when the set gave `total` orientations again without a problem.
std::vector<double> send_blocks(const RootOrientationReader& reader, const parallel::Team& team,
                                std::size_t total, bool& complete) {
  std::vector<double> buffer, own;
  int rank = 0;
  const auto finished = [&] {
    return buffer.size() == kOrientationValues * parallel::block_of(total, rank, team.size()).count;
  };
  const auto hand_over = [&] {
    if (rank == 0)
      own = std::move(buffer);
    else
      team.send(buffer, rank);
    buffer.clear();
    ++rank;
  };
  while (rank < team.size() && finished()) hand_over();
  const std::optional<std::size_t> read = reader.second_pass([&](const crystal::Orientation& o) {
    if (rank >= team.size()) return;  // (more than the first pass read: the set changed)
    pack(o, buffer);
    while (rank < team.size() && finished()) hand_over();
  });
  while (rank < team.size()) hand_over();  // (what is left, if the set changed)
  complete = read.has_value() && *read == total;
  return own;
}

// Rank 0's reader of an orientation file (its second pass reports a problem as nullopt).
RootOrientationReader root_reader(const model::OrientationFile& file, double& largest) {
  RootOrientationReader reader;
  reader.first_pass = [&file, &largest](const OrientationVisitor& each) {
    return file.read(each, largest);
  };
  reader.noted = [&largest] { return largest; };
  reader.second_pass = [&file](const OrientationVisitor& each) -> std::optional<std::size_t> {
    try {
      double again = -1.0;
      return file.read(each, again);
    } catch (const std::exception&) {
      return std::nullopt;
    }
  };
  reader.fail_weights = file.fail_weights;
  reader.fail_changed = file.fail_changed;
  return reader;
}

// A generated set, made one orientation at a time on every rank alike: each keeps only its
// block, and learns the digest and the weight sum of the whole set on the way.
void generate_own_block(model::CrystalCase& c, const parallel::Team& team) {
  const crystal::OrientationRequest& request = *c.orientation_origin.generated;
  const parallel::Block mine = parallel::block_of(request.count, team.rank(), team.size());
  model::OrientationDigest digest;
  double sum = 0.0;
  std::size_t index = 0;
  std::vector<crystal::Orientation> own;
  own.reserve(mine.count);
  crystal::for_each_generated_orientation(request, [&](const crystal::Orientation& o) {
    digest.add(o);
    sum += o.weight;
    if (index >= mine.offset && index - mine.offset < mine.count) own.push_back(o);
    ++index;
  });
  c.orientation_block = model::OrientationBlock{mine.offset, index, sum, digest.text()};
  c.orientations = std::move(own);
}

// An orientation as a rank keeps it between reading and sharing: the quaternion and the
// weight (its matrix follows from the quaternion alone: Orientation::from_quaternion).
constexpr std::size_t kReadValues = 5;
void keep(const crystal::Orientation& o, std::vector<double>& out) {
  out.insert(out.end(), {o.q.w, o.q.x, o.q.y, o.q.z, o.weight});
}
crystal::Orientation kept(const double* v) {
  const crystal::Quaternion q{v[0], v[1], v[2], v[3]};
  return {q, crystal::quaternion_to_matrix(q), v[4]};
}

// What each rank read of its byte range, as every rank learns it.
struct RangeRead {
  bool failed = false;   // an input error in its lines
  bool complete = true;  // the file as long as it was
  std::size_t orientations = 0;
  std::size_t lines = 0;
  double largest_euler_deg = -1.0;
};
std::vector<RangeRead> ranges_read(const parallel::Team& team, const RangeRead& mine) {
  const std::vector<double> all = team.all_gather(std::vector<double>{
      mine.failed ? 1.0 : 0.0, mine.complete ? 1.0 : 0.0, static_cast<double>(mine.orientations),
      static_cast<double>(mine.lines), mine.largest_euler_deg});
  std::vector<RangeRead> out(static_cast<std::size_t>(team.size()));
  for (std::size_t r = 0; r < out.size(); ++r) {
    const double* v = all.data() + 5 * r;
    out[r] = {v[0] != 0.0, v[1] != 0.0, static_cast<std::size_t>(v[2]),
              static_cast<std::size_t>(v[3]), v[4]};
  }
  return out;
}

// Stops every rank alike where a rank's range failed: the problem of the lowest such rank, the
// first in the file, as a serial read reports it (its line counted from the file's start).
void stop_on_first_problem(const model::OrientationFile& file, const parallel::Team& team,
                           const std::vector<RangeRead>& reads, const std::string& start,
                           const model::OrientationLines& mine) {
  auto lines_before = static_cast<std::size_t>(std::count(start.begin(), start.end(), '\n'));
  for (std::size_t r = 0; r < reads.size(); ++r) {
    if (!reads[r].failed && !reads[r].complete) file.fail_changed();
    if (!reads[r].failed) {
      lines_before += reads[r].lines;
      continue;
    }
    const int owner = static_cast<int>(r);
    std::string key = mine.problem_key, message = mine.problem_message;
    std::vector<double> line{static_cast<double>(mine.problem_line)};
    team.broadcast(key, owner);
    team.broadcast(message, owner);
    team.broadcast(line, owner);
    file.fail_line(static_cast<int>(lines_before + static_cast<std::size_t>(line[0])), key,
                   message);
  }
}

// The digest and the weight sum of the whole set, in file order: each rank continues them over
// its orientations from where the rank before it left them (FNV-1a is a chain: a rank cannot
// start before the one ahead of it is done, but hashing is cheap next to parsing the text).
std::pair<std::string, double> digest_in_rank_order(const parallel::Team& team,
                                                    const std::vector<double>& read) {
  // The 64-bit state as two 32-bit halves, each exact in a double; then the sum.
  std::vector<double> carried{0.0, 0.0, 0.0};
  std::uint64_t state = model::OrientationDigest().state();
  double sum = 0.0;
  if (team.rank() > 0) {
    carried = team.receive(team.rank() - 1);
    state = (static_cast<std::uint64_t>(carried[0]) << 32) | static_cast<std::uint64_t>(carried[1]);
    sum = carried[2];
  }
  model::OrientationDigest digest(state);
  for (std::size_t k = 0; k < read.size(); k += kReadValues) {
    crystal::Orientation o;
    o.q = {read[k], read[k + 1], read[k + 2], read[k + 3]};
    o.weight = read[k + 4];
    digest.add(o);
    sum += o.weight;
  }
  carried = {static_cast<double>(digest.state() >> 32),
             static_cast<double>(digest.state() & 0xffffffffu), sum};
  if (team.rank() + 1 < team.size()) team.send(carried, team.rank() + 1);
  team.broadcast(carried, team.size() - 1);
  state = (static_cast<std::uint64_t>(carried[0]) << 32) | static_cast<std::uint64_t>(carried[1]);
  return {model::OrientationDigest(state).text(), carried[2]};
}

// How many values of the orientations [first, first + count) fall into each rank's block of
// `total`.
std::vector<std::size_t> values_per_block(std::size_t first, std::size_t count, std::size_t total,
                                          int ranks) {
  std::vector<std::size_t> out(static_cast<std::size_t>(ranks), 0);
  for (int q = 0; q < ranks; ++q) {
    const parallel::Block b = parallel::block_of(total, q, ranks);
    const std::size_t low = std::max(first, b.offset),
                      high = std::min(first + count, b.offset + b.count);
    if (high > low) out[static_cast<std::size_t>(q)] = kReadValues * (high - low);
  }
  return out;
}

// Each rank's orientations, read in file order by byte ranges, sent to the ranks whose blocks of
// grains hold them; this rank's block.
std::vector<crystal::Orientation> regrouped(const parallel::Team& team,
                                            const std::vector<RangeRead>& reads,
                                            std::vector<double>&& read, std::size_t total) {
  std::size_t first = 0;  // of this rank's orientations, in the file
  for (int r = 0; r < team.rank(); ++r) first += reads[static_cast<std::size_t>(r)].orientations;
  const std::vector<std::size_t> to =
      values_per_block(first, read.size() / kReadValues, total, team.size());
  const parallel::Block mine = parallel::block_of(total, team.rank(), team.size());
  std::vector<std::size_t> from(static_cast<std::size_t>(team.size()), 0);
  std::size_t at = 0;
  for (std::size_t r = 0; r < reads.size(); ++r) {
    const std::size_t low = std::max(at, mine.offset),
                      high = std::min(at + reads[r].orientations, mine.offset + mine.count);
    if (high > low) from[r] = kReadValues * (high - low);
    at += reads[r].orientations;
  }
  std::vector<double> values = team.exchange(read, to, from);
  read = std::vector<double>();  // (freed before the block is built)
  std::vector<crystal::Orientation> out(mine.count);
  for (std::size_t k = 0; k < mine.count; ++k) out[k] = kept(values.data() + kReadValues * k);
  return out;
}

// An orientation file read by every rank, each the lines that start in its range of the bytes
// after the file's start (which rank 0 reads and every rank reads again from memory, for its
// header and columns); a problem is the first in the file, as a serial read reports it. A file
// whose bytes are not its lines (a byte-order mark) is read by rank 0 for all. Returns false for
// such a file, having read nothing.
bool read_by_ranges(model::CrystalCase& c, const OrientationSharing& sharing) {
  const model::OrientationFile& file = *c.orientation_origin.file;
  const parallel::Team& team = *sharing.team;
  std::vector<double> read;  // this rank's orientations, in file order (kReadValues each)
  std::string start;
  std::vector<double> size{-1.0};  // the file's bytes; -1: read whole
  parallel::on_root(
      team,
      [&] {
        std::optional<std::string> s = file.read_start([&](const auto& o) { keep(o, read); });
        if (!s) return;
        start = std::move(*s);
        size[0] = static_cast<double>(std::filesystem::file_size(file.path));
      },
      sharing.exit_code_of);
  team.broadcast(size, 0);
  if (size[0] < 0.0) return false;
  team.broadcast(start, 0);
  const auto bytes = static_cast<std::uint64_t>(size[0]);
  const parallel::Block range =
      parallel::block_of(bytes > start.size() ? bytes - start.size() : 0, team.rank(), team.size());
  const std::uint64_t begin = start.size() + range.offset;
  const model::OrientationLines lines =
      file.read_lines(start, begin, begin + range.count, [&](const auto& o) { keep(o, read); });
  const std::vector<RangeRead> reads =
      ranges_read(team, {lines.problem_line != 0, lines.complete, read.size() / kReadValues,
                         lines.lines, lines.largest_euler_deg});
  stop_on_first_problem(file, team, reads, start, lines);
  std::size_t total = 0;
  double largest = -1.0;
  for (const RangeRead& r : reads) {
    total += r.orientations;
    largest = std::max(largest, r.largest_euler_deg);
  }
  const auto [digest, sum] = digest_in_rank_order(team, read);
  if (!std::isfinite(sum)) file.fail_weights();
  c.orientation_source.largest_euler_deg = largest;
  c.orientation_block = model::OrientationBlock{
      parallel::block_of(total, team.rank(), team.size()).offset, total, sum, digest};
  c.orientations = regrouped(team, reads, std::move(read), total);
  return true;
}

// This rank's block of the orientations of `c`, and what the whole set gives.
void read_own_block(model::CrystalCase& c, const OrientationSharing& sharing) {
  if (c.orientation_origin.generated) {
    generate_own_block(c, *sharing.team);
    return;
  }
  if (!c.orientation_origin.file) {
    model::read_all_orientations(c);
    c.orientation_block = keep_own_block(c.orientations, *sharing.team);
    return;
  }
  if (read_by_ranges(c, sharing)) return;
  double largest = -1.0;
  SharedOrientations shared =
      share_root_orientations(sharing, root_reader(*c.orientation_origin.file, largest));
  c.orientation_source.largest_euler_deg = shared.noted;
  c.orientation_block = shared.block;
  c.orientations = std::move(shared.mine);
}

}  // namespace

void read_orientations(model::CrystalScene& scene, const OrientationSharing& sharing) {
  const bool blocks = sharing.team != nullptr && shares_grains(scene, *sharing.team);
  for (model::CrystalCase& c : scene.cases) {
    if (blocks)
      read_own_block(c, sharing);
    else
      model::read_all_orientations(c);
  }
}

model::OrientationBlock keep_own_block(std::vector<crystal::Orientation>& grains,
                                       const parallel::Team& team) {
  double sum = 0.0;
  for (const auto& g : grains) sum += g.weight;
  const parallel::Block mine = parallel::block_of(grains.size(), team.rank(), team.size());
  model::OrientationBlock block{mine.offset, grains.size(), sum,
                                model::orientations_digest(grains)};
  const auto first = grains.begin() + static_cast<std::ptrdiff_t>(mine.offset);
  grains =
      std::vector<crystal::Orientation>(first, first + static_cast<std::ptrdiff_t>(mine.count));
  return block;
}

SharedOrientations share_root_orientations(const OrientationSharing& sharing,
                                           const RootOrientationReader& reader) {
  const parallel::Team& team = *sharing.team;
  std::vector<double> whole(3, 0.0);  // count, weight sum, noted
  std::string digest;
  parallel::on_root(
      team,
      [&] {
        model::OrientationDigest d;
        double sum = 0.0;
        const std::size_t n = reader.first_pass([&](const crystal::Orientation& o) {
          d.add(o);
          sum += o.weight;
        });
        if (!std::isfinite(sum)) reader.fail_weights();
        whole = {static_cast<double>(n), sum, reader.noted()};
        digest = d.text();
      },
      sharing.exit_code_of);
  team.broadcast(whole, 0);
  team.broadcast(digest, 0);
  const auto total = static_cast<std::size_t>(whole[0]);
  SharedOrientations shared;
  shared.noted = whole[2];
  shared.block = model::OrientationBlock{parallel::block_of(total, team.rank(), team.size()).offset,
                                         total, whole[1], digest};
  bool complete = true;
  const std::vector<double> mine =
      team.is_root() ? send_blocks(reader, team, total, complete) : team.receive(0);
  parallel::on_root(
      team,
      [&] {
        if (!complete) reader.fail_changed();
      },
      sharing.exit_code_of);
  shared.mine = unpacked(mine);
  return shared;
}

}  // namespace subslip::driver
