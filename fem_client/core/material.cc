#include "fem_client/core/material.h"

#include <string>

#include "absl/strings/cord.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace rvehub::fem {
namespace {

constexpr char kPointPayload[] = "rvehub.fem/gauss_point";

}  // namespace

absl::Status PointFailure(absl::Status status, int point) {
  if (!status.ok()) status.SetPayload(kPointPayload, absl::Cord(absl::StrCat(point)));
  return status;
}

std::optional<int> FailedPoint(const absl::Status& status) {
  const auto payload = status.GetPayload(kPointPayload);  // absl::optional
  int point = 0;
  if (!payload.has_value() || !absl::SimpleAtoi(std::string(*payload), &point)) return std::nullopt;
  return point;
}

}  // namespace rvehub::fem
