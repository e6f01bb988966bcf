#include "engine.h"
#include "integrate_kernel.h"

#include "common/error.h"
#include "common/ice_formulas.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <unordered_map>

namespace hs::bonded {

namespace {


}  // namespace

Engine::Engine(const EngineDef& def) : def_(def), dt_auto_(def.dt == 0.0) { dt_ = def.dt; }

std::size_t Engine::add_particle(const ParticleInit& p) { return add_owned(p, ps_.next_gid()); }

std::size_t Engine::add_owned(const ParticleInit& p, GlobalId id) {
  const std::size_t i = ps_.add(p, id);
  for (auto& h : wall_hist_) h.push_back(Vec3::Zero());
  need_rebuild_ = true;
  forces_valid_ = false;
  note_radius(p.radius);
  return i;
}

void Engine::note_radius(double r) {
  if (r < min_radius_) {
    min_radius_ = r;
    if (dt_auto_)  // Eq. 2 follows the smallest particle
      dt_ = hs::eq2_time_step(def_.dt_alpha, 2.0 * min_radius_, def_.density, def_.youngs_modulus);
  }
}

void Engine::add_bond(GlobalId a, GlobalId b, BondKind kind) {
  if (a == b) throw std::invalid_argument("add_bond: a particle cannot bond to itself");
  const GlobalId gi = std::min(a, b), gj = std::max(a, b);
  const std::uint32_t i = ps_.local(gi), j = ps_.local(gj);
  if (i == ParticleStore::kNone || j == ParticleStore::kNone)
    throw std::invalid_argument("add_bond: unknown particle id");
  Bond bd;
  bd.i = i; bd.j = j; bd.gi = gi; bd.gj = gj; bd.kind = kind;
  bd.ref = BondRef::at_rest(ps_.x[i], ps_.q[i], ps_.radius[i], ps_.x[j], ps_.q[j], ps_.radius[j]);
  bd.strength = bond_strength(gi, gj, kind);
  bonds_.push_back(bd);
  ++ps_.bond_count[i];
  ++ps_.bond_count[j];
  need_rebuild_ = true;
  forces_valid_ = false;
}

std::vector<Bond> Engine::remove_bonds(const std::function<bool(const Bond&)>& which) {
  if (parallel()) throw std::logic_error("Engine::remove_bonds: serial only (call it before distribute())");
  std::vector<Bond> out;
  std::size_t w = 0;
  for (std::size_t r = 0; r < bonds_.size(); ++r) {
    const Bond& b = bonds_[r];
    if (!which(b)) {
      bonds_[w++] = b;
      continue;
    }
    out.push_back(b);
    --ps_.bond_count[b.i];
    --ps_.bond_count[b.j];
  }
  if (out.empty()) return out;
  bonds_.resize(w);
  bond_batch_.invalidate();
  need_rebuild_ = true;  // the pairs join the contact list there (bonded pairs are kept out of it)
  forces_valid_ = false;
  return out;
}

std::vector<std::array<std::uint32_t, 2>> touching_pairs(const std::vector<Vec3>& x, const std::vector<double>& radius,
                                                         double rel_tol) {
  std::vector<std::array<std::uint32_t, 2>> out;
  const std::size_t n = x.size();
  if (n == 0) return out;
  double rmax = 0.0;
  Vec3 lo = x[0], hi = lo;
  for (std::size_t i = 0; i < n; ++i) {
    rmax = std::max(rmax, radius[i]);
    lo = lo.cwiseMin(x[i]);
    hi = hi.cwiseMax(x[i]);
  }
  const double h = 2.0 * rmax * (1.0 + rel_tol) * 1.0001;
  const Eigen::Vector3i dims = (((hi - lo) / h).array().floor().cast<int>() + 1).matrix();
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> cells;
  auto key = [&](int cx, int cy, int cz) {
    return (static_cast<std::int64_t>(cx) * dims.y() + cy) * dims.z() + cz;
  };
  auto cell = [&](const Vec3& p) { return ((p - lo) / h).array().floor().cast<int>().matrix().eval(); };
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3i c = cell(x[i]);
    cells[key(c.x(), c.y(), c.z())].push_back(static_cast<std::uint32_t>(i));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3i c = cell(x[i]);
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const int cx = c.x() + dx, cy = c.y() + dy, cz = c.z() + dz;
          if (cx < 0 || cy < 0 || cz < 0 || cx >= dims.x() || cy >= dims.y() || cz >= dims.z()) continue;
          auto it = cells.find(key(cx, cy, cz));
          if (it == cells.end()) continue;
          for (std::uint32_t j : it->second) {
            if (j <= i) continue;
            const double lim = (radius[i] + radius[j]) * (1.0 + rel_tol);
            if ((x[j] - x[i]).squaredNorm() <= lim * lim) out.push_back({static_cast<std::uint32_t>(i), j});
          }
        }
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::size_t Engine::bond_touching(std::size_t first, std::size_t last, BondKind kind, double rel_tol) {
  if (last <= first) return 0;
  const std::vector<Vec3> x(ps_.x.begin() + first, ps_.x.begin() + last);
  const std::vector<double> r(ps_.radius.begin() + first, ps_.radius.begin() + last);
  std::vector<std::pair<GlobalId, GlobalId>> todo;
  for (const auto& [a, b] : touching_pairs(x, r, rel_tol)) todo.emplace_back(ps_.gid[first + a], ps_.gid[first + b]);
  std::sort(todo.begin(), todo.end());
  for (auto& [a, b] : todo) add_bond(a, b, kind);
  return todo.size();
}

int Engine::add_wall(const PlaneWall& w) {
  PlaneWall c = w;
  const double nn = c.normal.norm();
  if (!(nn > 0.0)) throw std::invalid_argument("add_wall: wall normal must be non-zero");
  c.normal /= nn;
  walls_.push_back(c);
  wall_force_.push_back(Vec3::Zero());
  wall_hist_.emplace_back(ps_.size(), Vec3::Zero());
  forces_valid_ = false;
  return static_cast<int>(walls_.size()) - 1;
}

int Engine::add_mesh_wall(MeshWallDef def) {
  double rmax = 0.0;
  for (std::size_t i = 0; i < ps_.size(); ++i) rmax = std::max(rmax, ps_.radius[i]);
  MeshWall w;
  w.grid = std::make_unique<mesh::MeshGrid>(def.mesh, rmax > 0.0 ? rmax : 0.25);
  w.position = def.position;
  w.load.part_force.assign(std::max<std::size_t>(1, def.mesh.part_names.size()), Vec3::Zero());
  w.load.part_moment = w.load.part_force;
  def.mesh = mesh::TriMesh{};  // the grid keeps its own copy
  def.mesh.part_names = w.grid->mesh().part_names;
  w.def = std::move(def);
  meshes_.push_back(std::move(w));
  forces_valid_ = false;
  return static_cast<int>(meshes_.size()) - 1;
}

void Engine::add_force_source(ForceSource* source) {
  if (source == nullptr) throw std::invalid_argument("add_force_source: null source");
  if (std::find(sources_.begin(), sources_.end(), source) != sources_.end())
    throw std::invalid_argument("add_force_source: source already registered");
  sources_.push_back(source);
  forces_valid_ = false;
}

void Engine::remove_force_source(ForceSource* source) {
  const auto it = std::find(sources_.begin(), sources_.end(), source);
  if (it == sources_.end()) return;
  sources_.erase(it);
  forces_valid_ = false;
}

// ---------------------------------------------------------------- time step

double Engine::eq2_time_step() const {
  double rmin = INFINITY;
  for (std::size_t i = 0; i < ps_.owned(); ++i) rmin = std::min(rmin, ps_.radius[i]);
  rmin = -global_max(-rmin);
  if (!std::isfinite(rmin)) return 0.0;
  return hs::eq2_time_step(def_.dt_alpha, 2.0 * rmin, def_.density, def_.youngs_modulus);
}

double Engine::critical_time_step() const {
  double inv_m = 0.0, inv_i = 0.0, r = 0.0, rmin = INFINITY;
  std::uint8_t zb = 0;
  for (std::size_t i = 0; i < ps_.owned(); ++i) {
    inv_m = std::max(inv_m, ps_.inv_mass[i]);
    inv_i = std::max(inv_i, ps_.inv_inertia[i]);
    r = std::max(r, ps_.radius[i]);
    rmin = std::min(rmin, ps_.radius[i]);
    zb = std::max(zb, ps_.bond_count[i]);
  }
  bool has_kind[2] = {false, false};
  for (const auto& b : bonds_) has_kind[static_cast<int>(b.kind)] = true;
  if (parallel()) {
    double g[7] = {inv_m, inv_i, r, -rmin, static_cast<double>(zb), has_kind[0] ? 1.0 : 0.0, has_kind[1] ? 1.0 : 0.0};
    comm_->max(g, 7);
    inv_m = g[0]; inv_i = g[1]; r = g[2]; rmin = -g[3]; zb = static_cast<std::uint8_t>(g[4]);
    has_kind[0] = g[5] > 0.0; has_kind[1] = g[6] > 0.0;
  }
  if (inv_m == 0.0) return INFINITY;
  const double m = 1.0 / inv_m;
  // Contact springs (identical particles at worst-case mass, inertia and lever arm).
  const ContactStiffness cs = with_contact_law(def_, [&](const auto& law) { return law.time_step_stiffness(rmin); });
  const double kn = cs.kn, kt = cs.kt;
  double zeta = cs.zeta;
  const double s_contact = 2.0 * inv_m * kn + kt * (2.0 * inv_m + 2.0 * r * r * inv_i);
  double s_bond = 0.0;
  for (int k = 0; k < 2; ++k) {
    if (!has_kind[k]) continue;
    const auto& p = def_.bond[k];
    s_bond = std::max(s_bond, 2.0 * inv_m * p.kn + p.ks * (2.0 * inv_m + 2.0 * r * r * inv_i) +
                                  2.0 * inv_i * (p.kb + p.kt));
    if (p.kn > 0.0) zeta = std::max(zeta, p.gamma_n / (2.0 * std::sqrt(0.5 * m * p.kn)));
    if (p.ks > 0.0) zeta = std::max(zeta, p.gamma_s / (2.0 * std::sqrt(0.5 * m * p.ks)));
    if (p.kb > 0.0 && inv_i > 0.0) zeta = std::max(zeta, p.gamma_b / (2.0 * std::sqrt(0.5 / inv_i * p.kb)));
    if (p.kt > 0.0 && inv_i > 0.0) zeta = std::max(zeta, p.gamma_t / (2.0 * std::sqrt(0.5 / inv_i * p.kt)));
  }
  // Gershgorin: a particle has at most 12 touching equal neighbours; bonds take their slots.
  const double z_b = zb;
  const double omega2 = std::max(12.0 * s_contact, z_b * s_bond + std::max(0.0, 12.0 - z_b) * s_contact);
  if (!(omega2 > 0.0)) return INFINITY;
  return 2.0 / std::sqrt(omega2) * (std::sqrt(1.0 + zeta * zeta) - zeta);
}

void Engine::check_time_step() const {
  const double crit = critical_time_step();
  if (!(dt_ > 0.0) || !std::isfinite(dt_)) {
    std::ostringstream s;
    s << "time step " << dt_ << " s is not a positive number; set it > 0 or leave it 0 for the paper's Eq. 2 default";
    throw InputError("/time/dt", s.str());
  }
  if (dt_ > crit) {
    std::ostringstream s;
    s.precision(4);
    s << "time step " << dt_ << " s exceeds the stable limit " << crit
      << " s of the stiffest spring (contact, bond normal/shear/bending/twist, damping included); "
      << "use dt <= " << crit << " s, e.g. the paper's Eq. 2 with alpha = 0.1 gives " << eq2_time_step()
      << " s (set /time/dt to 0 to use it)";
    throw InputError("/time/dt", s.str());
  }
}

double Engine::skin() const {
  if (def_.skin > 0.0) return def_.skin;
  // The smallest particle ever added (every rank added the same ones before distribute()).
  return std::isfinite(min_radius_) ? 0.2 * min_radius_ : 0.0;
}

// ---------------------------------------------------------------- neighbours

// A counting sort on the lower index, then each lower index's few bonds by the higher (insertion
// sort). The bonds are then moved in place: after a rebuild most are where they were.
void sort_bonds_by_particle(std::vector<Bond>& bonds, std::size_t n_particles, BondSortScratch& s) {
  const std::size_t nb = bonds.size();
  s.start.assign(n_particles + 1, 0);
  s.order.resize(nb);
  s.hi.resize(nb);
  for (const Bond& b : bonds) {
    assert(std::max(b.i, b.j) < n_particles);
    ++s.start[std::min(b.i, b.j) + 1];
  }
  for (std::size_t p = 0; p < n_particles; ++p) s.start[p + 1] += s.start[p];
  s.fill.assign(s.start.begin(), s.start.end() - 1);
  for (std::uint32_t k = 0; k < nb; ++k) {
    const Bond& b = bonds[k];
    const std::uint32_t lo = std::min(b.i, b.j), h = std::max(b.i, b.j);
    std::uint32_t at = s.fill[lo]++;
    for (; at > s.start[lo] && s.hi[at - 1] > h; --at) {
      s.order[at] = s.order[at - 1];
      s.hi[at] = s.hi[at - 1];
    }
    s.order[at] = k;
    s.hi[at] = h;
  }
  permute_in_place(bonds, s.order, s.done);
}

void Engine::sort_spatially(const std::vector<std::uint32_t>& cell_of, std::uint32_t ncells) {
  const std::size_t n = ps_.owned();
  std::vector<std::uint32_t> count(ncells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++count[cell_of[i] + 1];
  for (std::uint32_t c = 0; c < ncells; ++c) count[c + 1] += count[c];
  std::vector<std::uint32_t> order(n), new_of_old(ps_.size());
  for (std::size_t g = n; g < ps_.size(); ++g) new_of_old[g] = static_cast<std::uint32_t>(g);  // ghosts stay
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t k = count[cell_of[i]]++;
    order[k] = static_cast<std::uint32_t>(i);
    new_of_old[i] = k;
  }
  bool identity = true;
  for (std::size_t k = 0; k < n && identity; ++k) identity = order[k] == k;
  if (identity) return;
  ps_.permute(order);
  for (auto& b : bonds_) {
    b.i = new_of_old[b.i];
    b.j = new_of_old[b.j];
  }
  sort_bonds_by_particle(bonds_, ps_.size(), bond_sort_scratch_);
  for (auto& p : pairs_) {
    p.i = new_of_old[p.i];
    p.j = new_of_old[p.j];
  }
  std::vector<char> done;
  for (auto& h : wall_hist_) permute_in_place(h, order, done);
  for (auto& list : ghost_send_)
    for (auto& i : list) i = new_of_old[i];
}

void Engine::build_neighbors() {
  build_pair_list();
  if (!carried_exposure_.empty()) {
    // The rebuild of a restart at another rank count (load_state_union, at the positions of the
    // run's last rebuild) is not one of the run's own: the exposure stays as of that rebuild.
    exposure_.resize(ps_.n_owned);
    for (std::size_t i = 0; i < ps_.n_owned; ++i) exposure_[i] = carried_exposure_.at(ps_.gid[i]);
    carried_exposure_.clear();
    return;
  }
  update_exposure();  // collective under MPI, like the rebuild itself
}

void Engine::update_exposure() {
  // Per particle: sum of the unit directions to its bonded neighbours in its body frame (each
  // component rounded, water.h), the largest component per axis and sign, and the bond count; both
  // ends of every bond, ghost ends sent home under MPI (exposure_ghosts_home).
  const std::size_t n = ps_.size();
  exposure_sum_.assign(n, Vec3::Zero());
  exposure_reach_pos_.assign(n, Vec3::Zero());
  exposure_reach_neg_.assign(n, Vec3::Zero());
  exposure_count_.assign(n, 0u);
  if (def_.water.enabled) {
    auto add = [&](std::uint32_t k, const Vec3& d) {
      const Vec3 b = ps_.q[k].conjugate() * d;
      const Vec3 bq(exposure_quantize(b.x()), exposure_quantize(b.y()), exposure_quantize(b.z()));
      exposure_sum_[k] += bq;
      exposure_reach_pos_[k] = exposure_reach_pos_[k].cwiseMax(bq);
      exposure_reach_neg_[k] = exposure_reach_neg_[k].cwiseMax(-bq);
      ++exposure_count_[k];
    };
    for (const Bond& b : bonds_) {
      const Vec3 d = ps_.x[b.j] - ps_.x[b.i];
      const double L = d.norm();
      if (!(L > 0.0)) continue;
      add(b.i, d / L);
      add(b.j, -d / L);
    }
    if (parallel()) exposure_ghosts_home();
  }
  const std::size_t no = ps_.owned();
  exposure_.resize(no);
  for (std::size_t i = 0; i < no; ++i)
    exposure_[i] = exposure_from_bonds(exposure_sum_[i], exposure_reach_pos_[i], exposure_reach_neg_[i], exposure_count_[i],
                                       ps_.radius[i],
                                       ps_.buoyant_volume[i]);
}

void Engine::build_partner_csr(std::size_t n) {
  // Bond partners (CSR), to keep bonded pairs out of the contact list; crushed pairs too
  // (crushed_forces computes them), where both particles are here.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> crushed_local;
  for (const auto& [k, c] : crushed_) {
    const std::uint32_t a = ps_.local(k.a), b = ps_.local(k.b);
    if (a != ParticleStore::kNone && b != ParticleStore::kNone) crushed_local.emplace_back(a, b);
  }
  partner_start_.assign(n + 1, 0);
  for (const auto& b : bonds_) {
    ++partner_start_[b.i + 1];
    ++partner_start_[b.j + 1];
  }
  for (const auto& [a, b] : crushed_local) {
    ++partner_start_[a + 1];
    ++partner_start_[b + 1];
  }
  for (std::size_t i = 0; i < n; ++i) partner_start_[i + 1] += partner_start_[i];
  partner_list_.resize(partner_start_[n]);
  {
    std::vector<std::uint32_t> fill(partner_start_.begin(), partner_start_.end() - 1);
    for (const auto& b : bonds_) {
      partner_list_[fill[b.i]++] = b.j;
      partner_list_[fill[b.j]++] = b.i;
    }
    for (const auto& [a, b] : crushed_local) {
      partner_list_[fill[a]++] = b;
      partner_list_[fill[b]++] = a;
    }
  }
}

std::unordered_map<GidPair, Vec3, GidPairHash> Engine::take_contact_history() {
  // Contact history survives the rebuild, keyed by global ids. xi is the tangential
  // displacement of j relative to i, so it is stored oriented from the lower to the
  // higher global id and flipped back if the new list orders the pair the other way.
  // (Under MPI, exchange_full() has already moved it into carried_history_.)
  std::unordered_map<GidPair, Vec3, GidPairHash> history = std::move(carried_history_);
  carried_history_.clear();
  for (const auto& p : pairs_)
    if (p.xi.squaredNorm() > 0.0)
      history.emplace(GidPair::of(ps_.gid[p.i], ps_.gid[p.j]), ps_.gid[p.i] < ps_.gid[p.j] ? p.xi : Vec3(-p.xi));
  return history;
}

namespace {

// A pair list's non-zero springs by local index, for the next list on the same store: a CSR on
// each pair's lower index, the spring oriented from the lower index to the higher.
class SpringsByIndex {
 public:
  SpringsByIndex() = default;
  SpringsByIndex(const std::vector<ContactPair>& pairs, std::size_t n) : start_(n + 1, 0) {
    for (const auto& p : pairs)
      if (p.xi.squaredNorm() > 0.0) ++start_[std::min(p.i, p.j) + 1];
    for (std::size_t i = 0; i < n; ++i) start_[i + 1] += start_[i];
    items_.resize(start_[n]);
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (const auto& p : pairs)
      if (p.xi.squaredNorm() > 0.0)
        items_[fill[std::min(p.i, p.j)]++] = p.i < p.j ? std::make_pair(p.j, p.xi) : std::make_pair(p.i, Vec3(-p.xi));
  }
  bool empty() const { return items_.empty(); }
  /// The spring of pair (i, j), i < j, oriented from i to j; zero if it had none.
  Vec3 of(std::uint32_t i, std::uint32_t j) const {
    for (std::uint32_t k = start_[i]; k < start_[i + 1]; ++k)
      if (items_[k].first == j) return items_[k].second;
    return Vec3::Zero();
  }

