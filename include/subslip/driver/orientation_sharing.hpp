// How MPI ranks that share the grains of a crystal case come to hold only their blocks of its
// orientations (parallel::block_of), so that no process holds the whole set. The run model
// (model::OrientationOrigin, made by io/crystal_scene.hpp) says where a set comes from; this
// decides who reads it and who gets which block.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <vector>

#include "subslip/crystal/rotation.hpp"
#include "subslip/model/crystal_case.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::driver {

// MPI ranks that will share the grains of each case (parallel::block_of) and write them into
// the result file together: with fewer cases than ranks, each rank keeps only its block of each
// case's orientations (model::CrystalCase::orientation_block). An orientation file is then read
// once, by every rank: rank 0 reads its start (up to and with the first orientation: the
// header, the column labels), every rank the lines that start in its range of the bytes after
// it, and the orientations are sent to the ranks whose blocks hold them; the digest and the
// weight sum of the whole file are continued by each rank over its lines, in rank order. A
// problem of the file as a whole is reported by rank 0 (the others stop with `exit_code_of` of
// it: parallel::on_root); a problem in a line is that of the lowest rank that met one, the
// first in the file, which every rank throws alike (the serial read's error, file, line and
// key). A file with a byte-order mark, converted whole before it is read, is read by rank 0
// alone, twice, streaming, and each rank's block sent to it (share_root_orientations); a
// generated set is made on every rank one orientation at a time, each keeping its block; a
// scene's inline set, already in memory, is cut to each rank's block (keep_own_block).
// Collective.
struct OrientationSharing {
  const parallel::Team* team = nullptr;
  parallel::ExitCodeOf exit_code_of = nullptr;
};

// Reads the orientations of every case of `scene` (CrystalCase::orientation_origin into
// `orientations`). Where the ranks of `sharing.team` will share each case's grains (fewer cases
// than ranks), each rank keeps only its block and CrystalCase::orientation_block says what the
// whole set gives; otherwise (no team, or one rank, or a case for each rank) every process
// reads every set (model::read_all_orientations). Collective when sharing.
void read_orientations(model::CrystalScene& scene, const OrientationSharing& sharing);

// Cuts `grains`, a set every rank made alike, to this rank's block; what the whole set gives.
model::OrientationBlock keep_own_block(std::vector<crystal::Orientation>& grains,
                                       const parallel::Team& team);

using OrientationVisitor = std::function<void(const crystal::Orientation&)>;

// A set of orientations only rank 0 reads (an orientation file). Every function is called on
// rank 0 only.
struct RootOrientationReader {
  // The first pass: visits every orientation in order and returns how many; what it throws
  // stops every rank (rank 0 reports it).
  std::function<std::size_t(const OrientationVisitor&)> first_pass;
  // After the first pass: a number every rank learns with the count (the largest |Euler angle|).
  std::function<double()> noted;
  // The second pass: the same, or nullopt when the set cannot be read again.
  std::function<std::optional<std::size_t>(const OrientationVisitor&)> second_pass;
  // Throw the error that stops every rank: weights that sum past the largest double; a set the
  // second pass did not find as the first did (it changed while it was read).
  std::function<void()> fail_weights;
  std::function<void()> fail_changed;
};

struct SharedOrientations {
  std::vector<crystal::Orientation> mine;  // this rank's block
  model::OrientationBlock block;           // what the whole set gives
  double noted = 0.0;                      // RootOrientationReader::noted, on every rank
};

// The set `reader` reads on rank 0, each rank's block sent to it (rank 0 reads it twice: first
// the count, the weight sum and the digest, which every rank learns; then the blocks, in rank
// order, so that rank 0 never holds more than one block). Collective.
SharedOrientations share_root_orientations(const OrientationSharing& sharing,
                                           const RootOrientationReader& reader);

}  // namespace subslip::driver
