// The case's "bodies" section: rigid bodies with a prescribed velocity.
#include <array>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

constexpr Table<ContactKind> kBodyContacts = {{"rough", ContactKind::kRough},
                                              {"smooth", ContactKind::kSmooth},
                                              {"frictional", ContactKind::kFrictional}};

absl::Status ParseVelocity(const Json& j, const std::string& ptr,
                           std::vector<VelocityPoint>* history) {
  std::vector<std::array<double, 3>> rows;
  RETURN_IF_ERROR(ReadTimeRows(j, ptr, 3, "[t, vx, vy] (s, m/s, m/s)", false, &rows));
  for (const auto& [t, vx, vy] : rows) history->push_back({t, Eigen::Vector2d(vx, vy)});
  return absl::OkStatus();
}

constexpr Table<RigidBody::Shape> kBodyShapes = {{"rectangle", RigidBody::Shape::kRectangle},
                                                 {"circle", RigidBody::Shape::kCircle}};
absl::string_view BodyShapeName(RigidBody::Shape shape) {
  return shape == RigidBody::Shape::kCircle ? "circle" : "rectangle";
}
bool Rectangle(const RigidBody& b) { return b.shape == RigidBody::Shape::kRectangle; }
bool Circle(const RigidBody& b) { return b.shape == RigidBody::Shape::kCircle; }

Fields<RigidBody> BodyFields() {
  return {
      NameField<RigidBody>(),
      EnumField("shape", &RigidBody::shape, Need::kRequired, "body shape", kBodyShapes,
                &BodyShapeName),
      Vec2Field("center", &RigidBody::center, Need::kRequired, kAny),
      Only(&Rectangle, "only for shape \"rectangle\"",
           Vec2Field("half_size", &RigidBody::half_size, Need::kRequired, kPositive)),
      Only(&Circle, "only for shape \"circle\"",
           NumberField("radius", &RigidBody::radius, Need::kRequired, kPositive)),
      EnumField("contact", &RigidBody::contact, Need::kOptional, "body contact", kBodyContacts,
                &ContactKindName),
      FrictionField<RigidBody>("contact"),
      {"velocity",
       [](const Object& o, RigidBody* b) -> absl::Status {
         const Json* v = o.Get("velocity");
         return v == nullptr ? absl::OkStatus() : ParseVelocity(*v, o.At("velocity"), &b->velocity);
       },
       [](const RigidBody& b, OrderedJson& j) {
         OrderedJson& velocity = j["velocity"] = OrderedJson::array();
         for (const VelocityPoint& p : b.velocity) {
           velocity.push_back(OrderedJson::array({p.time, p.velocity.x(), p.velocity.y()}));
         }
       }},
  };
}

}  // namespace

absl::Status ParseBody(const Json& j, const std::string& ptr, RigidBody* b) {
  return ReadFields(j, ptr, BodyFields(), b).status();
}

OrderedJson WriteBody(const RigidBody& b) { return WriteFields(BodyFields(), b); }

}  // namespace rvehub::mpm::case_internal
