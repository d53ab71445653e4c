// The project's one pair of Status macros, for every layer (header-only,
// Abseil only, so the engine may use it too).
//
//   RETURN_IF_ERROR(DoThing());                   // returns its Status if not OK
//   ASSIGN_OR_RETURN(Foo foo, MakeFoo(x));        // declares foo from a StatusOr
//   ASSIGN_OR_RETURN(auto rows, ReadRows(path));  // (a type with commas: use auto)
//
// The enclosing function returns absl::Status or absl::StatusOr<U>.
#ifndef RVEHUB_RVE_SERVER_COMMON_STATUS_MACROS_H_
#define RVEHUB_RVE_SERVER_COMMON_STATUS_MACROS_H_

#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define RETURN_IF_ERROR(expr)                                                                \
  do {                                                                                       \
    if (::absl::Status rvehub_status_ = (expr); !rvehub_status_.ok()) return rvehub_status_; \
  } while (false)

#define RVEHUB_STATUS_CONCAT_INNER_(a, b) a##b
#define RVEHUB_STATUS_CONCAT_(a, b) RVEHUB_STATUS_CONCAT_INNER_(a, b)
#define RVEHUB_ASSIGN_OR_RETURN_IMPL_(statusor, lhs, expr) \
  auto statusor = (expr);                                  \
  if (!statusor.ok()) return std::move(statusor).status(); \
  lhs = *std::move(statusor)

#define ASSIGN_OR_RETURN(lhs, expr) \
  RVEHUB_ASSIGN_OR_RETURN_IMPL_(RVEHUB_STATUS_CONCAT_(rvehub_statusor_, __LINE__), lhs, expr)

#endif  // RVEHUB_RVE_SERVER_COMMON_STATUS_MACROS_H_
