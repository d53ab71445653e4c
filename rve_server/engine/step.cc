// The DEM step: the contact pass (pair law in SIMD lanes, then per-particle
// sums and the measured sums) and the leapfrog integration.
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

using internal::Damping;
using internal::kPi;
using internal::RoundNearest;
using internal::Scratch;
using internal::ThreadScratch;

namespace {

// What the pair pass reads and writes: particle and pair arrays, the cell
// h (m), the velocity gradient l (1/s) and the material.
struct PairPassArgs {
  const double* rad;  // m
  const double* sx;   // reduced coordinates
  const double* sy;
  const double* vx;  // m/s
  const double* vy;
  const double* om;             // rad/s
  const std::uint32_t* pair_i;  // pair k = (pair_i[k], pair_j[k]), i < j
  const std::uint32_t* pair_j;
  const double* kn;  // N/m, linear model's E·r* per pair
  double* ft;        // N, tangential history per pair
  double* moment;    // N·m, rolling history per pair
  double* bond;      // N, bond strength per pair (0: none)
  Scratch* out;
  double h00, h01, h10, h11, l00, l01, l10, l11;
  double dt;  // s
  const Material* mat;
};

// The contact law of every listed pair k ∈ [0, m): force on i −fn·n + ft·t
// (N) and the torques on i and j (N·m) into out->fx, fy, ti, tj, all 0 for a
// pair not in contact; kUpdate advances the history first (tangential spring
// by kt·v_t·Δt with the relative velocity of the affine motion l and of the
// particles, Coulomb cap, rolling spring, bond breakage) as the end of a DEM
// step does; without it the stored history is only read, so a recomputation
// gives the forces of the state bit for bit. kMeasure (0 none, 1 the servo's
// stress and stiffness, 2 the homogenisation sums, 3 their stress alone)
// also stores each pair's terms for those sums. The pairs are independent: the loop runs in SIMD
// lanes (an AVX2 clone where the CPU has it) with selects for every branch,
// each lane doing the scalar operations in the scalar order, so the bits do
// not depend on the lane count or the CPU.
template <bool kRolling, bool kBonds, bool kHertz, int kMeasure, bool kUpdate>
__attribute__((target_clones("avx2", "default"))) void PairPass(const PairPassArgs& a,
                                                                std::size_t m) {
  const double h00 = a.h00, h01 = a.h01, h10 = a.h10, h11 = a.h11;
  const double l00 = a.l00, l01 = a.l01, l10 = a.l10, l11 = a.l11, dt = a.dt;
  const Material& mat = *a.mat;
  const NormalLawParams normal = NormalParams(mat);
  const double mu = mat.friction;
  const double beta = mat.rolling_beta, eta = mat.rolling_eta;
  const double* __restrict rad = a.rad;
  const double* __restrict sx = a.sx;
  const double* __restrict sy = a.sy;
  const double* __restrict vx = a.vx;
  const double* __restrict vy = a.vy;
  const double* __restrict om = a.om;
  const std::uint32_t* __restrict pair_i = a.pair_i;
  const std::uint32_t* __restrict pair_j = a.pair_j;
  const double* __restrict nbr_kn = a.kn;
  double* __restrict nbr_ft = a.ft;
  double* __restrict nbr_moment = a.moment;
  double* __restrict nbr_bond = a.bond;
  double* __restrict o_fx = a.out->fx.data();
  double* __restrict o_fy = a.out->fy.data();
  double* __restrict o_ti = a.out->ti.data();
  double* __restrict o_tj = a.out->tj.data();
  double* __restrict o_t0 = a.out->term[0].data();
  double* __restrict o_t1 = a.out->term[1].data();
  double* __restrict o_t2 = a.out->term[2].data();
  double* __restrict o_t3 = a.out->term[3].data();
  double* __restrict o_t4 = a.out->term[4].data();
  double* __restrict o_t5 = a.out->term[5].data();
  double* __restrict o_el = a.out->elastic.data();
  double* __restrict o_act = a.out->active.data();
#pragma omp simd
  for (std::size_t k = 0; k < m; ++k) {
    const std::uint32_t i = pair_i[k], j = pair_j[k];
    double dsx = sx[j] - sx[i], dsy = sy[j] - sy[i];
    dsx -= RoundNearest(dsx);
    dsy -= RoundNearest(dsy);
    const double dx = h00 * dsx + h01 * dsy;  // branch vector i → j, m
    const double dy = h10 * dsx + h11 * dsy;
    const double ri = rad[i], rj = rad[j], rsum = ri + rj;
    const double d2 = dx * dx + dy * dy;
    const double bond = kBonds ? nbr_bond[k] : 0.0;
    bool bonded = kBonds && bond > 0;
    const bool touching = !(d2 >= rsum * rsum) || bonded;
    const double dist = std::sqrt(d2);
    const double inv = 1.0 / dist;
    const double nx = dx * inv, ny = dy * inv, tx = -ny, ty = nx;
    const double overlap = rsum - dist;  // m; < 0 only for a stretched bond
    // The linear model's kn = E·r* is cached per pair at the rebuild.
    const NormalResponse law = NormalLaw<kHertz>(normal, ri, rj, overlap, kHertz ? 0.0 : nbr_kn[k]);
    const double fn = law.fn, kn = law.kn, kt = law.kt, elastic = law.elastic;
    // Lever arms to the common contact point make a rigid motion of the
    // pair produce no relative tangential velocity.
    const double li = ri - 0.5 * overlap, lj = rj - 0.5 * overlap;
    double ft = nbr_ft[k];
    double moment = 0.0;
    bool gone = false;  // a broken bond's pair out of contact: no force
    if constexpr (kUpdate) {
      const double vrx = vx[j] - vx[i] + l00 * dx + l01 * dy;
      const double vry = vy[j] - vy[i] + l10 * dx + l11 * dy;
      const double vt = vrx * tx + vry * ty - (om[i] * li + om[j] * lj);
      ft += kt * vt * dt;
      if constexpr (kBonds) {
        const bool broken = bonded && (-fn > bond || std::abs(ft) > bond);
        nbr_bond[k] = broken ? 0.0 : bond;  // broken: purely frictional from now on
        bonded = bonded && !broken;
        gone = !bonded && overlap <= 0.0;
      }
      ft = bonded ? ft : CoulombCap(ft, fn, mu);
      if constexpr (kRolling) {
        const double kr = RollingStiffness(kt, ri, rj, beta);
        const double limit = RollingLimit(eta, ri, rj, fn);
        moment = std::clamp(nbr_moment[k] - kr * (om[i] - om[j]) * dt, -limit, limit);
      }
    } else {
      // The stored history as the last update left it. Capping again
      // changes nothing there (ft and M are already within the limits of
      // these very positions) and keeps a history from elsewhere (an
      // imported packing) physical.
      if constexpr (kBonds) gone = !bonded && overlap <= 0.0;
      ft = bonded ? ft : CoulombCap(ft, fn, mu);
      if constexpr (kRolling) {
        const double limit = RollingLimit(eta, ri, rj, fn);
        moment = std::clamp(nbr_moment[k], -limit, limit);
      }
    }
    const bool active = touching && !gone;
    if constexpr (kUpdate) {
      nbr_ft[k] = active ? ft : 0.0;
      if constexpr (kRolling) nbr_moment[k] = active ? moment : 0.0;
    }
    const double fcx = -fn * nx + ft * tx;  // force on i, N
    const double fcy = -fn * ny + ft * ty;
    o_fx[k] = active ? fcx : 0.0;
    o_fy[k] = active ? fcy : 0.0;
    o_ti[k] = active ? li * ft + moment : 0.0;
    o_tj[k] = active ? lj * ft - moment : 0.0;
    if constexpr (kMeasure != 0) {
      if constexpr (kMeasure == 1) {  // Σ f⊗b and the servo's Σ kn |b|² n_x⁴, n_y⁴
        const double kd2 = kn * d2;
        o_t0[k] = active ? fcx * dx : 0.0;
        o_t1[k] = active ? fcx * dy : 0.0;
        o_t2[k] = active ? fcy * dx : 0.0;
        o_t3[k] = active ? fcy * dy : 0.0;
        o_t4[k] = active ? kd2 * (nx * nx) * (nx * nx) : 0.0;
        o_t5[k] = active ? kd2 * (ny * ny) * (ny * ny) : 0.0;
      } else {  // sym Σ f⊗b (xy twice); kMeasure 2: Σ n⊗n (xx, xy) and Σ |f|
        o_t0[k] = active ? fcx * dx : 0.0;
        o_t1[k] = active ? fcx * dy + fcy * dx : 0.0;
        o_t2[k] = active ? fcy * dy : 0.0;
        if constexpr (kMeasure == 2) {
          o_t3[k] = active ? nx * nx : 0.0;
          o_t4[k] = active ? nx * ny : 0.0;
          o_t5[k] = active ? std::sqrt(fcx * fcx + fcy * fcy) : 0.0;
        }
      }
      if constexpr (kMeasure != 3) {
        o_el[k] = touching ? elastic : 0.0;  // counted before a bond breaks, as always
        o_act[k] = active ? 1.0 : 0.0;
      }
    }
  }
}

}  // namespace

