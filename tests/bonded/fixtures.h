// Small helpers shared by the engine tests: ice material in paper units.
#pragma once

#include "bonded/engine.h"
#include "bonded/hcp_lattice.h"
#include "common/ice_formulas.h"
#include "mesh/pier.h"

namespace hs::test {

struct Ice {
  double D = 0.5;        // particle diameter, m
  double rho = 920.0;    // kg/m^3
  double E = 1e9;        // Pa
  double kn() const { return eq1_contact_stiffness(E, D); }  // paper Eq. 1
  double sphere_mass() const { return rho * kPi * D * D * D / 6.0; }
  double cell_mass() const { return rho * bonded::hcp_cell_volume(D); }
  double tau0() const { return D * std::sqrt(rho / E); }
};

inline bonded::EngineDef no_field_def(const Ice& ice) {
  bonded::EngineDef d;
  d.gravity = Vec3::Zero();
  d.youngs_modulus = ice.E;
  d.density = ice.rho;
  d.contact.kn = d.contact.kt = ice.kn();
  return d;
}

inline bonded::ParticleInit sphere_at(const Ice& ice, const Vec3& x, bool lattice_mass = false) {
  bonded::ParticleInit p;
  p.x = x;
  p.radius = 0.5 * ice.D;
  p.mass = lattice_mass ? ice.cell_mass() : ice.sphere_mass();
  p.buoyant_volume = lattice_mass ? bonded::hcp_cell_volume(ice.D) : kPi * ice.D * ice.D * ice.D / 6.0;
  return p;
}

}  // namespace hs::test
