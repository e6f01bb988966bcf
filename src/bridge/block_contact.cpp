#include "block_contact.h"

#include "common/error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace hs::bridge {

namespace {

/// Closest-feature geometry of a sphere centre against a box (see the header).
struct BoxContact {
  double delta;  ///< overlap, m (> 0 in contact)
  Vec3 n;        ///< unit normal, world, from the box to the sphere
};

/// l: sphere centre in the block frame; h: half extents; R: body -> world. Returns false when the
/// sphere (radius r) cannot touch the box.
inline bool box_contact(const Vec3& l, const Vec3& h, const Mat3& R, double r, BoxContact& out) {
  const Vec3 q = l.cwiseMax(-h).cwiseMin(h);
  const Vec3 d = l - q;
  const double d2 = d.squaredNorm();
  if (d2 > 0.0) {  // outside: face, edge or corner
    if (d2 >= r * r) return false;
    const double dist = std::sqrt(d2);
    out.delta = r - dist;
    out.n = R * (d / dist);
    return true;
  }
  // Centre inside (or on) the box: out through the nearest face.
  int k = 0;
  double depth = h.x() - std::abs(l.x());
  for (int a = 1; a < 3; ++a) {
    const double da = h[a] - std::abs(l[a]);
    if (da < depth) {
      depth = da;
      k = a;
    }
  }
  out.delta = r + depth;
  out.n = (l[k] < 0.0 ? -1.0 : 1.0) * R.col(k);
  return true;
}

}  // namespace

std::size_t BlockContact::add_block(const ContactBlock& b) {
  auto bad = [](const std::string& what) { throw InputError("block", what); };
  for (int a = 0; a < 3; ++a)
    if (!(b.half_extents[a] > 0.0) || !std::isfinite(b.half_extents[a]))
      bad("half extents must be positive and finite");
  if (!(b.mass > 0.0)) bad("mass must be > 0 kg (INFINITY for an immovable block)");
  if (!(b.friction >= 0.0) || !std::isfinite(b.friction)) bad("friction must be a finite number >= 0");
  if (!(b.orientation.squaredNorm() > 0.0)) bad("orientation quaternion must be non-zero");
  for (const auto& o : blocks_)
    if (o.id == b.id) {
      std::ostringstream s;
      s << "duplicate block id " << b.id;
      bad(s.str());
    }
  blocks_.push_back(b);
  blocks_.back().orientation.normalize();
  loads_.emplace_back();
  return blocks_.size() - 1;
}

void BlockContact::remove_block(std::size_t k) {
  blocks_.erase(blocks_.begin() + static_cast<std::ptrdiff_t>(k));
  loads_.erase(loads_.begin() + static_cast<std::ptrdiff_t>(k));
  if (k < rot_.size()) rot_.erase(rot_.begin() + static_cast<std::ptrdiff_t>(k));
  if (k < ext_.size()) ext_.erase(ext_.begin() + static_cast<std::ptrdiff_t>(k));
  if (k < dirty_.size()) dirty_.erase(dirty_.begin() + static_cast<std::ptrdiff_t>(k));
}

void BlockContact::clear() {
  blocks_.clear();
  loads_.clear();
  rot_.clear();
  ext_.clear();
  dirty_.clear();
  history_.clear();
  next_history_.clear();
}

void BlockContact::set_state(std::size_t k, const Vec3& position, const Quat& orientation,
                             const Vec3& velocity, const Vec3& angular_velocity) {
  ContactBlock& b = blocks_[k];
  b.position = position;
  b.orientation = orientation.normalized();
  b.velocity = velocity;
  b.angular_velocity = angular_velocity;
  if (k < dirty_.size()) dirty_[k] = 1;
}

void BlockContact::clear_impulses() {
  for (auto& l : loads_) {
    l.impulse.setZero();
    l.angular_impulse.setZero();
  }
}