 private:
  std::vector<std::uint32_t> start_;
  std::vector<std::pair<std::uint32_t, Vec3>> items_;
};

}  // namespace

void Engine::build_pair_list() {
  const std::size_t n = ps_.size();
  ++stats_.neighbor_rebuilds;
  need_rebuild_ = false;
  bond_batch_.invalidate();  // bonds may have been reordered, added or moved to other ranks
  if (n == 0) {
    pairs_.clear();
    return;
  }
  const double sk = skin();
  double rmax = 0.0;
  Vec3 lo = ps_.x[0], hi = lo;
  for (std::size_t i = 0; i < n; ++i) {
    rmax = std::max(rmax, ps_.radius[i]);
    lo = lo.cwiseMin(ps_.x[i]);
    hi = hi.cwiseMax(ps_.x[i]);
  }
  double h = 2.0 * rmax + sk;
  // Keep the grid no larger than ~2 cells per particle even if particles fly apart.
  const Vec3 ext = (hi - lo).cwiseMax(Vec3::Constant(1e-12));
  while ((std::floor(ext.x() / h) + 1) * (std::floor(ext.y() / h) + 1) * (std::floor(ext.z() / h) + 1) >
         2.0 * static_cast<double>(n) + 27.0)
    h *= 1.26;
  const int nx = static_cast<int>(ext.x() / h) + 1, ny = static_cast<int>(ext.y() / h) + 1,
            nz = static_cast<int>(ext.z() / h) + 1;
  const std::uint32_t ncells = static_cast<std::uint32_t>(nx) * ny * nz;
  auto cell_coords = [&](const Vec3& x, int& cx, int& cy, int& cz) {
    cx = std::min(nx - 1, static_cast<int>((x.x() - lo.x()) / h));
    cy = std::min(ny - 1, static_cast<int>((x.y() - lo.y()) / h));
    cz = std::min(nz - 1, static_cast<int>((x.z() - lo.z()) / h));
  };
  cell_of_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    int cx, cy, cz;
    cell_coords(ps_.x[i], cx, cy, cz);
    cell_of_[i] = (static_cast<std::uint32_t>(cz) * ny + cy) * nx + cx;
  }
  if (def_.spatial_sort) {  // owned particles only; ghosts keep their place
    sort_spatially(cell_of_, ncells);
    for (std::size_t i = 0; i < n; ++i) {
      int cx, cy, cz;
      cell_coords(ps_.x[i], cx, cy, cz);
      cell_of_[i] = (static_cast<std::uint32_t>(cz) * ny + cy) * nx + cx;
    }
  }
  // Counting sort of particle indices by cell.
  cell_start_.assign(ncells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++cell_start_[cell_of_[i] + 1];
  for (std::uint32_t c = 0; c < ncells; ++c) cell_start_[c + 1] += cell_start_[c];
  cell_items_.resize(n);
  {
    std::vector<std::uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
    for (std::size_t i = 0; i < n; ++i) cell_items_[fill[cell_of_[i]]++] = static_cast<std::uint32_t>(i);
  }
  build_partner_csr(n);
  // Springs carried into the new list. On one rank with nothing carried by global id (a restart,
  // set_contact_history), the old list's local indices are still this store's (sort_spatially
  // renumbered them), so the springs are looked up by index: a CSR on the lower index, each spring
  // oriented from the lower index to the higher. Otherwise by global id (take_contact_history).
  // Both give every pair the same spring.
  const bool by_index = !parallel() && carried_history_.empty();
  std::unordered_map<GidPair, Vec3, GidPairHash> history;
  SpringsByIndex old_springs;
  if (by_index)
    old_springs = SpringsByIndex(pairs_, n);
  else
    history = take_contact_history();
  const std::uint32_t n_owned = static_cast<std::uint32_t>(ps_.n_owned);

  pairs_.clear();
  pair_smeff_.clear();  // (made again by the pair kernel)
  // Sorted by cell with no ghosts, a cell before i's (in cell order) holds only particles before
  // i, which j > i excludes: those cells are not visited (the same list, in the same order).
  const bool cell_ordered = def_.spatial_sort && n == ps_.n_owned;
  for (std::uint32_t i = 0; i < n; ++i) {
    const Vec3 xi = ps_.x[i];
    const double ri = ps_.radius[i];
    const std::uint32_t c = cell_of_[i];
    const int cx = c % nx, cy = (c / nx) % ny, cz = c / (nx * ny);
    for (int dz = -1; dz <= 1; ++dz) {
      const int z = cz + dz;
      if (z < 0 || z >= nz) continue;
      for (int dy = -1; dy <= 1; ++dy) {
        const int y = cy + dy;
        if (y < 0 || y >= ny) continue;
        for (int dx = -1; dx <= 1; ++dx) {
          const int x = cx + dx;
          if (x < 0 || x >= nx) continue;
          const std::uint32_t cc = (static_cast<std::uint32_t>(z) * ny + y) * nx + x;
          if (cell_ordered && cc < c) continue;
          for (std::uint32_t k = cell_start_[cc]; k < cell_start_[cc + 1]; ++k) {
            const std::uint32_t j = cell_items_[k];
            if (j <= i) continue;
            // An owned-ghost pair is computed by the rank owning its lower global id (once,
            // globally); ghost-ghost pairs belong to other ranks.
            if (j >= n_owned && (i >= n_owned || ps_.gid[i] > ps_.gid[j])) continue;
            const double lim = ri + ps_.radius[j] + sk;
            if ((ps_.x[j] - xi).squaredNorm() > lim * lim) continue;
            bool bonded = false;
            for (std::uint32_t b = partner_start_[i]; b < partner_start_[i + 1]; ++b)
              if (partner_list_[b] == j) { bonded = true; break; }
            if (bonded) continue;
            pairs_.push_back({i, j, Vec3::Zero()});
          }
        }
      }
    }
  }
  if (!old_springs.empty())
    for (auto& p : pairs_) p.xi = old_springs.of(p.i, p.j);  // (i < j in the new list)
  if (!history.empty())
    for (auto& p : pairs_) {
      auto it = history.find(GidPair::of(ps_.gid[p.i], ps_.gid[p.j]));
      if (it != history.end()) p.xi = ps_.gid[p.i] < ps_.gid[p.j] ? it->second : Vec3(-it->second);
    }
  x_at_build_.assign(ps_.x.begin(), ps_.x.end());
  max_disp2_ = 0.0;
}

// ---------------------------------------------------------------- forces

void Engine::field_forces() {
  const std::size_t n = ps_.owned();
  const Vec3 g = def_.gravity;
  const double gmag = g.norm();
  const bool water = def_.water.enabled;
  // The owned particles' gravity and zero torques may already be in place: step() sets them in
  // its first loop, right after the kick has used the last step's forces (one pass over the
  // store fewer), unless a neighbour rebuild (reorder, migration) came in between.
  if (fields_preset_ != stats_.neighbor_rebuilds || n != fields_preset_n_)
    for (std::size_t i = 0; i < n; ++i) {
      ps_.f[i] = ps_.mass[i] * g;
      ps_.torque[i].setZero();
    }
  fields_preset_ = ~std::uint64_t{0};
  for (std::size_t i = n; i < ps_.size(); ++i) {
    ps_.f[i].setZero();
    ps_.torque[i].setZero();
  }
  if (water) {
    if (exposure_.size() != n)
      throw std::logic_error("water: particle exposure not updated since particles were added (Engine::rebuild)");
    for (std::size_t i = 0; i < n; ++i)
      ps_.f[i] += water_force(def_.water, gmag, ps_.x[i], ps_.v[i], ps_.radius[i], ps_.buoyant_volume[i], ps_.q[i],
                              exposure_[i]);
  }
}

ContactResult Engine::wall_contact(double delta, double r, const Vec3& n, double vn, const Vec3& vt,
                                   double m, double friction, Vec3& xi) const {
  // A wall is a sphere of infinite radius and mass: R* = r, m_eff = m.
  return with_contact_law(def_, [&](const auto& law) {
    return law.with_friction(friction).force(delta, r, n, vn, vt, m, history_dt_, xi);
  });
}

void Engine::wall_forces() {
  // Only the particles that can touch a wall are tested (refresh_wall_candidates); for the
  // others the loop below would find dist >= r and keep their springs at zero.
  refresh_wall_candidates();
  if (wall_kernel()) return;  // the built-in laws (contact_kernel.cpp)
  // A law without a wall kernel (none of the built-in ones; kept for a new law, as pair_forces is):
  // the scalar law per candidate.
  for (std::size_t k = 0; k < walls_.size(); ++k) {
    const PlaneWall& w = walls_[k];
    Vec3 total = Vec3::Zero();
    auto& hist = wall_hist_[k];
    for (const std::uint32_t i : wall_cand_[k]) {
      const double r = ps_.radius[i];
      const double dist = (ps_.x[i] - w.point).dot(w.normal);
      if (dist >= r) {
        hist[i].setZero();
        continue;
      }
      if (ps_.inv_mass[i] == 0.0) continue;
      const double delta = r - dist;
      const Vec3 a = -(r - 0.5 * delta) * w.normal;
      const Vec3 vrel = ps_.v[i] + ps_.omega[i].cross(a) - w.velocity;
      const double vn = vrel.dot(w.normal);
      const Vec3 vt = vrel - vn * w.normal;
      const double m = ps_.mass[i];
      const ContactResult res = wall_contact(delta, r, w.normal, vn, vt, m, w.friction, hist[i]);
      ps_.f[i] += res.force;
      ps_.torque[i] += a.cross(res.force);
      total -= res.force;
      if (delta / r > worst_overlap_ratio_) {
        worst_overlap_ratio_ = delta / r;
        worst_overlap_i_ = static_cast<std::uint32_t>(i);
        worst_overlap_j_ = ParticleStore::kNone - 1 - static_cast<std::uint32_t>(k);  // plane wall k
      }
    }
    wall_force_[k] = total;
  }
}

void Engine::mesh_forces() {
  const std::size_t n = ps_.owned();
  double rmax = 0.0;
  for (std::size_t i = 0; i < n; ++i) rmax = std::max(rmax, ps_.radius[i]);
  for (auto& m : meshes_) {
    MeshWallLoad& load = m.load;
    load.force.setZero();
    load.moment.setZero();
    for (auto& v : load.part_force) v.setZero();
    for (auto& v : load.part_moment) v.setZero();
    load.contacts = 0;
    if (walls_parked_) continue;  // a parked structure exerts nothing (set_walls_parked)
    m.next_history.clear();
    const Vec3 lo = m.grid->bounds().lo + m.position - Vec3::Constant(rmax);
    const Vec3 hi = m.grid->bounds().hi + m.position + Vec3::Constant(rmax);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3& x = ps_.x[i];
      if ((x.array() < lo.array()).any() || (x.array() > hi.array()).any()) continue;
      if (ps_.inv_mass[i] == 0.0) continue;
      const double r = ps_.radius[i];
      if (m.grid->query(x - m.position, r, mesh_contacts_, mesh_scratch_) == 0) continue;
      for (const auto& c : mesh_contacts_) {
        const double delta = c.overlap;
        const Vec3& nrm = c.normal;
        const Vec3 a = -(r - 0.5 * delta) * nrm;
        const Vec3 vrel = ps_.v[i] + ps_.omega[i].cross(a) - m.def.velocity;
        const double vn = vrel.dot(nrm);
        const Vec3 vt = vrel - vn * nrm;
        const MeshWall::Key key{ps_.gid[i], (static_cast<std::uint64_t>(c.feature) << 32) | c.feature_id};
        auto it = m.history.find(key);
        Vec3 xi = it == m.history.end() ? Vec3::Zero() : it->second;
        const ContactResult res = wall_contact(delta, r, nrm, vn, vt, ps_.mass[i], m.def.friction, xi);
        m.next_history.emplace(key, xi);
        ps_.f[i] += res.force;
        ps_.torque[i] += a.cross(res.force);
        const Vec3 arm = x + a - m.position;  // contact point about the mesh origin
        const std::size_t part = c.part < load.part_force.size() ? c.part : 0;
        load.part_force[part] -= res.force;
        load.part_moment[part] -= arm.cross(res.force);
        ++load.contacts;
        if (delta / r > worst_overlap_ratio_) {
          worst_overlap_ratio_ = delta / r;
          worst_overlap_i_ = static_cast<std::uint32_t>(i);
          worst_overlap_j_ = ParticleStore::kNone;
        }
      }
    }
    for (std::size_t k = 0; k < load.part_force.size(); ++k) {
      load.force += load.part_force[k];
      load.moment += load.part_moment[k];
    }
    m.history.swap(m.next_history);
  }
}