// The contact pass: the pair pass above, then the forces and torques summed
// per particle into fx_, fy_, tq_ (N, N·m) in pair order, then (kMeasure)
// the sums, again in pair order. A pair not in contact adds +0, which
// changes no sum (none is ever −0), so the bits are those of one loop that
// skips such pairs. kServo sums the stress and the servo stiffness of the
// step (StepResult); kSums the homogenisation sums (sums_). Both measure the
// elastic energy (last_elastic_).
template <bool kRolling, bool kBonds, bool kHertz, Rve::Measure kMeasure, bool kUpdate>
Rve::StepResult Rve::ContactLoop(const Eigen::Matrix2d& l) {
  const std::size_t n = p_.radius.size();
  const std::size_t m = nbr_j_.size();
  constexpr bool kAny = kMeasure != Measure::kNone;
  constexpr bool kServo = kMeasure == Measure::kServo, kSums = kMeasure == Measure::kSums;
  constexpr bool kStressOnly = kMeasure == Measure::kStress;
  Scratch& scratch = ThreadScratch();
  for (std::vector<double>* v : {&scratch.fx, &scratch.fy, &scratch.ti, &scratch.tj}) {
    if (v->size() < m) v->resize(m);
  }
  if constexpr (kAny) {
    for (std::vector<double>* v :
         {&scratch.elastic, &scratch.active, &scratch.term[0], &scratch.term[1], &scratch.term[2],
          &scratch.term[3], &scratch.term[4], &scratch.term[5]}) {
      if (v->size() < m) v->resize(m);
    }
  }
  const PairPassArgs args{p_.radius.data(),
                          p_.sx.data(),
                          p_.sy.data(),
                          p_.vx.data(),
                          p_.vy.data(),
                          p_.omega.data(),
                          nbr_i_.data(),
                          nbr_j_.data(),
                          nbr_kn_.data(),
                          nbr_ft_.data(),
                          nbr_moment_.data(),
                          nbr_bond_.data(),
                          &scratch,
                          p_.cell(0, 0),
                          p_.cell(0, 1),
                          p_.cell(1, 0),
                          p_.cell(1, 1),
                          l(0, 0),
                          l(0, 1),
                          l(1, 0),
                          l(1, 1),
                          dt_,
                          &p_.material};
  PairPass<kRolling, kBonds, kHertz, static_cast<int>(kMeasure), kUpdate>(args, m);

  // Forces and torques per particle, in the order of one loop over rows i:
  // row i's own pairs summed apart and added last. kSums also counts each
  // particle's contacts there (integers: exact in any order).
  fx_.assign(n, 0.0);
  fy_.assign(n, 0.0);
  tq_.assign(n, 0.0);
  std::int32_t* __restrict count = nullptr;
  const double* __restrict c_act = nullptr;
  std::int64_t nc = 0;  // contacts
  if constexpr (kSums) {
    scratch.count.assign(n, 0);
    count = scratch.count.data();
    c_act = scratch.active.data();
  }
  double* __restrict fx = fx_.data();
  double* __restrict fy = fy_.data();
  double* __restrict tq = tq_.data();
  const double* __restrict c_fx = scratch.fx.data();
  const double* __restrict c_fy = scratch.fy.data();
  const double* __restrict c_ti = scratch.ti.data();
  const double* __restrict c_tj = scratch.tj.data();
  const std::uint32_t* __restrict row_start = row_start_.data();
  const std::uint32_t* __restrict nbr_j = nbr_j_.data();
  for (std::uint32_t i = 0; i < n; ++i) {
    double fxi = 0, fyi = 0, tqi = 0;
    std::int32_t ci = 0;
    const std::uint32_t row_end = row_start[i + 1];
    for (std::uint32_t k = row_start[i]; k < row_end; ++k) {
      const std::uint32_t j = nbr_j[k];
      fxi += c_fx[k];
      fyi += c_fy[k];
      fx[j] -= c_fx[k];
      fy[j] -= c_fy[k];
      tqi += c_ti[k];
      tq[j] += c_tj[k];
      if constexpr (kSums) {
        const std::int32_t active = c_act[k] != 0.0;
        ci += active;
        count[j] += active;
      }
    }
    fx[i] += fxi;
    fy[i] += fyi;
    tq[i] += tqi;
    if constexpr (kSums) {
      count[i] += ci;
      nc += ci;
    }
  }
  forces_valid_ = true;

  const double volume = p_.cell.determinant() * p_.material.thickness;
  StepResult out;
  if constexpr (kAny) {
    // The six sums, each in pair order.
    double sum[6] = {0, 0, 0, 0, 0, 0};
    const double* __restrict t0 = scratch.term[0].data();
    const double* __restrict t1 = scratch.term[1].data();
    const double* __restrict t2 = scratch.term[2].data();
    const double* __restrict t3 = scratch.term[3].data();
    const double* __restrict t4 = scratch.term[4].data();
    const double* __restrict t5 = scratch.term[5].data();
    if constexpr (kStressOnly) {
      for (std::size_t k = 0; k < m; ++k) {
        sum[0] += t0[k];
        sum[1] += t1[k];
        sum[2] += t2[k];
      }
    } else {
      for (std::size_t k = 0; k < m; ++k) {
        sum[0] += t0[k];
        sum[1] += t1[k];
        sum[2] += t2[k];
        sum[3] += t3[k];
        sum[4] += t4[k];
        sum[5] += t5[k];
      }
    }
    // (Forces never measures the stress alone while the energy is tracked.)
    if (kServo || (track_energy_ && !kStressOnly)) {
      double elastic = 0;
      for (std::size_t k = 0; k < m; ++k) elastic += scratch.elastic[k];
      last_elastic_ = elastic;
    } else {
      last_elastic_ = 0.0;
    }
    if constexpr (kServo) {
      out.stress << sum[0] / volume, sum[1] / volume, sum[2] / volume, sum[3] / volume;
      out.stiffness = Eigen::Vector2d(sum[4], sum[5]) / volume;
      sums_valid_ = stress_valid_ = false;
    }
    if constexpr (kStressOnly) {
      sums_.stress << sum[0], 0.5 * sum[1], 0.5 * sum[1], sum[2];  // as kSums below
      sums_valid_ = false;
      stress_valid_ = true;
    }
    if constexpr (kSums) {
      Sums& s = sums_;
      s.stress << sum[0], 0.5 * sum[1], 0.5 * sum[1], sum[2];  // symmetric part of Σ f⊗b
      s.fabric << sum[3], sum[4], sum[4], static_cast<double>(nc) - sum[3];
      s.force_sum = sum[5];
      s.num_contacts = nc;
      s.rattlers0 = s.rattlers1 = 0;
      for (std::size_t i = 0; i < n; ++i) {
        s.rattlers0 += count[i] == 0;
        s.rattlers1 += count[i] == 1;
      }
      sums_valid_ = stress_valid_ = true;
    }
  } else {
    sums_valid_ = stress_valid_ = false;
  }
  return out;
}

