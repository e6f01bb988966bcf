// Crushed pairs (docs/engine.md, "Crushed bonds"): a bond that breaks with its particles squeezed
// deeper than h = EngineDef::crushed_set_depth (0.25 r, half the default stability limit) leaves a
// contact with a permanent set. The ice between the two centres has failed; the contact pushes
// back only on the overlap beyond set = overlap at the break - h, so it takes over from the bond at h,
// whatever the squeeze, instead of at the whole overlap (a contact that starts 0.7 r deep is past
// the stability limit at once, and its force, k_n 0.7 r, is a kick no bond was carrying).
//
// The pairs are kept out of the contact list (build_pair_list) and computed here, on the rank that
// owns the lower global id (migration and checkpoints carry them, engine_parallel.cpp and
// engine_state.cpp). Once the two particles part (no overlap), the set is gone and the pair joins
// the contact list as an ordinary contact. Usually there are none: this costs nothing then.
#include "engine.h"

#include "contact_law.h"

#include <algorithm>
#include <cmath>

namespace hs::bonded {

double Engine::crushed_set_of(GlobalId a, GlobalId b) const {
  const auto it = crushed_.find(GidPair::of(a, b));
  return it == crushed_.end() ? -1.0 : it->second.set;
}

void Engine::crushed_forces() {
  with_contact_law(def_, [&](const auto& law) {
    Vec3* f = ps_.f.data();
    Vec3* t = ps_.torque.data();
    const Vec3* x = ps_.x.data();
    const Vec3* v = ps_.v.data();
    const Vec3* w = ps_.omega.data();
    const double* r = ps_.radius.data();
    const double* im = ps_.inv_mass.data();
    double worst = 0.0;
    std::uint32_t wi = 0, wj = 0;
    for (auto it = crushed_.begin(); it != crushed_.end();) {
      const std::uint32_t i = ps_.local(it->first.a), j = ps_.local(it->first.b);
      if (i == ParticleStore::kNone || j == ParticleStore::kNone) {  // far apart (beyond the halo)
        it = crushed_.erase(it);
        continue;
      }
      const Vec3 d = x[j] - x[i];
      const double rs = r[i] + r[j];
      const double dist = d.norm();
      const double delta = rs - dist;
      if (delta <= 0.0) {  // parted: an ordinary contact from now on
        pairs_.push_back({i, j, Vec3::Zero()});
        it = crushed_.erase(it);
        continue;
      }
      CrushedContact& c = it->second;
      const double de = delta - c.set;
      const double inv_sum = im[i] + im[j];
      if (de <= 0.0 || inv_sum == 0.0) {  // inside the set: no push, no friction
        c.xi.setZero();
        ++it;
        continue;
      }
      const Vec3 n = d / dist;
      const Vec3 ai = (r[i] - 0.5 * delta) * n;  // the contact point: mid-way through the overlap
      const Vec3 aj = -(r[j] - 0.5 * delta) * n;
      const Vec3 vrel = v[j] + w[j].cross(aj) - v[i] - w[i].cross(ai);
      const double vn = vrel.dot(n);
      const Vec3 vt = vrel - vn * n;
      const ContactResult res = law.force(de, r[i] * r[j] / rs, n, vn, vt, 1.0 / inv_sum, history_dt_, c.xi);
      f[j] += res.force;
      f[i] -= res.force;
      t[i] -= ai.cross(res.force);
      t[j] += aj.cross(res.force);
      const double ratio = de / std::min(r[i], r[j]);
      if (ratio > worst) {
        worst = ratio;
        wi = i;
        wj = j;
      }
      ++it;
    }
    if (worst > worst_overlap_ratio_) {
      worst_overlap_ratio_ = worst;
      worst_overlap_i_ = wi;
      worst_overlap_j_ = wj;
      worst_overlap_source_ = -1;
    }
  });
}

double Engine::crushed_energy() const {
  double e = 0.0;
  with_contact_law(def_, [&](const auto& law) {
    for (const auto& [k, c] : crushed_) {
      const std::uint32_t i = ps_.local(k.a), j = ps_.local(k.b);
      if (i == ParticleStore::kNone || j == ParticleStore::kNone) continue;
      const double rs = ps_.radius[i] + ps_.radius[j];
      const double de = rs - (ps_.x[j] - ps_.x[i]).norm() - c.set;
      if (de > 0.0) e += law.energy(de, ps_.radius[i] * ps_.radius[j] / rs, c.xi);
    }
  });
  return e;
}

}  // namespace hs::bonded