void Engine::source_forces() {
  const ForceSourceContext ctx{def_, history_dt_, time_};
  for (std::size_t k = 0; k < sources_.size(); ++k) {
    const ForceSourceResult r = sources_[k]->add_forces(ps_, ps_.owned(), ctx);
    if (r.worst_overlap_ratio > worst_overlap_ratio_) {
      worst_overlap_ratio_ = r.worst_overlap_ratio;
      worst_overlap_i_ = r.worst_particle;
      worst_overlap_source_ = static_cast<int>(k);
    }
  }
}

template <class Law>
void Engine::pair_forces(const Law& law) {
  Vec3* __restrict f = ps_.f.data();
  Vec3* __restrict t = ps_.torque.data();
  const Vec3* x = ps_.x.data();
  const Vec3* v = ps_.v.data();
  const Vec3* w = ps_.omega.data();
  const double* r = ps_.radius.data();
  const double* im = ps_.inv_mass.data();
  const double dt = history_dt_;
  double worst = 0.0;
  std::uint32_t wi = 0, wj = 0;
  for (auto& p : pairs_) {
    const std::uint32_t i = p.i, j = p.j;
    const Vec3 d = x[j] - x[i];
    const double rs = r[i] + r[j];
    const double d2 = d.squaredNorm();
    if (d2 >= rs * rs) {
      p.xi.setZero();
      continue;
    }
    const double inv_sum = im[i] + im[j];
    if (inv_sum == 0.0) continue;
    const double dist = std::sqrt(d2);
    const Vec3 n = d / dist;
    const double delta = rs - dist;
    const Vec3 ai = (r[i] - 0.5 * delta) * n;
    const Vec3 aj = -(r[j] - 0.5 * delta) * n;
    const Vec3 vrel = v[j] + w[j].cross(aj) - v[i] - w[i].cross(ai);
    const double vn = vrel.dot(n);
    const Vec3 vt = vrel - vn * n;
    const double rstar = r[i] * r[j] / rs;
    const ContactResult res = law.force(delta, rstar, n, vn, vt, 1.0 / inv_sum, dt, p.xi);
    f[j] += res.force;
    f[i] -= res.force;
    t[i] -= ai.cross(res.force);
    t[j] += aj.cross(res.force);
    const double ratio = delta / std::min(r[i], r[j]);
    if (ratio > worst) {
      worst = ratio;
      wi = i;
      wj = j;
    }
  }
  if (worst > worst_overlap_ratio_) {
    worst_overlap_ratio_ = worst;
    worst_overlap_i_ = wi;
    worst_overlap_j_ = wj;
    worst_overlap_source_ = -1;
  }
}