Rve::StepResult Rve::Forces(const Eigen::Matrix2d& l, Measure measure, bool update) {
  const bool rolling = !nbr_moment_.empty(), bonds = !nbr_bond_.empty();
  const bool hertz = p_.material.model == ContactModel::kHertzMindlin;
  // The energy needs the elastic sum, which only the full sums carry.
  if (measure == Measure::kStress && track_energy_) measure = Measure::kSums;
  // One instantiation per feature set keeps unused features out of the loop;
  // a pass that only reads the history always measures (it serves Observe).
  auto pick = [&]<Measure kMeasure, bool kUpdate>() {
    if (hertz) {
      return rolling ? ContactLoop<true, false, true, kMeasure, kUpdate>(l)
                     : ContactLoop<false, false, true, kMeasure, kUpdate>(l);
    }
    if (rolling) {
      return bonds ? ContactLoop<true, true, false, kMeasure, kUpdate>(l)
                   : ContactLoop<true, false, false, kMeasure, kUpdate>(l);
    }
    return bonds ? ContactLoop<false, true, false, kMeasure, kUpdate>(l)
                 : ContactLoop<false, false, false, kMeasure, kUpdate>(l);
  };
  if (!update) return pick.template operator()<Measure::kSums, false>();
  switch (measure) {
    case Measure::kServo:
      return pick.template operator()<Measure::kServo, true>();
    case Measure::kSums:
      return pick.template operator()<Measure::kSums, true>();
    case Measure::kStress:
      return pick.template operator()<Measure::kStress, true>();
    case Measure::kNone:
      break;
  }
  return pick.template operator()<Measure::kNone, true>();
}

