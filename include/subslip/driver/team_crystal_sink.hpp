// A crystal sink shared by the ranks of a team (MPI): the root holds the real sink (the result
// file); every rank calls every method, in the same order, with its own block of grains. The
// root stores the blocks gathered in grain order and tells every rank what it found (the cases'
// status, their stored results, the latest checkpoint, scattered back by block) and whether it
// succeeded: a failure of the real sink stops every rank (parallel::on_root), none hangs.
//
// Gathering to the root keeps the result file that of a serial run, but holds one output state
// of the whole aggregate on the root: a run of more grains than one machine holds needs the
// per-rank hyperslab writes of parallel HDF5 instead (CollectiveCrystalSink below). This one
// serves builds whose HDF5 is serial and file systems without MPI-IO (--gather-output).
#pragma once

#include "subslip/driver/crystal_sink.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::driver {

class TeamCrystalSink final : public CrystalSink {
 public:
  // `root_sink`: the real sink on the root, null on the other ranks.
  TeamCrystalSink(const parallel::Team& team, CrystalSink* root_sink);

  CaseStatus status(std::size_t index) const override;
  StoredCrystalCase stored_case(std::size_t index) const override;
  std::optional<ResumePoint> latest_checkpoint(std::size_t index) const override;
  std::size_t checkpoint_capacity() const override;
  void begin_case(std::size_t index, const ResumePoint* resume) override;
  void write_state(const crystal::MacroState& state, const GrainBlock& grains) override;
  void write_checkpoint(const CheckpointBlock& checkpoint,
                        const crystal::MacroState& last_output) override;
  void complete_case(const CrystalSummary& summary) override;
  void fail_case(const CrystalSummary& summary, const std::string& why) override;
  void end_run() override;

 private:
  const parallel::Team& team_;
  CrystalSink* root_;
};

// A crystal sink of which every rank holds its own, all writing one file together (parallel
// HDF5: io::CrystalSinkOptions::mpi): each stores its own block of grains and the same of
// everything else. Every method is called by every rank in the same order; this makes what
// they store the same where it could differ (a summary's timings are the root's) and agrees
// on failure: when the sink throws on any rank, every rank throws, the lowest failing rank's
// error (a SinkWriteError stays one, on every rank), so no rank waits in a collective write.
class CollectiveCrystalSink final : public CrystalSink {
 public:
  CollectiveCrystalSink(const parallel::Team& team, CrystalSink& own_sink);

  CaseStatus status(std::size_t index) const override;
  StoredCrystalCase stored_case(std::size_t index) const override;
  std::optional<ResumePoint> latest_checkpoint(std::size_t index) const override;
  std::size_t checkpoint_capacity() const override;
  void begin_case(std::size_t index, const ResumePoint* resume) override;
  void write_state(const crystal::MacroState& state, const GrainBlock& grains) override;
  void write_checkpoint(const CheckpointBlock& checkpoint,
                        const crystal::MacroState& last_output) override;
  void complete_case(const CrystalSummary& summary) override;
  void fail_case(const CrystalSummary& summary, const std::string& why) override;
  void end_run() override;

 private:
  template <class Work>
  void together(Work&& work) const;
  CrystalSummary roots(const CrystalSummary& summary) const;

  const parallel::Team& team_;
  CrystalSink& own_;
};

}  // namespace subslip::driver
