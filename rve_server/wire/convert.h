// Translation between the wire messages (proto/rvehub/v1) and the values
// every layer shares (rve_server/values): the only protobuf conversions, used
// by the server's service and by the client library alike. Pure functions;
// malformed messages give InvalidArgument naming the field.
#ifndef RVEHUB_RVE_SERVER_WIRE_CONVERT_H_
#define RVEHUB_RVE_SERVER_WIRE_CONVERT_H_

#include <Eigen/Dense>
#include <vector>

#include "absl/status/statusor.h"
#include "rve_server/values/element_test.h"
#include "rve_server/values/increment.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"
#include "rve_server/values/state.h"
#include "rvehub/v1/rve_service.pb.h"

namespace rvehub::wire {

// 3×3 row-major, 9 values.
void ToProto(const Eigen::Matrix3d& m, google::protobuf::RepeatedField<double>* out);
absl::StatusOr<Eigen::Matrix3d> Matrix3FromProto(const google::protobuf::RepeatedField<double>& v,
                                                 absl::string_view field);

void ToProto(const dem::Material& m, v1::Material* out);
dem::Material FromProto(const v1::Material& m);
void ToProto(const dem::Controls& c, v1::Controls* out);
dem::Controls FromProto(const v1::Controls& c);

void ToProto(const dem::RveSnapshot& p, v1::Packing* out);
// Shapes are checked (cell 4 values, particle and contact arrays of one
// length each); physics is checked later by dem::Rve::Create.
absl::StatusOr<dem::RveSnapshot> FromProto(const v1::Packing& p);

void ToProto(const RveRecord& r, v1::RveRecord* out);
absl::StatusOr<RveRecord> FromProto(const v1::RveRecord& r);

void ToProto(const dem::RveState& s, const Eigen::Matrix3d& deformation_gradient,
             v1::RveState* out);
// Bytes of a per-RVE message kept in an RveResult (longer ones are cut).
inline constexpr std::size_t kMaxResultMessageBytes = 512;
// RveOutcome → RveResult (code from the absl status).
void ToProto(const RveOutcome& o, v1::RveResult* out);

void ToProto(const TemplateInfo& t, v1::TemplateInfo* out);
TemplateInfo FromProto(const v1::TemplateInfo& t);
void ToProto(const RunInfo& r, v1::RunInfo* out);
RunInfo FromProto(const v1::RunInfo& r);

// Values sent as they are (a default is sent as itself); zero fields mean
// "the default" on the way back.
void ToProto(const dem::ApplyOptions& o, v1::ApplyOptions* out);
dem::ApplyOptions FromProto(const v1::ApplyOptions& o);
v1::ApplyMode ToProto(ApplyMode mode);
// InvalidArgument unless COMMIT or TRIAL.
absl::StatusOr<ApplyMode> FromProto(v1::ApplyMode mode);
// ΔF of every increment checked (9 finite values), the field named.
absl::StatusOr<std::vector<Increment>> FromProto(
    const google::protobuf::RepeatedPtrField<v1::Increment>& increments);
// InvalidArgument when neither pressure nor k0 is set.
absl::StatusOr<InitialStress> FromProto(const v1::InitialStress& s);
absl::StatusOr<dem::ElementTestSpec> FromProto(const v1::ElementTestRequest& r);
void ToProto(const dem::ElementTestRow& r, v1::ElementTestRow* out);
dem::ElementTestRow FromProto(const v1::ElementTestRow& r);

// Client side (rve_server/client): the request of an element test and the
// state of an RVE read back.
v1::ElementTest ToProto(dem::ElementTestKind kind);
// Every field of `s` as it is; the template name is the caller's.
void ToProto(const dem::ElementTestSpec& s, v1::ElementTestRequest* out);
// The inverse of ToProto(RveState): InvalidArgument for a tensor without 9
// values, DataLoss for a tangent of neither 0 nor 81 values.
absl::Status FromProto(const v1::RveState& s, dem::RveState* out,
                       Eigen::Matrix3d* deformation_gradient);
// The inverse of FromProto(InitialStress). kTemplate sets neither pressure
// nor k0: the wire has no such kind, and callers leave such stresses out.
void ToProto(const InitialStress& s, v1::InitialStress* out);
// The inverse of ToProto(RveOutcome): id, step, engine seconds (0 unless
// finite) and the status from code and message; the state and F only when
// the code is OK. An error (FromProto(RveState)'s) only for a malformed state.
absl::Status FromProto(const v1::RveResult& r, RveOutcome* out);

}  // namespace rvehub::wire

#endif  // RVEHUB_RVE_SERVER_WIRE_CONVERT_H_