namespace {

// The arrays one leapfrog step reads and writes, one entry per particle.
struct ParticleArrays {
  std::size_t n;
  const double* rad;          // m
  const double* fx;           // N
  const double* fy;           // N
  const double* tq;           // N·m
  const double* inv_mass;     // 1/kg
  const double* inv_inertia;  // 1/(kg m²)
  double* vx;                 // m/s
  double* vy;                 // m/s
  double* om;                 // rad/s
  double* sx;                 // reduced coordinates
  double* sy;
  double* th;  // rad
};

// Leapfrog with local non-viscous damping acting in the frame q (the cell's
// axes). Returns max |v|² (m²/s²). kMeasure adds the kinetic energy ×2 (J)
// at the force time into *kinetic2, in particle order. Each particle's
// update is independent, so without kMeasure the loop runs in SIMD lanes
// with the scalar operations' bits (a max needs no order).
template <bool kRotated, bool kMeasure>
__attribute__((target_clones("avx2", "default"))) double Leapfrog(
    const ParticleArrays& a, double dt, double alpha, const Eigen::Matrix2d& q,
    const Eigen::Matrix2d& hinv, double mass_per_r2, double* kinetic2) {
  const double q00 = q(0, 0), q01 = q(0, 1), q10 = q(1, 0), q11 = q(1, 1);
  const double i00 = hinv(0, 0), i01 = hinv(0, 1), i10 = hinv(1, 0), i11 = hinv(1, 1);
  const std::size_t n = a.n;
  const double* __restrict rad = a.rad;
  const double* __restrict ffx = a.fx;
  const double* __restrict ffy = a.fy;
  const double* __restrict ftq = a.tq;
  const double* __restrict inv_mass = a.inv_mass;
  const double* __restrict inv_inertia = a.inv_inertia;
  double* __restrict wvx = a.vx;
  double* __restrict wvy = a.vy;
  double* __restrict wom = a.om;
  double* __restrict wsx = a.sx;
  double* __restrict wsy = a.sy;
  double* __restrict wth = a.th;
  double vmax2 = 0.0;
  double k2 = 0.0;
#pragma omp simd reduction(max : vmax2) if (!kMeasure)
  for (std::size_t i = 0; i < n; ++i) {
    const double fx = ffx[i], fy = ffy[i], tq = ftq[i], vx = wvx[i], vy = wvy[i], om = wom[i];
    double ax, ay;
    if constexpr (!kRotated) {
      ax = (fx + Damping(alpha, fx, vx)) * inv_mass[i];
      ay = (fy + Damping(alpha, fy, vy)) * inv_mass[i];
    } else {
      const double lfx = q00 * fx + q10 * fy, lfy = q01 * fx + q11 * fy;
      const double lvx = q00 * vx + q10 * vy, lvy = q01 * vx + q11 * vy;
      const double dfx = Damping(alpha, lfx, lvx), dfy = Damping(alpha, lfy, lvy);
      ax = (fx + q00 * dfx + q01 * dfy) * inv_mass[i];
      ay = (fy + q10 * dfx + q11 * dfy) * inv_mass[i];
    }
    const double aw = (tq + Damping(alpha, tq, om)) * inv_inertia[i];
    if constexpr (kMeasure) {
      // Velocities at the force time (mean of the two half steps) for the energy;
      // m = c·r², I = ½ m r²: multiplications instead of dividing by 1/m.
      const double ux = vx + 0.5 * dt * ax, uy = vy + 0.5 * dt * ay, uw = om + 0.5 * dt * aw;
      const double r2 = rad[i] * rad[i];
      k2 += mass_per_r2 * r2 * (ux * ux + uy * uy + 0.5 * r2 * uw * uw);
    }
    const double nvx = vx + dt * ax, nvy = vy + dt * ay, nom = om + dt * aw;
    wvx[i] = nvx;
    wvy[i] = nvy;
    wom[i] = nom;
    wth[i] += dt * nom;
    const double dxr = dt * nvx, dyr = dt * nvy;
    wsx[i] += i00 * dxr + i01 * dyr;
    wsy[i] += i10 * dxr + i11 * dyr;
    const double v2 = nvx * nvx + nvy * nvy;
    vmax2 = v2 > vmax2 ? v2 : vmax2;
  }
  if constexpr (kMeasure) *kinetic2 = k2;
  return vmax2;
}

}  // namespace

