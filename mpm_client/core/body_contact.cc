#include "mpm_client/core/body_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rvehub::mpm {
namespace {

using Eigen::Vector2d;

// Signed distance from x to the body's surface (m, outside +) and the unit
// normal there, pointing out of the body.
void SignedDistance(const RigidBody& body, const Vector2d& center, const Vector2d& x,
                    double& distance, Vector2d& normal) {
  const Vector2d d = x - center;
  if (body.shape == RigidBody::Shape::kCircle) {
    const double r = d.norm();
    normal = r > 0.0 ? Vector2d(d / r) : Vector2d::UnitY();
    distance = r - body.radius;
    return;
  }
  const Vector2d e = body.half_size;
  const Vector2d outside = d.cwiseAbs() - e;
  if (outside.x() > 0.0 || outside.y() > 0.0) {
    // Outside: to the nearest point of the rectangle (a face or a corner).
    const Vector2d r = d - d.cwiseMax(-e).cwiseMin(e);
    distance = r.norm();
    normal = r / distance;
    return;
  }
  // Inside: to the nearest face; ties go to ±y, then ±x (a footing's base
  // and sides), in that order.
  const double gap[4] = {e.y() - d.y(), e.y() + d.y(), e.x() - d.x(), e.x() + d.x()};
  const Vector2d face[4] = {{0.0, 1.0}, {0.0, -1.0}, {1.0, 0.0}, {-1.0, 0.0}};
  int best = 0;
  for (int k = 1; k < 4; ++k) {
    if (gap[k] < gap[best]) best = k;
  }
  normal = face[best];
  distance = -gap[best];
}

}  // namespace

double DomainExtent(const Eigen::Matrix2d& f, const Vector2d& lp0, const Vector2d& n) {
  return (f.transpose() * n).cwiseProduct(lp0).norm();  // |(n·F e_i)·lp0_i|, m
}

Vector2d DomainBound(const Eigen::Matrix2d& f, const Vector2d& lp0) { return f.cwiseAbs() * lp0; }

BodyGap GapToBody(const RigidBody& body, const Vector2d& center, const Vector2d& x,
                  const Eigen::Matrix2d& f, const Vector2d& lp0) {
  BodyGap out;
  double distance = 0.0;
  SignedDistance(body, center, x, distance, out.normal);
  const double extent = DomainExtent(f, lp0, out.normal);
  out.gap = distance - extent;
  out.face = x - extent * out.normal;
  return out;
}

int ResolveContacts(std::span<const SurfaceContact> contacts, std::span<const RigidBody> bodies,
                    std::span<const Vector2d> body_velocity, double dt, double weight,
                    ContactGrid grid, std::span<Vector2d> impulse) {
  // Accumulated impulse of each contact in this solve, (normal, tangential),
  // N·s: the projection bounds the sum, not each sweep's increment.
  thread_local std::vector<Vector2d> total;
  total.assign(contacts.size(), Vector2d::Zero());
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  int sweep = 0;
  while (sweep < kContactMaxSweeps) {
    ++sweep;
    double largest = 0.0;  // m/s, the largest change of a face velocity
    for (std::size_t c = 0; c < contacts.size(); ++c) {
      const SurfaceContact& contact = contacts[c];
      const RigidBody& body = bodies[contact.body];
      Vector2d face_velocity = Vector2d::Zero();
      Vector2d compliance = Vector2d::Zero();  // Σ c²/m over the free components, 1/kg
      for (int k = 0; k < contact.count; ++k) {
        const std::int32_t node = contact.node[k];
        const double m = grid.mass[node];
        if (!(m > grid.min_mass)) continue;
        const double c = contact.weight[k];
        face_velocity += c * grid.velocity[node];
        const double moved = std::max(m, contact.mass_floor);
        if (!(grid.fixed[node] & 1)) compliance.x() += c * c / moved;
        if (!(grid.fixed[node] & 2)) compliance.y() += c * c / moved;
      }
      // Applies the impulse j (N·s) at the face, spread over its nodes.
      auto apply = [&](const Vector2d& j) {
        for (int k = 0; k < contact.count; ++k) {
          const std::int32_t node = contact.node[k];
          const double m = grid.mass[node];
          if (!(m > grid.min_mass)) continue;
          Vector2d dv = (contact.weight[k] / std::max(m, contact.mass_floor)) * j;
          if (grid.fixed[node] & 1) dv.x() = 0.0;
          if (grid.fixed[node] & 2) dv.y() = 0.0;
          grid.velocity[node] += dv;
          impulse[contact.body] += (weight * m) * dv;
        }
        const Vector2d change = compliance.cwiseProduct(j);
        face_velocity += change;
        largest = std::max(largest, change.norm());
      };
      const Vector2d& n = contact.where.normal;
      const Vector2d t(-n.y(), n.x());
      const Vector2d vb = body_velocity[contact.body];
      Vector2d& acc = total[c];
      // Normal: the face may approach the body by at most the open gap.
      const double kn = compliance.x() * n.x() * n.x() + compliance.y() * n.y() * n.y();
      if (kn > 0.0) {
        const double target = -std::max(contact.where.gap, 0.0) / dt;
        const double next = std::max(0.0, acc.x() + (target - (face_velocity - vb).dot(n)) / kn);
        const double dj = next - acc.x();
        acc.x() = next;
        if (dj != 0.0) apply(dj * n);
      }
      if (body.contact == ContactKind::kSmooth) continue;
      // Tangential: no slip, within Coulomb's bound on the normal impulse.
      const double kt = compliance.x() * t.x() * t.x() + compliance.y() * t.y() * t.y();
      if (!(kt > 0.0)) continue;
      const double bound = body.contact == ContactKind::kRough ? (acc.x() > 0.0 ? kInfinity : 0.0)
                                                               : body.friction * acc.x();
      const double next = std::clamp(acc.y() - (face_velocity - vb).dot(t) / kt, -bound, bound);
      const double dj = next - acc.y();
      acc.y() = next;
      if (dj != 0.0) apply(dj * t);
    }
    if (largest <= kContactTolerance) break;
  }
  return sweep;
}

