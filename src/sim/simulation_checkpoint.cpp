// Checkpoints of a simulation (docs/output.md, "Checkpoints"): the state of every part of the run
// (engine, hybrid system with its rigid world, recorders) saved after a step and restored for a
// restart. `hybridsim run` (app/checkpoint.h) names the files, ties them to the scene and copies
// the run file's rows.
#include "sim/simulation.h"

#include "common/state_archive.h"
#include "io/checkpoint_file.h"
#include "io/run_file.h"
#include "parallel/comm.h"
#include "sim/recorder.h"

#include <cstring>

namespace hs::sim {

namespace {

/// Every rank's archive at rank 0 (collective); the other ranks get an empty list.
std::vector<StateArchive> gather_states(StateArchive a, const par::Comm& comm) {
  std::vector<StateArchive> all;
  if (!comm.parallel()) {
    all.push_back(std::move(a));
    return all;
  }
  const std::string mine = a.serialize();
  par::Bytes b(sizeof(std::uint64_t) + mine.size());
  const std::uint64_t n = mine.size();
  std::memcpy(b.data(), &n, sizeof n);
  std::memcpy(b.data() + sizeof n, mine.data(), mine.size());
  const par::Bytes g = comm.gather(b);
  if (comm.rank() != 0) return all;
  std::size_t o = 0;
  while (o + sizeof(std::uint64_t) <= g.size()) {
    std::uint64_t len;
    std::memcpy(&len, g.data() + o, sizeof len);
    o += sizeof len;
    StateArchive r;
    r.deserialize(g.data() + o, len);
    o += len;
    all.push_back(std::move(r));
  }
  return all;
}

}  // namespace

void Simulation::save_checkpoint(const std::string& path, const io::CheckpointMeta& identity, const Recorders& rec,
                                 io::RunFile& file, const par::Comm& comm) const {
  file.flush();  // the run file holds every row the checkpoint counts
  StateArchive a;
  engine().save_state(a, "engine/");
  hybrid().save_state(a, "hybrid/");
  rec.save_state(a);
  cost_ledger_.save(a);
  const std::vector<StateArchive> all = gather_states(std::move(a), comm);
  if (comm.parallel() && comm.rank() != 0) return;
  io::CheckpointMeta meta = identity;
  meta.step = engine().step_count();
  meta.time = engine().time();
  meta.ranks = comm.size();
  meta.series_rows = file.series_count() ? file.series_rows(0) : 0;
  meta.snapshots = file.snapshot_count();
  meta.program_version = HYBRIDSIM_VERSION;
  meta.run_file = file.path();
  io::write_checkpoint(path, meta, all);
}

std::size_t Simulation::load_checkpoint(const StateArchive& state, Recorders& rec) {
  engine().load_state(state, "engine/");
  const std::size_t lost = hybrid().load_state(state, "hybrid/");
  rec.load_state(state, *this);
  cost_ledger_.add_saved(state);  // the processes before this one: added to this one's set-up
  return lost;
}

std::size_t Simulation::load_checkpoint(const std::vector<StateArchive>& all, Recorders& rec) {
  const std::size_t lost = hybrid().load_state_union(all, "hybrid/");
  engine().load_state_union(all, "engine/");
  rec.load_state(all.front(), *this);
  cost_ledger_.add_saved_union(all.data(), all.size(), comm().rank());
  return lost;
}

}  // namespace hs::sim