void Engine::bond_forces() {
  std::erase_if(squeezed_breaks_, [&](const SqueezedBreak& q) { return q.step + 1 < step_; });
  if (bonds_.empty()) return;
  if (!bond_batch_.valid_for(bonds_.size())) bond_batch_.pack(bonds_);
  broken_bonds_.clear();
  const BondKernelIo io{ps_.x.data(), ps_.q.data(), ps_.v.data(), ps_.omega.data(), ps_.f.data(), ps_.torque.data()};
  if (bonds_unbreakable_[0] || bonds_unbreakable_[1]) {  // a set-up stage: strengths taken as infinite
    ParallelBondParams held[2] = {def_.bond[0], def_.bond[1]};
    for (int k = 0; k < 2; ++k)
      if (bonds_unbreakable_[k]) held[k].sigma_c = held[k].tau_c = held[k].sigma_cc = INFINITY;
    bond_kernel(bond_batch_, held, 2, io, broken_bonds_);
  } else {
    bond_kernel(bond_batch_, def_.bond, 2, io, broken_bonds_);
  }
  const std::size_t n_broken = broken_bonds_.size();
  for (const BrokenBond& bb : broken_bonds_) {
    // Broken: its force is removed from this step on. Mark via an impossible kind.
    Bond& b = bonds_[bb.index];
    const double rs = ps_.radius[b.i] + ps_.radius[b.j];
    const double rmin = std::min(ps_.radius[b.i], ps_.radius[b.j]);
    const double ratio = (rs - (ps_.x[b.j] - ps_.x[b.i]).norm()) / rmin;
    const double h = def_.crushed_set_depth;
    std::uint8_t mark = 0xff;  // 0xff: broken, its pair joins the contact list; 0xfe: crushed
    if (ratio > h) {
      squeezed_breaks_.push_back({ps_.gid[b.i], ps_.gid[b.j], ratio, ratio * rmin / rs, step_, bb.mode});
      if (def_.crushed_set) {
        crushed_[GidPair::of(ps_.gid[b.i], ps_.gid[b.j])] = {(ratio - h) * rmin, Vec3::Zero()};
        mark = 0xfe;
      }
    }
    b.kind = static_cast<BondKind>(mark);
    ++broken_now_[static_cast<int>(bb.mode) - 1];
  }
  if (n_broken == 0) return;
  // Erase the broken bonds, keeping the others' order (the bonds before the first stay put).
  std::size_t w = broken_bonds_.front().index;
  for (std::size_t r = w; r < bonds_.size(); ++r) {
    const Bond& b = bonds_[r];
    if (static_cast<std::uint8_t>(b.kind) >= 0xfe) {
      --ps_.bond_count[b.i];
      --ps_.bond_count[b.j];
      // Now they interact by contact: in the list, or as a crushed pair (crushed_forces).
      if (static_cast<std::uint8_t>(b.kind) == 0xff) pairs_.push_back({b.i, b.j, Vec3::Zero()});
      continue;
    }
    bonds_[w++] = b;
  }
  bonds_.resize(w);
  bond_batch_.erase(broken_bonds_);  // the same bonds out of the kernel's copy
}

