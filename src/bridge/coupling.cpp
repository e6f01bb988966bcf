#include "coupling.h"

#include <cmath>

namespace hs::bridge {

void ImpulseCoupler::reset(const std::vector<rigid::BlockId>& blocks) {
  blocks_ = blocks;
  linear_.assign(blocks.size(), Vec3::Zero());
  angular_.assign(blocks.size(), Vec3::Zero());
}

void ImpulseCoupler::add(std::size_t k, const Vec3& j, const Vec3& p, const Vec3& block_centre) {
  linear_[k] += j;
  angular_[k] += (p - block_centre).cross(j);
}

void ImpulseCoupler::add_about_centre(std::size_t k, const Vec3& j, const Vec3& h) {
  linear_[k] += j;
  angular_[k] += h;
}

std::size_t ImpulseCoupler::sum_and_apply(const par::Comm& comm, rigid::RigidWorld& world) {
  const int n = static_cast<int>(3 * blocks_.size());
  if (n > 0) {
    comm.sum_same_everywhere(linear_.data()->data(), n);
    comm.sum_same_everywhere(angular_.data()->data(), n);
  }
  std::size_t touched = 0;
  for (std::size_t k = 0; k < blocks_.size(); ++k) {
    const Vec3& J = linear_[k];
    const Vec3& L = angular_[k];
    if (J.squaredNorm() == 0.0 && L.squaredNorm() == 0.0) continue;
    ++touched;
    const Vec3 c = world.position(blocks_[k]);
    world.add_impulse(blocks_[k], J, c);
    if (L.squaredNorm() > 0.0) {
      // The angular impulse as a couple: +k at c + a and -k at c - a with a _|_ L and
      // k = (L x a) / (2 |a|^2), so that 2 a x k = L and the net linear impulse is zero.
      const Vec3 u = std::abs(L.x()) < 0.9 * L.norm() ? Vec3::UnitX() : Vec3::UnitY();
      const Vec3 a = L.cross(u).normalized();
      const Vec3 kk = L.cross(a) / 2.0;
      world.add_impulse(blocks_[k], kk, c + a);
      world.add_impulse(blocks_[k], -kk, c - a);
    }
  }
  reset(blocks_);
  return touched;
}

}  // namespace hs::bridge