double CornerOverhang(const RigidBody& body, const Vector2d& center,
                      std::span<const Vector2d> position, std::span<const Vector2d> half_size,
                      const Vector2d& origin, double h) {
  if (body.shape != RigidBody::Shape::kRectangle) return 0.0;
  const Vector2d lower = center - body.half_size, upper = center + body.half_size;
  // Rounding of positions must neither flag a corner on a node line nor
  // miss a box that ends at one.
  const double tol = 1e-9 * h;
  double overhang = 0.0;
  for (std::size_t p = 0; p < position.size(); ++p) {
    const Vector2d lo = position[p] - half_size[p], hi = position[p] + half_size[p];
    for (int a = 0; a < 2; ++a) {
      const int b = 1 - a;  // along the face
      // Does the box face the body's face normal to a, within one cell?
      const bool below = hi[a] <= lower[a] + tol && hi[a] >= lower[a] - h;
      const bool above = lo[a] >= upper[a] - tol && lo[a] <= upper[a] + h;
      if (!below && !above) continue;
      for (const double end : {lower[b], upper[b]}) {
        if (lo[b] > end + tol || hi[b] < end - tol) continue;  // no soil at this corner
        const double cells = (end - origin[b]) / h;
        const double line =
            origin[b] + h * (end == upper[b] ? std::ceil(cells - 1e-9) : std::floor(cells + 1e-9));
        if (std::abs(line - end) > tol) overhang = std::max(overhang, std::abs(line - end));
      }
    }
  }
  return overhang;
}

double BodyShareOfNode(const RigidBody& body, const Vector2d& center, const Vector2d& node,
                       double h, const Vector2d& lower, const Vector2d& upper) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  if (body.shape == RigidBody::Shape::kRectangle) {
    const Vector2d a = center - body.half_size, b = center + body.half_size;
    return HatShare(a.x(), b.x(), node.x(), h, lower.x(), upper.x()) *
           HatShare(a.y(), b.y(), node.y(), h, lower.y(), upper.y());
  }
  // A circle: exact where the support lies wholly outside or inside it.
  const double distance = (node - center).norm() - body.radius;  // m, outside +
  if (distance >= std::sqrt(2.0) * h) return 0.0;
  if (distance <= -std::sqrt(2.0) * h) {
    return HatShare(-kInfinity, kInfinity, node.x(), h, lower.x(), upper.x()) *
           HatShare(-kInfinity, kInfinity, node.y(), h, lower.y(), upper.y());
  }
  constexpr int kSamples = 16;  // per axis over the support 2h; the grid's lines are sample edges
  const double step = 2.0 * h / kSamples;
  double share = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    const double x = node.x() - h + (i + 0.5) * step;
    if (x < lower.x() || x > upper.x()) continue;
    const double wx = 1.0 - std::abs(x - node.x()) / h;
    for (int j = 0; j < kSamples; ++j) {
      const double y = node.y() - h + (j + 0.5) * step;
      if (y < lower.y() || y > upper.y()) continue;
      if ((Vector2d(x, y) - center).squaredNorm() > body.radius * body.radius) continue;
      share += wx * (1.0 - std::abs(y - node.y()) / h);
    }
  }
  return share * (step / h) * (step / h);
}

}  // namespace rvehub::mpm
