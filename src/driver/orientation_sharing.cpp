#include "subslip/driver/orientation_sharing.hpp"

#include "subslip/driver/crystal_run.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <exception>
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