void BlockContact::build_grid(double r_max, std::size_t n_particles, const Vec3& plo, const Vec3& phi) {
  const std::size_t nall = blocks_.size();
  rot_.resize(nall);
  ext_.resize(nall);
  dirty_.resize(nall, 1);
  // Only blocks that reach the particles can touch one; a particle is tested against the blocks of
  // its cell in increasing k either way, so leaving the others out changes no force.
  near_.clear();
  std::vector<Vec3> lo, hi;
  Vec3 glo = Vec3::Constant(INFINITY), ghi = Vec3::Constant(-INFINITY);
  double mean_size = 0.0;
  for (std::size_t k = 0; k < nall; ++k) {
    const ContactBlock& b = blocks_[k];
    if (dirty_[k]) {
      rot_[k] = b.orientation.toRotationMatrix();
      ext_[k] = rot_[k].cwiseAbs() * b.half_extents;  // world AABB half sizes: |R| h
      dirty_[k] = 0;
    }
    const Vec3 e = ext_[k] + Vec3::Constant(r_max);  // grown by the largest radius
    const Vec3 l = b.position - e, u = b.position + e;
    if ((u.array() < plo.array()).any() || (l.array() > phi.array()).any()) continue;
    near_.push_back(static_cast<std::uint32_t>(k));
    lo.push_back(l);
    hi.push_back(u);
    glo = glo.cwiseMin(l);
    ghi = ghi.cwiseMax(u);
    mean_size += 2.0 * e.maxCoeff();
  }
  const std::size_t nb = near_.size();
  if (nb == 0) {
    grid_lo_ = Vec3::Zero();
    nx_ = ny_ = nz_ = 0;
    cell_start_.assign(1, 0);
    cell_blocks_.clear();
    stats_.grid_cells = 0;
    return;
  }
  mean_size /= static_cast<double>(nb);
  // Cells half the mean block size (in the broad-phase test a particle is then tested against 1.7
  // blocks instead of 4.1 with block-sized cells: 46 instead of 72 ns per particle), but no more
  // cells than 4 per block plus 1 per 2 particles however far apart the blocks lie.
  const Vec3 ext = (ghi - glo).cwiseMax(Vec3::Constant(1e-12));
  double h = 0.5 * mean_size;
  while ((std::floor(ext.x() / h) + 1) * (std::floor(ext.y() / h) + 1) * (std::floor(ext.z() / h) + 1) >
         4.0 * static_cast<double>(nb) + 0.5 * static_cast<double>(n_particles) + 27.0)
    h *= 1.26;
  grid_lo_ = glo;
  grid_h_ = h;
  nx_ = static_cast<int>(ext.x() / h) + 1;
  ny_ = static_cast<int>(ext.y() / h) + 1;
  nz_ = static_cast<int>(ext.z() / h) + 1;
  const std::size_t ncells = static_cast<std::size_t>(nx_) * ny_ * nz_;
  auto coord = [&](double x, double o, int n) { return std::clamp(static_cast<int>((x - o) / h), 0, n - 1); };
  // Two passes (count, fill): blocks listed in increasing k in every cell (deterministic order).
  cell_start_.assign(ncells + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::uint32_t> fill;
    if (pass == 1) {
      for (std::size_t c = 0; c < ncells; ++c) cell_start_[c + 1] += cell_start_[c];
      cell_blocks_.resize(cell_start_[ncells]);
      fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    }
    for (std::size_t k = 0; k < nb; ++k) {
      const int x0 = coord(lo[k].x(), glo.x(), nx_), x1 = coord(hi[k].x(), glo.x(), nx_);
      const int y0 = coord(lo[k].y(), glo.y(), ny_), y1 = coord(hi[k].y(), glo.y(), ny_);
      const int z0 = coord(lo[k].z(), glo.z(), nz_), z1 = coord(hi[k].z(), glo.z(), nz_);
      for (int z = z0; z <= z1; ++z)
        for (int y = y0; y <= y1; ++y)
          for (int x = x0; x <= x1; ++x) {
            const std::size_t c = (static_cast<std::size_t>(z) * ny_ + y) * nx_ + x;
            if (pass == 0)
              ++cell_start_[c + 1];
            else
              cell_blocks_[fill[c]++] = near_[k];
          }
    }
  }
  stats_.grid_cells = ncells;
}

