// The engine's MPI side: distribution, migration, ghosts, reverse force communication,
// reductions and load balance. See docs/parallel.md for the design and its cost model.
//
// Ownership rules (they make every interaction computed exactly once, on one rank):
//   * a particle belongs to the rank whose box holds its centre (checked at every rebuild);
//   * a bond lives on the rank owning its lower global id (gi), and migrates with that particle;
//   * a contact pair of an owned and a ghost particle is computed by the rank owning the lower
//     global id; its tangential history migrates with that particle;
//   * a crushed pair (engine_crushed.cpp) lives and migrates as its bond did;
//   * plane-wall and mesh-wall contact history migrates with its particle, and so does the
//     per-particle state of force sources (ForceSource::pack_history).
// Forces that a rank computes on its ghosts are sent back to their owners after every force
// evaluation ("reverse communication"), so integration only ever touches owned particles.
#include "engine.h"

#include "common/error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>
#include <unordered_set>

namespace hs::bonded {

namespace {

using par::Bytes;

// Messages are raw bytes of plain structs. Eigen's fixed-size vectors and quaternions are plain
// arrays of doubles (not formally trivially copyable: they declare copy constructors), and all
// ranks run the same binary, so memcpy is exact.
template <class T>
void put(Bytes& b, const T& v) {
  const std::size_t o = b.size();
  b.resize(o + sizeof(T));
  std::memcpy(b.data() + o, &v, sizeof(T));
}

struct Reader {
  const Bytes& b;
  std::size_t pos = 0;
  template <class T>
  T get() {
    if (pos + sizeof(T) > b.size()) throw std::logic_error("hs::bonded: truncated MPI message");
    T v;
    std::memcpy(static_cast<void*>(&v), b.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
  bool done() const { return pos == b.size(); }
};

struct BondWire {
  GlobalId gi, gj;
  std::uint8_t kind;
  BondRef ref;
};
struct PairHistWire {
  GlobalId a, b;
  Vec3 xi;
};
struct CrushedWire {
  GlobalId a, b;
  double set;
  Vec3 xi;
};
struct MeshHistWire {
  std::uint32_t mesh;
  GlobalId gid;
  std::uint64_t feature;
  Vec3 xi;
};

using SteadyClock = std::chrono::steady_clock;
double seconds_since(SteadyClock::time_point t0) {
  return std::chrono::duration<double>(SteadyClock::now() - t0).count();
}

}  // namespace

void Engine::drop_owned(const std::vector<char>& keep) {
  // Owned particles (and their plane-wall friction history) whose keep flag is false leave.
  const std::size_t n = ps_.owned();
  if (ps_.n_ghost != 0) throw std::logic_error("Engine::drop_owned: ghosts must be gone first");
  for (auto& h : wall_hist_) {
    std::size_t w = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (keep[i]) h[w++] = h[i];
    h.resize(w);
  }
  ps_.compact(keep);
}

std::int64_t Engine::global_particle_count() const {
  const auto n = static_cast<std::int64_t>(ps_.owned());
  return parallel() ? comm_->sum(n) : n;
}

std::int64_t Engine::global_bond_count() const {
  const auto n = static_cast<std::int64_t>(bonds_.size());
  return parallel() ? comm_->sum(n) : n;
}

void Engine::carry_pair_history(std::size_t below) {
  for (const auto& p : pairs_)
    if (p.xi.squaredNorm() > 0.0 && p.i < below)
      carried_history_.emplace(GidPair::of(ps_.gid[p.i], ps_.gid[p.j]),
                               ps_.gid[p.i] < ps_.gid[p.j] ? p.xi : Vec3(-p.xi));
}

void Engine::distribute(const par::Comm& comm, const ParallelDef& def) {
  comm_ = &comm;
  pdef_ = def;
  if (!comm.parallel()) return;
  const int me = comm.rank();
  const std::size_t n = ps_.owned();
  if (distributed_) throw std::logic_error("Engine::distribute: called twice");
  distributed_ = true;
  // Every rank holds the same full system here, so local bounds are global.
  Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
  for (std::size_t i = 0; i < n; ++i) {
    lo = lo.cwiseMin(ps_.x[i]);
    hi = hi.cwiseMax(ps_.x[i]);
  }
  if (n == 0) lo = hi = Vec3::Zero();
  std::array<int, 3> dims = def.grid;
  if (dims[0] * dims[1] * dims[2] == 0) dims = par::Decomposition::choose_dims(comm.size(), hi - lo);
  if (dims[0] * dims[1] * dims[2] != comm.size()) {
    std::ostringstream s;
    s << "the decomposition grid " << dims[0] << " x " << dims[1] << " x " << dims[2] << " has "
      << dims[0] * dims[1] * dims[2] << " boxes but the run has " << comm.size()
      << " MPI ranks; make the product equal the rank count, or leave the grid out to have it chosen";
    throw InputError("/parallel/grid", s.str());
  }
  dom_ = par::Decomposition(dims);
  dom_.set_uniform(lo, hi);
  // One id counter on every rank (insert_lattice hands out ids from it): the largest anywhere.
  ps_.advance_gid(static_cast<GlobalId>(comm.max(static_cast<double>(ps_.next_gid()))));
  // Keep this rank's share: particles in its box, bonds whose lower-id particle it owns.
  // The first exchange below balances the cuts by cost and moves particles accordingly.
  // Contact history made before the spread (the relaxation before the freeze runs serially on
  // every rank alike) goes to the first neighbour build by global ids, as at any exchange: a
  // serial run keeps its list, so N ranks must keep the history too.
  carry_pair_history(ps_.size());
  pairs_.clear();
  last_balance_step_ = step_;
  max_bond_length_ = 0.0;
  for (const Bond& b : bonds_) max_bond_length_ = std::max(max_bond_length_, (ps_.x[b.j] - ps_.x[b.i]).norm());
  std::vector<char> keep(n, 0);
  for (std::size_t i = 0; i < n; ++i) keep[i] = dom_.rank_of(ps_.x[i]) == me;
  std::vector<Bond> mine;
  for (const Bond& b : bonds_)
    if (keep[b.i]) mine.push_back(b);
  bonds_.swap(mine);
  std::erase_if(crushed_, [&](const auto& e) {  // on the rank owning a, as its bond was
    const std::uint32_t a = ps_.local(e.first.a);
    return a == ParticleStore::kNone || a >= n || !keep[a];
  });
  drop_owned(keep);
  for (Bond& b : bonds_) {  // owned end bound now (for the cost estimate), the other after the exchange
    b.i = ps_.local(b.gi);
    b.j = ps_.local(b.gj);
  }
  need_rebuild_ = true;
  forces_valid_ = false;
  x_at_build_.clear();
  maybe_balance(true);  // the cost estimate needs bonds, which we now have
  exchange_full();
}

std::vector<double> Engine::particle_work() const {
  // Relative cost of a particle: its integration and fields (1), its listed contact pairs
  // (1 each: distance test, and the contact law when touching) and its bonds (4 each: the bond
  // law costs ~4x a contact, see the bonded benchmark profile). Pairs and bonds are charged to
  // the particle whose rank computes them.
  const std::size_t n = ps_.owned();
  std::vector<double> w(n, 1.0);
  for (const auto& p : pairs_)
    if (p.i < n) w[p.i] += 1.0;
  for (const auto& b : bonds_)
    if (b.i < n) w[b.i] += 4.0;
  for (const auto& m : meshes_) {  // mesh queries near the structure
    const Vec3 lo = m.grid->bounds().lo + m.position, hi = m.grid->bounds().hi + m.position;
    for (std::size_t i = 0; i < n; ++i)
      if ((ps_.x[i].array() >= lo.array()).all() && (ps_.x[i].array() <= hi.array()).all()) w[i] += 2.0;
  }
  return w;
}

void Engine::maybe_balance(bool force) {
  if (!parallel()) return;
  if (!force && (pdef_.balance_interval == 0 || step_ - last_balance_step_ < pdef_.balance_interval)) return;
  const std::size_t n = ps_.owned();
  std::vector<double> w = particle_work();
  if (pdef_.cost == ParallelDef::Cost::Time && !force) {
    // Scale this rank's counted work so it sums to its measured time.
    double wsum = 0.0;
    for (double x : w) wsum += x;
    const double scale = wsum > 0.0 ? force_seconds_since_balance_ / wsum : 0.0;
    for (double& x : w) x *= scale;
  }
  double b[6] = {INFINITY, INFINITY, INFINITY, INFINITY, INFINITY, INFINITY};  // -lo, hi
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      b[a] = std::min(b[a], ps_.x[i][a]);
      b[3 + a] = std::min(b[3 + a], -ps_.x[i][a]);
    }
  for (double& x : b) x = -x;
  comm_->max(b, 6);  // b = {-min, max}; a maximum is exact, so every rank has the same bits
  const Vec3 lo(-b[0], -b[1], -b[2]), hi(b[3], b[4], b[5]);
  const int nb = std::max(16, pdef_.histogram_bins);
  std::vector<double> h(3 * static_cast<std::size_t>(nb), 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      const double span = hi[a] - lo[a];
      const int k = span > 0.0 ? std::clamp(static_cast<int>((ps_.x[i][a] - lo[a]) / span * nb), 0, nb - 1) : 0;
      h[a * nb + k] += w[i];
    }
  // The cuts must be identical on every rank (or peers and owners would disagree): the sum is
  // reduced on rank 0 and broadcast.
  comm_->sum_same_everywhere(h.data(), static_cast<int>(h.size()));
  std::array<std::vector<double>, 3> hist;
  for (int a = 0; a < 3; ++a) hist[a].assign(h.begin() + a * nb, h.begin() + (a + 1) * nb);
  dom_.balance(hist, lo, hi);
  last_balance_step_ = step_;
  force_seconds_since_balance_ = 0.0;
  ++pstats_.balances;
}

void Engine::exchange_full() {
  const auto t0 = SteadyClock::now();
  ++pstats_.exchanges;
  drop_ghosts();
  redistribute();
  pstats_.comm_seconds += seconds_since(t0);
}

void Engine::drop_ghosts() {
  // 1. Ghosts go; contact history leaves the pair list for global-id keys (oriented low -> high).
  // The pair list stays (its owned ends still count in the load balance) until redistribute().
  const std::size_t n = ps_.owned();
  // Longest bond before the ghosts go (every bond's two ends are present now).
  // (Right after distribute() the far ends are not bound yet: keep the length measured there.)
  double lb = 0.0;
  bool unbound = false;
  for (const Bond& b : bonds_) {
    if (b.i >= ps_.size() || b.j >= ps_.size()) {
      unbound = true;
      continue;
    }
    lb = std::max(lb, (ps_.x[b.j] - ps_.x[b.i]).norm());
  }
  max_bond_length_ = unbound ? std::max(lb, max_bond_length_) : lb;
  carry_pair_history(n);  // (ghost ids are still there to read)
  ps_.truncate(n);
  for (auto& h : wall_hist_) h.resize(n);
}

void Engine::redistribute() {
  const std::size_t n = ps_.owned();
  // 2. Load balance (moves the cuts) while the pair counts still describe the work.
  const std::uint64_t balances_before = pstats_.balances;
  maybe_balance(false);
  pairs_.clear();
  // 3. Migration to the owners of the new positions.
  const int me = comm_->rank();
  std::vector<int> dest(n, -1);
  bool far = pstats_.balances != balances_before;
  for (std::size_t i = 0; i < n; ++i) {
    const int r = dom_.rank_of(ps_.x[i]);
    if (r == me) continue;
    dest[i] = r;
    if (!std::binary_search(peers_.begin(), peers_.end(), r)) far = true;
  }
  far = global_max(far ? 1.0 : 0.0) > 0.0;
  migrate(dest, far);
  // 4. New ghost lists (the halo covers contacts within the skin and every bond's partner).
  make_ghosts();
  refresh_bond_counts();
}

namespace {

/// Moves the entries of `map` whose key belongs to a leaving particle (gid_of(key) in `leaving`)
/// into the section of its destination rank, as wire_of(entry), counting them.
template <class Map, class GidOf, class WireOf>
void move_leaving(Map& map, const std::unordered_map<GlobalId, int>& leaving, std::vector<Bytes>& out,
                  std::vector<std::uint32_t>& count, GidOf gid_of, WireOf wire_of) {
  for (auto it = map.begin(); it != map.end();) {
    const auto l = leaving.find(gid_of(it->first));
    if (l == leaving.end()) {
      ++it;
      continue;
    }
    put(out[l->second], wire_of(*it));
    ++count[l->second];
    it = map.erase(it);
  }
}

}  // namespace

void Engine::migrate(const std::vector<int>& dest, bool any_rank) {
  const int me = comm_->rank(), np = comm_->size();
  const std::size_t n = ps_.owned();
  std::vector<Bytes> out(np);
  std::vector<std::uint32_t> count(np, 0);
  // Sections per destination: particles (+ wall histories), bonds, pair histories, mesh
  // histories, crushed pairs.
  std::vector<Bytes> bonds_out(np), hist_out(np), mesh_out(np), crushed_out(np);
  std::vector<std::uint32_t> nbonds(np, 0), nhist(np, 0), nmesh(np, 0), ncrushed(np, 0);
  std::unordered_map<GlobalId, int> leaving;
  for (std::size_t i = 0; i < n; ++i) {
    if (dest[i] < 0) continue;
    const int r = dest[i];
    leaving.emplace(ps_.gid[i], r);
    put(out[r], ps_.record(i));
    for (const auto& h : wall_hist_) put(out[r], h[i]);
    ++count[r];
    ++pstats_.migrated;
  }
  if (global_max(leaving.empty() ? 0.0 : 1.0) == 0.0) return;  // nobody moves
  const bool any_leave = !leaving.empty();  // (this rank's scans below are for its own leavers)
  std::vector<Bond> stay;
  for (const Bond& b : bonds_) {
    if (!any_leave) break;
    auto it = leaving.find(b.gi);
    if (it == leaving.end()) {
      stay.push_back(b);
      continue;
    }
    put(bonds_out[it->second], BondWire{b.gi, b.gj, static_cast<std::uint8_t>(b.kind), b.ref});
    ++nbonds[it->second];
  }
  if (any_leave) bonds_.swap(stay);
  if (any_leave) {  // the records keyed by a leaving particle go with it
    move_leaving(carried_history_, leaving, hist_out, nhist, [](const GidPair& k) { return k.a; },
                 [](const auto& e) { return PairHistWire{e.first.a, e.first.b, e.second}; });
    for (std::uint32_t k = 0; k < meshes_.size(); ++k)
      move_leaving(meshes_[k].history, leaving, mesh_out, nmesh, [](const MeshWall::Key& key) { return key.gid; },
                   [k](const auto& e) { return MeshHistWire{k, e.first.gid, e.first.feature, e.second}; });
    move_leaving(crushed_, leaving, crushed_out, ncrushed, [](const GidPair& key) { return key.a; },
                 [](const auto& e) { return CrushedWire{e.first.a, e.first.b, e.second.set, e.second.xi}; });
  }
  std::vector<std::vector<Bytes>> src_out(sources_.size(), std::vector<Bytes>(np));
  if (any_leave)
    for (std::size_t k = 0; k < sources_.size(); ++k) sources_[k]->pack_history(leaving, src_out[k]);
  // Assemble: [n particles][particles][n bonds][bonds][n hist][hist][n mesh][mesh]
  //           [n crushed][crushed] then per force source: [n bytes][bytes]
  std::vector<Bytes> msg(np);
  for (int r = 0; r < np; ++r) {
    if (r == me) continue;
    Bytes& m = msg[r];
    put(m, count[r]);
    m.insert(m.end(), out[r].begin(), out[r].end());
    put(m, nbonds[r]);
    m.insert(m.end(), bonds_out[r].begin(), bonds_out[r].end());
    put(m, nhist[r]);
    m.insert(m.end(), hist_out[r].begin(), hist_out[r].end());
    put(m, nmesh[r]);
    m.insert(m.end(), mesh_out[r].begin(), mesh_out[r].end());
    put(m, ncrushed[r]);
    m.insert(m.end(), crushed_out[r].begin(), crushed_out[r].end());
    for (const auto& so : src_out) {
      put(m, static_cast<std::uint64_t>(so[r].size()));
      m.insert(m.end(), so[r].begin(), so[r].end());
    }
  }
  // Remove the leavers.
  if (any_leave) {
    std::vector<char> keep(n);
    for (std::size_t i = 0; i < n; ++i) keep[i] = dest[i] < 0;
    drop_owned(keep);
  }
  // Send, receive (only with peers unless the cuts moved or someone went far).
  std::vector<Bytes> in;
  std::vector<int> from;
  if (any_rank) {
    in = comm_->all_to_all(msg);
    for (int r = 0; r < np; ++r) from.push_back(r);
  } else {
    std::vector<Bytes> send;
    for (int p : peers_) send.push_back(std::move(msg[p]));
    comm_->exchange(peers_, send, in);
    from = peers_;
  }
  for (std::size_t k = 0; k < in.size(); ++k)
    if (from[k] != me && !in[k].empty()) unpack_migration(in[k]);
}

// One rank's migration message (the layout migrate() assembles).
void Engine::unpack_migration(const Bytes& in) {
  Reader rd{in};
  const auto np_in = rd.get<std::uint32_t>();
  for (std::uint32_t q = 0; q < np_in; ++q) {
    ps_.push(rd.get<ParticleRecord>());
    for (auto& h : wall_hist_) h.push_back(rd.get<Vec3>());
  }
  ps_.n_owned = ps_.size();
  const auto nb = rd.get<std::uint32_t>();
  for (std::uint32_t q = 0; q < nb; ++q) {
    const auto w = rd.get<BondWire>();
    Bond b;
    b.i = b.j = ParticleStore::kNone;  // bound to local indices after the ghost exchange
    b.gi = w.gi;
    b.gj = w.gj;
    b.kind = static_cast<BondKind>(w.kind);
    b.ref = w.ref;
    b.strength = bond_strength(b.gi, b.gj, b.kind);  // from the ids: nothing to send
    bonds_.push_back(b);
  }
  const auto nh = rd.get<std::uint32_t>();
  for (std::uint32_t q = 0; q < nh; ++q) {
    const auto w = rd.get<PairHistWire>();
    carried_history_[GidPair{w.a, w.b}] = w.xi;
  }
  const auto nm = rd.get<std::uint32_t>();
  for (std::uint32_t q = 0; q < nm; ++q) {
    const auto w = rd.get<MeshHistWire>();
    meshes_.at(w.mesh).history[MeshWall::Key{w.gid, w.feature}] = w.xi;
  }
  const auto nc = rd.get<std::uint32_t>();
  for (std::uint32_t q = 0; q < nc; ++q) {
    const auto w = rd.get<CrushedWire>();
    crushed_[GidPair{w.a, w.b}] = CrushedContact{w.set, w.xi};
  }
  for (ForceSource* src : sources_) {
    const auto len = static_cast<std::size_t>(rd.get<std::uint64_t>());
    if (rd.pos + len > in.size()) throw std::logic_error("hs::bonded: truncated MPI message");
    if (len > 0) src->unpack_history(in.data() + rd.pos, len);
    rd.pos += len;
  }
  if (!rd.done()) throw std::logic_error("hs::bonded: malformed migration message");
}

void Engine::make_ghosts() {
  const int me = comm_->rank(), np = comm_->size();
  const std::size_t n = ps_.owned();
  // Halo: contacts within 2 r_max + skin, and the longest bond (with 5 % to spare) + skin.
  double rmax = 0.0;
  for (std::size_t i = 0; i < n; ++i) rmax = std::max(rmax, ps_.radius[i]);
  double g[2] = {rmax, max_bond_length_};
  comm_->max(g, 2);
  max_bond_length_ = g[1];
  // Particles move less than skin/2 between rebuilds, so every partner stays inside the halo
  // until the next one (a missing partner is reported below, never silently dropped).
  halo_ = std::max(2.0 * g[0], 1.05 * g[1]) + skin();
  const par::Box mine = dom_.box(me);
  peers_.clear();
  for (int r = 0; r < np; ++r)
    if (r != me && dom_.box(r).touches(mine, halo_)) peers_.push_back(r);
  ghost_send_.assign(peers_.size(), {});
  std::vector<Bytes> send(peers_.size()), recv;
  for (std::size_t k = 0; k < peers_.size(); ++k) {
    const par::Box b = dom_.box(peers_[k]);
    for (std::size_t i = 0; i < n; ++i)
      if (b.near(ps_.x[i], halo_)) {
        ghost_send_[k].push_back(static_cast<std::uint32_t>(i));
        put(send[k], ps_.record(i));
      }
  }
  comm_->exchange(peers_, send, recv);
  ghost_start_.assign(peers_.size(), 0);
  ghost_n_.assign(peers_.size(), 0);
  for (std::size_t k = 0; k < peers_.size(); ++k) {
    ghost_start_[k] = static_cast<std::uint32_t>(ps_.size());
    Reader rd{recv[k]};
    while (!rd.done()) {
      ps_.push(rd.get<ParticleRecord>());
      ++ghost_n_[k];
    }
  }
  ps_.n_ghost = ps_.size() - ps_.n_owned;
  for (auto& h : wall_hist_) h.resize(ps_.size(), Vec3::Zero());
  // (ParticleStore::push keeps the id index up to date: no full rebuild of it here.)
  // Bind bonds to local indices; a partner missing from owned + ghosts would be a lost bond.
  std::string lost;
  for (Bond& b : bonds_) {
    b.i = ps_.local(b.gi);
    b.j = ps_.local(b.gj);
    if ((b.i == ParticleStore::kNone || b.i >= ps_.n_owned || b.j == ParticleStore::kNone) && lost.empty()) {
      std::ostringstream s;
      s << "bond between particles " << b.gi << " and " << b.gj << " lost its partner at an MPI exchange "
        << "(rank " << me << ", halo " << halo_ << " m): the bond is longer than the ghost halo";
      lost = s.str();
    }
  }
  // Every rank stops together (a rank left alone would wait in the next exchange forever).
  if (global_max(lost.empty() ? 0.0 : 1.0) > 0.0)
    throw SimulationError(lost.empty() ? "a bond lost its partner at an MPI exchange on another rank" : lost);
}

void Engine::refresh_bond_counts() {
  if (!parallel()) return;
  if (!(max_bond_length_ > 0.0)) {  // no bond on any rank (make_ghosts reduced the length)
    for (auto& c : ps_.bond_count) c = 0;
    return;
  }
  // Count every bond at both ends (ghost ends included), then send ghost counts home.
  for (auto& c : ps_.bond_count) c = 0;
  std::vector<std::uint32_t> cnt(ps_.size(), 0);
  for (const Bond& b : bonds_) {  // (ghost counts are scratch: bond_forces may decrement them)
    ++cnt[b.i];
    ++cnt[b.j];
  }
  std::vector<Bytes> send(peers_.size()), recv;
  for (std::size_t k = 0; k < peers_.size(); ++k)
    for (std::uint32_t g = 0; g < ghost_n_[k]; ++g) put(send[k], cnt[ghost_start_[k] + g]);
  comm_->exchange(peers_, send, recv);
  for (std::size_t k = 0; k < peers_.size(); ++k) {
    Reader rd{recv[k]};
    for (std::uint32_t i : ghost_send_[k]) cnt[i] += rd.get<std::uint32_t>();
  }
  for (std::size_t i = 0; i < ps_.owned(); ++i) ps_.bond_count[i] = static_cast<std::uint8_t>(cnt[i]);
}

void Engine::exposure_ghosts_home() {
  std::vector<Bytes> send(peers_.size()), recv;
  for (std::size_t k = 0; k < peers_.size(); ++k)
    for (std::uint32_t g = 0; g < ghost_n_[k]; ++g) {
      const std::uint32_t i = ghost_start_[k] + g;
      put(send[k], exposure_sum_[i]);
      put(send[k], exposure_reach_pos_[i]);
      put(send[k], exposure_reach_neg_[i]);
      put(send[k], exposure_count_[i]);
    }
  comm_->exchange(peers_, send, recv);
  for (std::size_t k = 0; k < peers_.size(); ++k) {  // ascending peer order
    Reader rd{recv[k]};
    for (std::uint32_t i : ghost_send_[k]) {
      exposure_sum_[i] += rd.get<Vec3>();  // exact: quantized components (water.h)
      exposure_reach_pos_[i] = exposure_reach_pos_[i].cwiseMax(rd.get<Vec3>());
      exposure_reach_neg_[i] = exposure_reach_neg_[i].cwiseMax(rd.get<Vec3>());
      exposure_count_[i] += rd.get<std::uint32_t>();
    }
  }
}

// Ghost updates: fixed-size records in persistent buffers, one round of messages each way.
void Engine::forward_ghosts() {
  const auto t0 = SteadyClock::now();
  constexpr std::size_t rec = 3 * sizeof(Vec3) + sizeof(Quat);
  const std::size_t np = peers_.size();
  fwd_send_.resize(np);
  fwd_recv_.resize(np);
  for (std::size_t k = 0; k < np; ++k) {
    par::Bytes& b = fwd_send_[k];
    b.resize(ghost_send_[k].size() * rec);
    char* o = b.data();
    for (std::uint32_t i : ghost_send_[k]) {
      std::memcpy(o, ps_.x[i].data(), sizeof(Vec3));
      std::memcpy(o + sizeof(Vec3), ps_.v[i].data(), sizeof(Vec3));
      std::memcpy(o + 2 * sizeof(Vec3), ps_.omega[i].data(), sizeof(Vec3));
      std::memcpy(o + 3 * sizeof(Vec3), ps_.q[i].coeffs().data(), sizeof(Quat));
      o += rec;
    }
    fwd_recv_[k].resize(ghost_n_[k] * rec);
  }
  comm_->exchange_sized(peers_, fwd_send_, fwd_recv_);
  for (std::size_t k = 0; k < np; ++k) {
    const char* o = fwd_recv_[k].data();
    for (std::uint32_t g = ghost_start_[k], e = ghost_start_[k] + ghost_n_[k]; g < e; ++g) {
      std::memcpy(ps_.x[g].data(), o, sizeof(Vec3));
      std::memcpy(ps_.v[g].data(), o + sizeof(Vec3), sizeof(Vec3));
      std::memcpy(ps_.omega[g].data(), o + 2 * sizeof(Vec3), sizeof(Vec3));
      std::memcpy(ps_.q[g].coeffs().data(), o + 3 * sizeof(Vec3), sizeof(Quat));
      o += rec;
    }
  }
  pstats_.comm_seconds += seconds_since(t0);
}

void Engine::reverse_ghost_forces() {
  const auto t0 = SteadyClock::now();
  constexpr std::size_t rec = 2 * sizeof(Vec3);
  const std::size_t np = peers_.size();
  rev_send_.resize(np);
  rev_recv_.resize(np);
  for (std::size_t k = 0; k < np; ++k) {
    par::Bytes& b = rev_send_[k];
    b.resize(ghost_n_[k] * rec);
    char* o = b.data();
    for (std::uint32_t g = ghost_start_[k], e = ghost_start_[k] + ghost_n_[k]; g < e; ++g) {
      std::memcpy(o, ps_.f[g].data(), sizeof(Vec3));
      std::memcpy(o + sizeof(Vec3), ps_.torque[g].data(), sizeof(Vec3));
      o += rec;
    }
    rev_recv_[k].resize(ghost_send_[k].size() * rec);
  }
  comm_->exchange_sized(peers_, rev_send_, rev_recv_);
  for (std::size_t k = 0; k < np; ++k) {  // ascending peer order: deterministic sums
    const char* o = rev_recv_[k].data();
    for (std::uint32_t i : ghost_send_[k]) {
      Vec3 f, t;
      std::memcpy(f.data(), o, sizeof(Vec3));
      std::memcpy(t.data(), o + sizeof(Vec3), sizeof(Vec3));
      ps_.f[i] += f;
      ps_.torque[i] += t;
      o += rec;
    }
  }
  pstats_.comm_seconds += seconds_since(t0);
}

double Engine::reduce_loads(double flag) {
  const auto t0 = SteadyClock::now();
  std::vector<double> v;
  for (const Vec3& f : wall_force_) v.insert(v.end(), f.data(), f.data() + 3);
  for (const auto& m : meshes_) {
    for (const Vec3& f : m.load.part_force) v.insert(v.end(), f.data(), f.data() + 3);
    for (const Vec3& f : m.load.part_moment) v.insert(v.end(), f.data(), f.data() + 3);
    v.push_back(static_cast<double>(m.load.contacts));
  }
  for (const std::uint64_t b : broken_now_) v.push_back(static_cast<double>(b));
  v.push_back(flag);
  comm_->sum(v.data(), static_cast<int>(v.size()));
  std::size_t k = 0;
  auto take = [&](Vec3& f) {
    f = Vec3(v[k], v[k + 1], v[k + 2]);
    k += 3;
  };
  for (Vec3& f : wall_force_) take(f);
  for (auto& m : meshes_) {
    m.load.force.setZero();
    m.load.moment.setZero();
    for (Vec3& f : m.load.part_force) {
      take(f);
      m.load.force += f;
    }
    for (Vec3& f : m.load.part_moment) {
      take(f);
      m.load.moment += f;
    }
    m.load.contacts = static_cast<std::size_t>(v[k++]);
  }
  for (std::uint64_t& b : broken_now_) b = static_cast<std::uint64_t>(v[k++]);
  pstats_.comm_seconds += seconds_since(t0);
  return v[k];
}

}  // namespace hs::bonded