void Engine::rebuild() {
  if (parallel()) exchange_full();
  build_neighbors();
}

void Engine::sync_before_forces() {
  bool need = need_rebuild_ || x_at_build_.size() != ps_.size();
  if (parallel()) need = global_max(need ? 1.0 : 0.0) > 0.0;
  if (need)
    rebuild();
  else if (parallel())
    forward_ghosts();
}

void Engine::evaluate_forces(double history_dt, bool finish) {
  const auto t0 = std::chrono::steady_clock::now();
  history_dt_ = history_dt;
  broken_now_[0] = broken_now_[1] = broken_now_[2] = 0;
  worst_overlap_ratio_ = 0.0;
  worst_overlap_source_ = -1;
  field_forces();
  wall_forces();
  if (!meshes_.empty()) mesh_forces();
  if (!sources_.empty()) source_forces();
  with_contact_law(def_, [&](const auto& law) {
    using L = std::decay_t<decltype(law)>;
    if constexpr (std::is_same_v<L, LinearLaw> || std::is_same_v<L, HertzLaw>)
      pair_kernel(law);  // contact_kernel.cpp
    else
      pair_forces(law);  // a law without a vectorised kernel
  });
  bond_forces();
  if (!crushed_.empty()) crushed_forces();  // engine_crushed.cpp
  const double dt_force = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  pstats_.force_seconds += dt_force;
  force_seconds_since_balance_ += dt_force;
  if (parallel()) reverse_ghost_forces();
  if (finish) finish_forces(false);
  forces_valid_ = true;
}