bonded::ForceSourceResult BlockContact::add_forces(bonded::ParticleStore& ps, std::size_t n_owned,
                                                   const bonded::ForceSourceContext& ctx) {
  const auto t0 = std::chrono::steady_clock::now();
  bonded::ForceSourceResult res;
  for (auto& l : loads_) {
    l.force.setZero();
    l.torque.setZero();
    l.contacts = 0;
  }
  next_history_.clear();
  next_history_.reserve(history_.size());
  if (record_) recorded_.clear();
  stats_.candidates = 0;
  stats_.tests = 0;
  if (blocks_.empty() || n_owned == 0) {
    history_.clear();
    stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return res;
  }
  double r_max = 0.0;
  Vec3 plo = Vec3::Constant(INFINITY), phi = Vec3::Constant(-INFINITY);
  for (std::size_t i = 0; i < n_owned; ++i) {
    r_max = std::max(r_max, ps.radius[i]);
    plo = plo.cwiseMin(ps.x[i]);
    phi = phi.cwiseMax(ps.x[i]);
  }
  build_grid(r_max, n_owned, plo, phi);

  const bonded::EngineDef& def = ctx.def;
  const double hdt = ctx.history_dt;
  const double h = grid_h_;
  const Vec3 glo = grid_lo_;
  for (std::size_t i = 0; i < n_owned; ++i) {
    if (ps.inv_mass[i] == 0.0) continue;
    const Vec3& x = ps.x[i];
    const Vec3 s = (x - glo) / h;
    if (s.x() < 0.0 || s.y() < 0.0 || s.z() < 0.0) continue;
    const int cx = static_cast<int>(s.x()), cy = static_cast<int>(s.y()), cz = static_cast<int>(s.z());
    if (cx >= nx_ || cy >= ny_ || cz >= nz_) continue;
    const std::size_t c = (static_cast<std::size_t>(cz) * ny_ + cy) * nx_ + cx;
    const double r = ps.radius[i];
    stats_.tests += cell_start_[c + 1] - cell_start_[c];
    for (std::uint32_t e = cell_start_[c]; e < cell_start_[c + 1]; ++e) {
      const std::uint32_t k = cell_blocks_[e];
      const ContactBlock& b = blocks_[k];
      const Mat3& R = rot_[k];
      const Vec3 rel = x - b.position;
      const Vec3 l = R.transpose() * rel;
      if (std::abs(l.x()) >= b.half_extents.x() + r || std::abs(l.y()) >= b.half_extents.y() + r ||
          std::abs(l.z()) >= b.half_extents.z() + r)
        continue;
      ++stats_.candidates;
      BoxContact bc;
      if (!box_contact(l, b.half_extents, R, r, bc)) continue;
      const double delta = bc.delta;
      const Vec3& n = bc.n;
      const Vec3 a = -(r - 0.5 * delta) * n;  // contact point from the sphere centre
      const Vec3 arm = rel + a;                // contact point from the block centre
      const Vec3 vrel = ps.v[i] + ps.omega[i].cross(a) - b.velocity - b.angular_velocity.cross(arm);
      const double vn = vrel.dot(n);
      const Vec3 vt = vrel - vn * n;
      const double m = ps.mass[i];
      const double m_eff = std::isinf(b.mass) ? m : m * b.mass / (m + b.mass);
      const Key key{ps.gid[i], b.id};
      auto it = history_.find(key);
      Vec3 xi = it == history_.end() ? Vec3::Zero() : it->second;
      // A block is a sphere of infinite radius: R* = r.
      const bonded::ContactResult cr = bonded::with_contact_law(def, [&](const auto& law) {
        return law.with_friction(b.friction).force(delta, r, n, vn, vt, m_eff, hdt, xi);
      });
      next_history_.emplace(key, xi);
      const Vec3& F = cr.force;
      ps.f[i] += F;
      ps.torque[i] += a.cross(F);
      BlockLoad& L = loads_[k];
      L.force -= F;
      L.torque -= arm.cross(F);
      ++L.contacts;
      if (record_) recorded_.push_back({static_cast<std::uint32_t>(k), b.position + arm, -F});
      if (delta / r > res.worst_overlap_ratio) {
        res.worst_overlap_ratio = delta / r;
        res.worst_particle = static_cast<std::uint32_t>(i);
        worst_block_ = k;
      }
    }
  }
  if (hdt > 0.0)
    for (auto& L : loads_) {
      L.impulse += hdt * L.force;
      L.angular_impulse += hdt * L.torque;
    }
  history_.swap(next_history_);
  stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

std::string BlockContact::describe_worst(const bonded::ParticleStore& ps, std::uint32_t i, const Vec3& v_mid) const {
  if (worst_block_ >= blocks_.size() || i >= ps.size()) return name();
  const ContactBlock& b = blocks_[worst_block_];
  std::ostringstream s;
  s.precision(6);
  s << "rigid block " << b.id << " (centre (" << b.position.transpose() << ") m, half extents ("
    << b.half_extents.transpose() << ") m, velocity (" << b.velocity.transpose() << ") m/s, angular velocity "
    << b.angular_velocity.norm() << " rad/s" << (std::isinf(b.mass) ? ", immovable" : "") << ")";
  // How fast they close along the contact normal (n from the block to the particle), with the
  // particle's mid-step velocity and the block's as the step saw it; the spin's share is left out.
  const Mat3 R = b.orientation.toRotationMatrix();
  const Vec3 rel = ps.x[i] - b.position;
  BoxContact bc;
  if (box_contact(R.transpose() * rel, b.half_extents, R, ps.radius[i], bc)) {
    const Vec3 a = -(ps.radius[i] - 0.5 * bc.delta) * bc.n;
    const double vn = (v_mid - b.velocity - b.angular_velocity.cross(rel + a)).dot(bc.n);
    s << "; the particle at (" << ps.x[i].transpose() << ") m, moving at " << v_mid.norm() << " m/s in this step, "
      << (vn < 0.0 ? "closes on" : "parts from") << " it at " << std::abs(vn) << " m/s along the contact normal";
  }
  return s.str();
}

namespace {
struct HistWire {
  GlobalId gid;
  std::uint64_t block;
  Vec3 xi;
};
}  // namespace

void BlockContact::pack_history(const std::unordered_map<GlobalId, int>& leaving, std::vector<par::Bytes>& out) {
  for (auto it = history_.begin(); it != history_.end();) {
    const auto l = leaving.find(it->first.gid);
    if (l == leaving.end()) {
      ++it;
      continue;
    }
    const HistWire w{it->first.gid, it->first.block, it->second};
    par::Bytes& b = out[static_cast<std::size_t>(l->second)];
    const std::size_t o = b.size();
    b.resize(o + sizeof(HistWire));
    std::memcpy(b.data() + o, &w, sizeof(HistWire));  // same binary on every rank
    it = history_.erase(it);
  }
}

void BlockContact::unpack_history(const char* data, std::size_t size) {
  if (size % sizeof(HistWire) != 0) throw std::logic_error("BlockContact: malformed history message");
  for (std::size_t o = 0; o < size; o += sizeof(HistWire)) {
    HistWire w;
    std::memcpy(static_cast<void*>(&w), data + o, sizeof(HistWire));
    history_[Key{w.gid, w.block}] = w.xi;
  }
}

double BlockContact::elastic_energy(const bonded::ParticleStore& ps, std::size_t n_owned,
                                    const bonded::EngineDef& def) const {
  double e = 0.0;
  for (std::size_t i = 0; i < n_owned; ++i) {
    const double r = ps.radius[i];
    for (const ContactBlock& b : blocks_) {
      const Mat3 R = b.orientation.toRotationMatrix();
      const Vec3 l = R.transpose() * (ps.x[i] - b.position);
      BoxContact bc;
      if (!box_contact(l, b.half_extents, R, r, bc)) continue;
      auto it = history_.find(Key{ps.gid[i], b.id});
      const Vec3 xi = it == history_.end() ? Vec3::Zero() : it->second;
      // The sum inside the (inlined) lambda, as it was inside each branch before the dispatch: the
      // compiled arithmetic, and so the energy series, stay bit for bit (docs/engine.md).
      bonded::with_contact_law(def, [&](const auto& law) __attribute__((always_inline)) { e += law.energy(bc.delta, r, xi); });
    }
  }
  return e;
}

}  // namespace hs::bridge
