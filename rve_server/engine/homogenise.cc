// The homogenised state of an RVE: Love–Weber stress, fabric, void ratio,
// coordination and the tangent, from the sums of the last measured contact
// pass.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "rve_server/engine/contact_law.h"
#include "rve_server/engine/rve.h"
#include "rve_server/engine/rve_internal.h"

namespace rvehub::dem {

void Rve::EnsureSums() const {
  // A pass that only reads the contact history: it fills the caches and
  // changes no state, so a const Rve may run it.
  if (!sums_valid_) {
    const_cast<Rve*>(this)->Forces(Eigen::Matrix2d::Zero(), Measure::kSums, /*update=*/false);
  }
}

void Rve::EnsureStress() const {
  if (!stress_valid_) EnsureSums();
}

double Rve::MeanPressure() const {
  EnsureStress();
  return -0.5 * (sums_.stress(0, 0) + sums_.stress(1, 1)) /
         (p_.cell.determinant() * p_.material.thickness);
}

Eigen::Matrix2d Rve::DefinitionStress() const {
  Eigen::Matrix2d sum = Eigen::Matrix2d::Zero();  // Σ f⊗b, N·m
  ForEachContact([&](const ContactForce& c) { sum += c.ForceOnI() * c.branch.transpose(); });
  return 0.5 * (sum + sum.transpose()) / (p_.cell.determinant() * p_.material.thickness);
}

std::vector<ContactForce> Rve::Contacts() const {
  std::vector<ContactForce> out;
  ForEachContact([&](const ContactForce& c) { out.push_back(c); });
  return out;
}

namespace {

// What ParticleTerms reads, one entry per particle.
struct ParticleState {
  std::size_t n;
  const double* fx;  // N, sum of the contact forces
  const double* fy;
  const double* vx;  // m/s
  const double* vy;
  const double* om;           // rad/s
  const double* inv_mass;     // 1/kg
  const double* inv_inertia;  // 1/(kg m²)
};

// Per particle: |Σ contact forces| (N; far from overflow, so no hypot) into
// resultant[i] and twice the kinetic energy m v² + I ω² (J) into
// kinetic2[i]. Each particle is independent, so the loop runs in SIMD lanes
// with the scalar operations' bits (an AVX2 clone where the CPU has it).
__attribute__((target_clones("avx2", "default"))) void ParticleTerms(const ParticleState& a,
                                                                     double* __restrict resultant,
                                                                     double* __restrict kinetic2) {
  const double* __restrict fx = a.fx;
  const double* __restrict fy = a.fy;
  const double* __restrict vx = a.vx;
  const double* __restrict vy = a.vy;
  const double* __restrict om = a.om;
  const double* __restrict inv_mass = a.inv_mass;
  const double* __restrict inv_inertia = a.inv_inertia;
#pragma omp simd
  for (std::size_t i = 0; i < a.n; ++i) {
    resultant[i] = std::sqrt(fx[i] * fx[i] + fy[i] * fy[i]);
    kinetic2[i] = (vx[i] * vx[i] + vy[i] * vy[i]) / inv_mass[i] + om[i] * om[i] / inv_inertia[i];
  }
}

}  // namespace

// The state's stress, volume, porosity measures, Δt and mass scale (and the
// tangent) from the known stress sums. Love–Weber stress σ = (1/V) sym Σ f⊗b.
RveState Rve::ObserveCommon(bool want_tangent) const {
  RveState s;
  const Eigen::Matrix2d& h = p_.cell;
  const Material& mat = p_.material;
  const double area = h.determinant();
  s.volume = area * mat.thickness;
  const Eigen::Matrix2d sym = 0.5 * (sums_.stress + sums_.stress.transpose()) / s.volume;
  s.stress.topLeftCorner<2, 2>() = sym;
  s.void_ratio = VoidRatioOfArea(area);
  s.porosity = s.void_ratio / (1.0 + s.void_ratio);
  const double e = std::max(s.void_ratio, 0.0);
  s.permeability = p_.permeability_coefficient * e * e * e / (1.0 + e);
  s.time_step = dt_;
  s.mass_scale = p_.controls.mass_scale;
  if (want_tangent) {
    // D_ijkl = (1/V)Σ(kn n_i b_j n_k b_l + kt t_i b_j t_k b_l): rarely asked
    // for (the MPM time step), so one pass of its own.
    double d[2][2][2][2] = {};
    ForEachContact([&](const ContactForce& c) {
      const Eigen::Vector2d& nn = c.normal;
      const Eigen::Vector2d t(-nn.y(), nn.x());
      const Eigen::Vector2d& br = c.branch;
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b)
          for (int e2 = 0; e2 < 2; ++e2)
            for (int g = 0; g < 2; ++g)
              d[a][b][e2][g] +=
                  c.kn * nn[a] * br[b] * nn[e2] * br[g] + c.kt * t[a] * br[b] * t[e2] * br[g];
    });
    Eigen::Matrix<double, 9, 9>& tangent = s.tangent.emplace(Eigen::Matrix<double, 9, 9>::Zero());
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b)
        for (int c = 0; c < 2; ++c)
          for (int e2 = 0; e2 < 2; ++e2) tangent(3 * a + b, 3 * c + e2) = d[a][b][c][e2] / s.volume;
  }
  return s;
}