bool Engine::finish_forces(bool bad_here) {
  // One reduction per step carries the loads, the broken-bond counts and the blow-up flag.
  double bad = bad_here ? 1.0 : 0.0;
  if (parallel()) bad = reduce_loads(bad);
  stats_.bonds_broken_tension += broken_now_[0];
  stats_.bonds_broken_shear += broken_now_[1];
  stats_.bonds_broken_compression += broken_now_[2];
  stats_.bonds_broken += broken_now_[0] + broken_now_[1] + broken_now_[2];
  return bad > 0.0;
}

// ---------------------------------------------------------------- integration

bool Engine::unstable_here(double worst_v2) const {
  return !(worst_v2 <= def_.limits.max_speed * def_.limits.max_speed) ||
         !(worst_overlap_ratio_ <= def_.limits.max_overlap_ratio);
}

void Engine::check_blowup(std::uint32_t worst, double worst_v2, bool unstable_anywhere) const {
  const bool bad_here = unstable_here(worst_v2);
  double crit = 0.0;
  if (parallel()) {
    if (!unstable_anywhere) return;
    crit = critical_time_step();  // collective: every rank, before the ranks part ways
    if (!bad_here) {
      std::ostringstream m;
      m << "simulation became unstable on another rank at step " << step_ << " (t = " << time_
        << " s); that rank's message names the particle. Output written so far is kept.";
      throw SimulationError(m.str());
    }
  } else if (!bad_here) {
    return;
  } else {
    crit = critical_time_step();
  }
  std::ostringstream s;
  s.precision(6);
  bool bad = false;
  const SqueezedBreak* crushed = nullptr;  // the worst pair was a bond broken deep in compression
  bool bad_overlap = false;  // an overlap between two particles (whose stiffness dt_crit covers) stopped the run
  if (!(worst_v2 <= def_.limits.max_speed * def_.limits.max_speed)) {
    bad = true;
    s << "particle " << ps_.gid[worst] << " at (" << ps_.x[worst].transpose() << ") m moves at "
      << std::sqrt(worst_v2) << " m/s, beyond the limit stability.max_speed = " << def_.limits.max_speed
      << " m/s";
  } else if (!(worst_overlap_ratio_ <= def_.limits.max_overlap_ratio)) {
    bad = true;
    s << "contact overlap reached " << worst_overlap_ratio_
      << " of the particle radius (limit stability.max_overlap_ratio = " << def_.limits.max_overlap_ratio
      << ")";
    // How the pair arrived in this step: the mid-step velocities v(n+1/2), which this step's push
    // on the overlap has not yet changed (an owned particle holds v(n+1) here, a ghost v(n+1/2)).
    // Closing fast is an impact, slowly a squeeze; an overlap that parts them was already there.
    const auto mid = [&](std::uint32_t k) {
      return k < ps_.owned() ? Vec3(ps_.v[k] - 0.5 * dt_ * ps_.inv_mass[k] * ps_.f[k]) : ps_.v[k];
    };
    if (worst_overlap_source_ >= 0 && worst_overlap_i_ < ps_.size())
      s << " between particle " << ps_.gid[worst_overlap_i_] << " and "
        << sources_[static_cast<std::size_t>(worst_overlap_source_)]->describe_worst(ps_, worst_overlap_i_,
                                                                                      mid(worst_overlap_i_));
    else if (worst_overlap_i_ < ps_.size() && worst_overlap_j_ < ps_.size()) {
      const std::uint32_t i = worst_overlap_i_, j = worst_overlap_j_;
      s << " between particles " << ps_.gid[i] << " and " << ps_.gid[j];
      crushed = squeezed_break(ps_.gid[i], ps_.gid[j]);
      bad_overlap = true;
      const Vec3 vi = mid(i), vj = mid(j);
      const Vec3 n = (ps_.x[j] - ps_.x[i]).normalized();
      const double closing = -(vj - vi).dot(n);
      s << "; they " << (closing >= 0.0 ? "close" : "part") << " at " << std::abs(closing)
        << " m/s along their line of centres (speeds " << vi.norm() << " and " << vj.norm() << " m/s in this step)";
    }
    else if (worst_overlap_i_ < ps_.size() && worst_overlap_j_ == ParticleStore::kNone)
      s << " between particle " << ps_.gid[worst_overlap_i_] << " and a mesh structure (the particle at ("
        << ps_.x[worst_overlap_i_].transpose() << ") m, moving at " << mid(worst_overlap_i_).norm()
        << " m/s in this step)";
    else if (worst_overlap_i_ < ps_.size())
      s << " between particle " << ps_.gid[worst_overlap_i_] << " and wall '"
        << walls_[ParticleStore::kNone - 1 - worst_overlap_j_].name << "'";
  }
  if (!bad) return;
  std::ostringstream m;
  m.precision(6);
  m << "simulation became unstable at step " << step_ << " (t = " << time_ << " s): " << s.str();
  if (crushed) {
    // Not a time-step problem: a bond carried the pair that deep and its contact took over there.
    m.precision(3);
    m << ". They were bonded until step " << crushed->step << ", when the bond broke in "
      << (crushed->mode == BondFailure::Tension ? "tension" : crushed->mode == BondFailure::Shear ? "shear" : "compression")
      << " with the centres " << crushed->overlap_ratio << " of the radius deep (" << 100.0 * crushed->strain
      << " % closer than touching), so the contact that replaced it started that deep. Not a time-step problem "
         "(a smaller step does not help): the ice there is crushed or rolled past what its bonds represent. "
      << (def_.crushed_set ? ""
                           : "bonds.crushed_contact = \"set\" (the default; this run has \"elastic\") lets the "
                             "contact take over at bonds.crushed_set_depth, the rest of the overlap its permanent set. ")
      << "A compressive strength for the bonds (bonds.compressive_strength_ratio) breaks squeezed bonds sooner, "
         "and stiffer ice (material.youngs_modulus; the step shrinks with it) keeps the strains small; "
         "docs/engine.md, \"Crushed bonds\". Output written so far is kept; this step was not written.";
    throw SimulationError(m.str());
  }
  m << ". Time step dt = " << dt_ << " s, critical dt = " << crit << " s";
  if (bad_overlap && dt_ <= 0.9 * crit) {
    // A stable step: the depth a load or an impact presses a linear contact to does not depend on
    // it (docs/engine.md, "What an overlap report says"), so the advice is about the load.
    m.precision(2);
    m << " (" << dt_ / crit
      << " of it: a stable step, and a smaller one would press the contact about as deep). The load made this "
         "overlap: a squeeze, an impact (falling or thrown ice closes fast), or an initial overlap. Stiffer ice "
         "(material.youngs_modulus; the step shrinks as 1/sqrt(E)) keeps overlaps smaller. If you judge the stop "
         "harmless, continue from the last checkpoint with a larger stability.max_overlap_ratio (--restart with "
         "--set; docs/output.md, \"What a restart may change\"). Output written so far is kept; this step was not "
         "written.";
  } else {
    m << ". Reduce the time step (time.dt_alpha or time.dt), or check stiffness, damping and "
         "initial overlaps. Output written so far is kept; this step was not written.";
  }
  throw SimulationError(m.str());
}

