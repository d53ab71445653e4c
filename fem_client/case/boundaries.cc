// The case's "boundaries" section: one condition per face of the mesh, and
// the checks that they make a well-posed problem together.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "fem_client/case/sections.h"

namespace rvehub::fem::case_internal {
namespace {

constexpr Table<Face> kFaces = {
    {"left", Face::kLeft}, {"right", Face::kRight}, {"bottom", Face::kBottom}, {"top", Face::kTop}};

constexpr Table<BoundaryKind> kKinds = {
    {"fixed", BoundaryKind::kFixed},       {"roller", BoundaryKind::kRoller},
    {"platen", BoundaryKind::kPlaten},     {"pressure", BoundaryKind::kPressure},
    {"periodic", BoundaryKind::kPeriodic}, {"shear", BoundaryKind::kShear}};

constexpr Table<Contact> kContacts = {{"smooth", Contact::kSmooth}, {"rough", Contact::kRough}};

constexpr Table<Pin> kPins = {{"start", Pin::kStart}, {"middle", Pin::kMiddle}, {"end", Pin::kEnd}};

absl::string_view ContactName(Contact c) { return c == Contact::kRough ? "rough" : "smooth"; }

absl::string_view PinName(Pin pin) {
  switch (pin) {
    case Pin::kNone:
      break;
    case Pin::kStart:
      return "start";
    case Pin::kMiddle:
      return "middle";
    case Pin::kEnd:
      return "end";
  }
  return "none";
}

bool IsPlaten(const BoundarySpec& b) { return b.kind == BoundaryKind::kPlaten; }
bool IsPressure(const BoundarySpec& b) { return b.kind == BoundaryKind::kPressure; }
bool IsRoller(const BoundarySpec& b) { return b.kind == BoundaryKind::kRoller; }

// The axis normal to a face: 0 (x) for left and right, 1 (y) for bottom and top.
int NormalAxis(Face face) { return face == Face::kLeft || face == Face::kRight ? 0 : 1; }

Face Opposite(Face face) {
  switch (face) {
    case Face::kLeft:
      return Face::kRight;
    case Face::kRight:
      return Face::kLeft;
    case Face::kBottom:
      return Face::kTop;
    case Face::kTop:
      break;
  }
  return Face::kBottom;
}

// Which displacements a boundary holds (prescribed or zero), x and y.
std::array<bool, 2> Holds(const BoundarySpec& b) {
  const int n = NormalAxis(b.face);
  std::array<bool, 2> held = {false, false};
  switch (b.kind) {
    case BoundaryKind::kFixed:
    case BoundaryKind::kShear:
      held = {true, true};
      break;
    case BoundaryKind::kRoller:
      held[n] = true;
      held[1 - n] = b.pin != Pin::kNone;
      break;
    case BoundaryKind::kPlaten:
      held[n] = true;
      held[1 - n] = b.contact == Contact::kRough;
      break;
    case BoundaryKind::kPressure:
    case BoundaryKind::kPeriodic:
      break;
  }
  return held;
}

// `mesh`: for the pin's node (null when only writing).
Fields<BoundarySpec> BoundaryFields(const MeshSpec* mesh) {
  return {
      NameField<BoundarySpec>(),
      EnumField("face", &BoundarySpec::face, Need::kRequired, "face", kFaces, &FaceName),
      {"kind",
       [](const Object& o, BoundarySpec* b) -> absl::Status {
         RETURN_IF_ERROR(GetEnum(o, "kind", Need::kRequired, "boundary kind", kKinds, &b->kind));
         // Periodicity pairs the side faces; the simple-shear platen is the
         // top, over a fixed base (G&Z §5).
         if (b->kind == BoundaryKind::kPeriodic && NormalAxis(b->face) != 0) {
           return Bad(o.At("kind"), "periodic boundaries pair the left and right faces, not the ",
                      FaceName(b->face));
         }
         if (b->kind == BoundaryKind::kShear && b->face != Face::kTop) {
           return Bad(o.At("kind"), "the shear platen is the top face, not the ",
                      FaceName(b->face));
         }
         return absl::OkStatus();
       },
       [](const BoundarySpec& b, OrderedJson& j) { j["kind"] = BoundaryKindName(b.kind); }},
      Only(&IsPlaten, "only for kind \"platen\"",
           EnumField("contact", &BoundarySpec::contact, Need::kRequired, "contact", kContacts,
                     &ContactName)),
      Only(&IsPressure, "only for kind \"pressure\"",
           NumberField("pressure", &BoundarySpec::pressure, Need::kRequired, kPackingStress)),
      Only(&IsRoller, "only for kind \"roller\"",
           {"pin",
            [mesh](const Object& o, BoundarySpec* b) -> absl::Status {
              RETURN_IF_ERROR(GetEnum(o, "pin", Need::kOptional, "pin", kPins, &b->pin));
              const int nodes = NodesAlongFace(*mesh, b->face);
              if (b->pin == Pin::kMiddle && nodes % 2 == 0) {
                return Bad(o.At("pin"), "the ", FaceName(b->face), " face has ", nodes,
                           " nodes, none at its middle (", nodes - 1, " ",
                           ElementName(mesh->element),
                           " elements along it): pin \"start\" or \"end\", or use an even "
                           "number of elements");
              }
              return absl::OkStatus();
            },
            [](const BoundarySpec& b, OrderedJson& j) {
              if (b.pin != Pin::kNone) j["pin"] = PinName(b.pin);
            }}),
  };
}

}  // namespace

absl::string_view FaceName(Face face) {
  switch (face) {
    case Face::kLeft:
      break;
    case Face::kRight:
      return "right";
    case Face::kBottom:
      return "bottom";
    case Face::kTop:
      return "top";
  }
  return "left";
}

absl::string_view BoundaryKindName(BoundaryKind kind) {
  switch (kind) {
    case BoundaryKind::kFixed:
      break;
    case BoundaryKind::kRoller:
      return "roller";
    case BoundaryKind::kPlaten:
      return "platen";
    case BoundaryKind::kPressure:
      return "pressure";
    case BoundaryKind::kPeriodic:
      return "periodic";
    case BoundaryKind::kShear:
      return "shear";
  }
  return "fixed";
}

absl::Status ParseBoundary(const Json& j, const std::string& ptr, const MeshSpec& mesh,
                           BoundarySpec* b) {
  return ReadFields(j, ptr, BoundaryFields(&mesh), b).status();
}

OrderedJson WriteBoundary(const BoundarySpec& b) { return WriteFields(BoundaryFields(nullptr), b); }

absl::Status CheckBoundaries(const std::vector<BoundarySpec>& boundaries, const std::string& ptr) {
  // The boundary on each face (its index), -1 where the face is free.
  std::array<int, 4> on_face = {-1, -1, -1, -1};
  const auto at = [&](int i, absl::string_view key = "") {
    return key.empty() ? Child(ptr, i) : Child(Child(ptr, i), key);
  };
  // "the top face is free", "the top face has roller boundary "r" (/boundaries/1)".
  const auto describe = [&](Face face) -> std::string {
    const int i = on_face[static_cast<int>(face)];
    if (i < 0) return absl::StrCat("the ", FaceName(face), " face is free");
    return absl::StrCat("the ", FaceName(face), " face has ", BoundaryKindName(boundaries[i].kind),
                        " boundary ", Quote(boundaries[i].name), " (", at(i), ")");
  };
  const auto kind_on = [&](Face face) {
    const int i = on_face[static_cast<int>(face)];
    return i < 0 ? std::optional<BoundaryKind>() : std::optional(boundaries[i].kind);
  };

  // One condition per face: two would contradict each other or say the
  // same twice.
  for (int i = 0; i < static_cast<int>(boundaries.size()); ++i) {
    int& slot = on_face[static_cast<int>(boundaries[i].face)];
    if (slot >= 0) {
      return Bad(at(i, "face"), "the ", FaceName(boundaries[i].face), " face already has boundary ",
                 Quote(boundaries[slot].name), " (", at(slot), "): one boundary per face");
    }
    slot = i;
  }

  // Periodic faces come in pairs: each left node is tied to the right node
  // at its height.
  for (Face face : {Face::kLeft, Face::kRight}) {
    const int i = on_face[static_cast<int>(face)];
    if (i >= 0 && boundaries[i].kind == BoundaryKind::kPeriodic &&
        kind_on(Opposite(face)) != BoundaryKind::kPeriodic) {
      return Bad(at(i, "kind"), "a periodic ", FaceName(face), " face needs the ",
                 FaceName(Opposite(face)), " face periodic too; ", describe(Opposite(face)));
    }
  }

  // Exactly one face drives the specimen; the face across a platen holds its
  // normal displacement, so the platen's travel strains the specimen instead
  // of moving it.
  int driven = -1;
  for (int i = 0; i < static_cast<int>(boundaries.size()); ++i) {
    const BoundaryKind kind = boundaries[i].kind;
    if (kind != BoundaryKind::kPlaten && kind != BoundaryKind::kShear) continue;
    if (driven >= 0) {
      return Bad(at(i, "kind"), "one boundary drives the specimen, and ",
                 BoundaryKindName(boundaries[driven].kind), " boundary ",
                 Quote(boundaries[driven].name), " (", at(driven), ") already does");
    }
    driven = i;
  }
  if (driven < 0) {
    return Bad(ptr,
               "no boundary drives the specimen: give a \"platen\" (compression) or the top's "
               "\"shear\" platen (simple shear)");
  }
  const BoundarySpec& d = boundaries[driven];
  if (d.kind == BoundaryKind::kPlaten) {
    const std::optional<BoundaryKind> across = kind_on(Opposite(d.face));
    if (across != BoundaryKind::kFixed && across != BoundaryKind::kRoller) {
      return Bad(at(driven, "face"), "a platen on the ", FaceName(d.face), " face needs the ",
                 FaceName(Opposite(d.face)),
                 " face held normal to it (fixed or roller) to push against; ",
                 describe(Opposite(d.face)));
    }
  } else {
    // G&Z §5: the base fixed, the sides periodic; the shear platen's height
    // held makes the shearing undrained at constant volume.
    if (kind_on(Face::kBottom) != BoundaryKind::kFixed) {
      return Bad(at(driven, "kind"), "the shear platen needs the bottom face fixed; ",
                 describe(Face::kBottom));
    }
    if (kind_on(Face::kLeft) != BoundaryKind::kPeriodic) {
      return Bad(at(driven, "kind"),
                 "the shear platen needs periodic left and right faces (simple shear); ",
                 describe(Face::kLeft));
    }
  }

  // Without a support in x or in y the specimen can move as a rigid body and
  // the stiffness matrix is singular.
  std::array<bool, 2> held = {false, false};
  for (const BoundarySpec& b : boundaries) {
    const std::array<bool, 2> h = Holds(b);
    held[0] = held[0] || h[0];
    held[1] = held[1] || h[1];
  }
  for (int axis = 0; axis < 2; ++axis) {
    if (held[axis]) continue;
    return Bad(ptr, "nothing holds the specimen in ", axis == 0 ? "x" : "y",
               ", so it can move as a rigid body: give a fixed face, a roller on the ",
               axis == 0 ? "left or right" : "bottom or top",
               " face, a rough platen or a pin on a ",
               axis == 0 ? "bottom or top" : "left or right", " roller");
  }
  return absl::OkStatus();
}

}  // namespace rvehub::fem::case_internal