RveState Rve::ObserveStress(bool want_tangent) const {
  EnsureStress();
  return ObserveCommon(want_tangent);
}

// The homogenised state from the sums of the last measured contact pass
// (the last DEM step of an increment, or a pass that only reads the history)
// and one pass over the particles.
RveState Rve::Observe(bool want_tangent) const {
  EnsureSums();
  RveState s = ObserveCommon(want_tangent);
  const std::size_t n = p_.radius.size();
  const Sums& m = sums_;
  const std::int64_t nc = m.num_contacts;
  s.num_contacts = nc;
  if (nc > 0) {
    s.fabric_defined = true;
    const Eigen::Matrix2d phi = m.fabric / static_cast<double>(nc);
    s.fabric.topLeftCorner<2, 2>() = phi;
    const Eigen::Matrix2d fa = 4.0 * (phi - 0.5 * Eigen::Matrix2d::Identity());
    s.fabric_anisotropy_tensor.topLeftCorner<2, 2>() = fa;
    s.fabric_anisotropy = std::sqrt(0.5 * fa.squaredNorm());
  }
  s.coordination = 2.0 * static_cast<double>(nc) / static_cast<double>(n);
  // Each particle's terms in SIMD lanes, then the sums in particle order.
  internal::Scratch& scratch = internal::ThreadScratch();
  scratch.resultant.resize(n);
  scratch.kinetic2.resize(n);
  ParticleTerms({n, fx_.data(), fy_.data(), p_.vx.data(), p_.vy.data(), p_.omega.data(),
                 inv_mass_.data(), inv_inertia_.data()},
                scratch.resultant.data(), scratch.kinetic2.data());
  double resultant = 0, rotation = 0, kinetic = 0;
  for (std::size_t i = 0; i < n; ++i) {
    resultant += scratch.resultant[i];
    rotation += p_.theta[i];
    kinetic += scratch.kinetic2[i];
  }
  // Thornton's mechanical coordination: rattlers (0 or 1 contact) left out.
  const double n0 = static_cast<double>(m.rattlers0), n1 = static_cast<double>(m.rattlers1);
  const double active = static_cast<double>(n) - n0 - n1;
  s.mechanical_coordination = active > 0 ? (2.0 * static_cast<double>(nc) - n1) / active : 0.0;
  s.unbalanced_force_ratio =
      nc > 0 ? (resultant / static_cast<double>(n)) / (m.force_sum / static_cast<double>(nc)) : 0.0;
  s.mean_rotation = rotation / static_cast<double>(n);
  s.kinetic_energy = 0.5 * kinetic;
  return s;
}

}  // namespace rvehub::dem