const Engine::SqueezedBreak* Engine::squeezed_break(GlobalId a, GlobalId b) const {
  for (const auto& q : squeezed_breaks_)
    if ((q.gi == a && q.gj == b) || (q.gi == b && q.gj == a)) return &q;
  return nullptr;
}

void Engine::step() {
  if (!forces_valid_) {
    sync_before_forces();
    evaluate_forces(0.0);
  }
  std::size_t n = ps_.owned();
  const double dt = dt_, hdt = 0.5 * dt_;
  // Orientations matter only to bonds. Under MPI a rank may own bonded particles whose bonds
  // live on a neighbour (the owner of the lower id), so there orientations advance whenever any
  // rank has a bond (max_bond_length_ is the global figure of the last exchange).
  bool rotate = !bonds_.empty() || (parallel() && max_bond_length_ > 0.0);
  for (const ForceSource* src : sources_) rotate = rotate || src->uses_orientation();
  Vec3* x = ps_.x.data();
  Vec3* v = ps_.v.data();
  Vec3* w = ps_.omega.data();
  Vec3* fk = ps_.f.data();
  Vec3* tk = ps_.torque.data();
  const double* im = ps_.inv_mass.data();
  const double* ii = ps_.inv_inertia.data();
  const double* mass = ps_.mass.data();
  const Vec3 g = def_.gravity;
  // this step's forces start from gravity here (field_forces); integrate_kernel.cpp
  const double disp2 = kick_drift(n, dt, hdt, x, v, w, fk, tk, im, ii, mass, x_at_build_.data(), g);
  fields_preset_ = stats_.neighbor_rebuilds;
  fields_preset_n_ = n;
  if (rotate) rotate_orientations(n, ps_.q.data(), w, dt);
  if (!walls_parked_) {
    for (auto& wall : walls_) wall.point += dt * wall.velocity;
    for (auto& m : meshes_) m.position += dt * m.def.velocity;
  }
  time_ += dt;
  ++step_;
  const double half_skin = 0.5 * skin();
  bool rebuild_now = need_rebuild_ || disp2 > half_skin * half_skin;
  if (parallel()) rebuild_now = global_max(rebuild_now ? 1.0 : 0.0) > 0.0;
  if (rebuild_now)
    rebuild();
  else if (parallel())
    forward_ghosts();
  evaluate_forces(dt, false);
  // The rebuild may have reordered the store (and, under MPI, changed who is owned): take every
  // array and the owned count afresh.
  n = ps_.owned();
  v = ps_.v.data();
  w = ps_.omega.data();
  const Vec3* f = ps_.f.data();
  const Vec3* t = ps_.torque.data();
  im = ps_.inv_mass.data();
  ii = ps_.inv_inertia.data();
  double worst_v2 = kick(n, hdt, v, w, f, t, im, ii);
  std::uint32_t worst = 0;
  if (!(worst_v2 <= def_.limits.max_speed * def_.limits.max_speed)) {
    // Too fast somewhere (or NaN): which particle, for the message (the first NaN, or the fastest)
    worst_v2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double v2 = v[i].squaredNorm();
      if (!(v2 <= worst_v2)) {  // also catches NaN
        worst_v2 = v2;
        worst = static_cast<std::uint32_t>(i);
        if (std::isnan(v2)) break;
      }
    }
  }
  check_blowup(worst, worst_v2, finish_forces(unstable_here(worst_v2)));
  if (on_step) on_step(*this);
}