// Leapfrog with local non-viscous damping, acting in the cell's frame, with
// the forces of the current positions (fx_, fy_, tq_).
void Rve::Integrate() {
  const Material& mat = p_.material;
  const ParticleArrays a{p_.radius.size(), p_.radius.data(), fx_.data(),          fy_.data(),
                         tq_.data(),       inv_mass_.data(), inv_inertia_.data(), p_.vx.data(),
                         p_.vy.data(),     p_.omega.data(),  p_.sx.data(),        p_.sy.data(),
                         p_.theta.data()};
  const double mass_per_r2 = mat.density * kPi * mat.thickness * p_.controls.mass_scale;  // kg/m²
  const Eigen::Matrix2d& q = p_.frame;
  const Eigen::Matrix2d hinv = p_.cell.inverse();
  const bool rotated = q != Eigen::Matrix2d::Identity();
  double kinetic2 = 0.0, vmax2;
  if (track_energy_) {
    vmax2 = rotated ? Leapfrog<true, true>(a, dt_, mat.damping, q, hinv, mass_per_r2, &kinetic2)
                    : Leapfrog<false, true>(a, dt_, mat.damping, q, hinv, mass_per_r2, &kinetic2);
    energy_ = {0.5 * kinetic2, last_elastic_};
  } else {
    vmax2 = rotated ? Leapfrog<true, false>(a, dt_, mat.damping, q, hinv, mass_per_r2, nullptr)
                    : Leapfrog<false, false>(a, dt_, mat.damping, q, hinv, mass_per_r2, nullptr);
  }
  displacement_bound_ += std::sqrt(vmax2) * dt_;
}