void Engine::run(std::uint64_t steps) {
  for (std::uint64_t s = 0; s < steps; ++s) step();
}

// ---------------------------------------------------------------- diagnostics

std::size_t Engine::bond_count(BondKind kind) const {
  return static_cast<std::size_t>(std::count_if(bonds_.begin(), bonds_.end(), [&](const Bond& b) { return b.kind == kind; }));
}

std::size_t Engine::overloaded_bond_count(BondKind kind) const {
  const ParallelBondParams& p = def_.bond[static_cast<int>(kind)];
  std::size_t n = 0;
  for (const auto& b : bonds_) {
    if (b.kind != kind) continue;
    const BondKinematics k{ps_.x[b.i], ps_.x[b.j], ps_.q[b.i], ps_.q[b.j], ps_.v[b.i], ps_.v[b.j], ps_.omega[b.i], ps_.omega[b.j]};
    const BondResult r = parallel_bond(p, b.ref, k);
    n += bond_failure(p, r.sigma, r.tau, r.crush, b.strength) != BondFailure::None;
  }
  return n;
}

EnergyReport Engine::energy() const {
  EnergyReport e;
  const double gmag = def_.gravity.norm();
  for (std::size_t i = 0; i < ps_.owned(); ++i) {
    if (ps_.inv_mass[i] == 0.0) continue;
    e.kinetic_translational += 0.5 * ps_.mass[i] * ps_.v[i].squaredNorm();
    e.kinetic_rotational += 0.5 / ps_.inv_inertia[i] * ps_.omega[i].squaredNorm();
    e.gravity_potential -= ps_.mass[i] * def_.gravity.dot(ps_.x[i]);
    if (def_.water.enabled)
      e.buoyancy_potential += buoyancy_potential(def_.water, gmag, ps_.x[i].z(), ps_.radius[i], ps_.buoyant_volume[i]);
  }
  for (const auto& b : bonds_) {
    const BondKinematics k{ps_.x[b.i], ps_.x[b.j], ps_.q[b.i], ps_.q[b.j], ps_.v[b.i], ps_.v[b.j], ps_.omega[b.i], ps_.omega[b.j]};
    e.bond_elastic += parallel_bond(def_.bond[static_cast<int>(b.kind)], b.ref, k).energy;
  }
  for (const auto& p : pairs_) {
    const double rs = ps_.radius[p.i] + ps_.radius[p.j];
    const double dist = (ps_.x[p.j] - ps_.x[p.i]).norm();
    if (dist >= rs) continue;
    const double rstar = ps_.radius[p.i] * ps_.radius[p.j] / rs;
    e.contact_elastic +=
        with_contact_law(def_, [&](const auto& law) { return law.energy(rs - dist, rstar, p.xi); });
  }
  if (!crushed_.empty()) e.contact_elastic += crushed_energy();
  if (parallel()) {  // every bond and contact pair lives on exactly one rank
    double v[6] = {e.kinetic_translational, e.kinetic_rotational, e.gravity_potential,
                   e.buoyancy_potential, e.bond_elastic, e.contact_elastic};
    comm_->sum(v, 6);
    e = {v[0], v[1], v[2], v[3], v[4], v[5]};
  }
  return e;
}

Vec3 Engine::linear_momentum() const {
  Vec3 p = Vec3::Zero();
  for (std::size_t i = 0; i < ps_.owned(); ++i)
    if (ps_.inv_mass[i] > 0.0) p += ps_.mass[i] * ps_.v[i];
  if (parallel()) comm_->sum(p.data(), 3);
  return p;
}

Vec3 Engine::angular_momentum(const Vec3& about) const {
  Vec3 l = Vec3::Zero();
  for (std::size_t i = 0; i < ps_.owned(); ++i) {
    if (ps_.inv_mass[i] == 0.0) continue;
    l += (ps_.x[i] - about).cross(ps_.mass[i] * ps_.v[i]) + ps_.omega[i] / ps_.inv_inertia[i];
  }
  if (parallel()) comm_->sum(l.data(), 3);
  return l;
}

}  // namespace hs::bonded