Rve::StepResult Rve::Step(const Eigen::Matrix2d& l, const Eigen::Matrix2d& next_cell,
                          bool measure) {
  const StepResult r =
      Forces(l, measure || track_energy_ ? Measure::kServo : Measure::kNone, /*update=*/true);
  Integrate();
  AdvanceCell(next_cell);
  forces_valid_ = sums_valid_ = stress_valid_ = false;  // those of the old positions
  return r;
}

Rve::StepResult Rve::StepForcesLast(const Eigen::Matrix2d& l, const Eigen::Matrix2d& next_cell,
                                    Measure measure) {
  // The forces of the current positions: those the last step left, or (after
  // a restore, a Run or a change of the contacts) recomputed from the state.
  if (!forces_valid_ || (track_energy_ && !sums_valid_)) Forces(l, Measure::kSums, false);
  Integrate();
  AdvanceCell(next_cell);
  // The new positions' forces, with the history advanced by this step's
  // motion: the next step integrates with them and, measured, they are the
  // homogenised state of the new configuration.
  return Forces(l, track_energy_ && measure == Measure::kNone ? Measure::kSums : measure,
                /*update=*/true);
}

void Rve::AdvanceCell(const Eigen::Matrix2d& next_cell) {
  p_.cell = next_cell;
  ++p_.total_steps;
  MaybeFlip();
  MaybeRebuild();
}

}  // namespace rvehub::dem
