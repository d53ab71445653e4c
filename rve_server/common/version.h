// The release of RVEHub that every binary reports (server info, store files'
// created_by, run records).
#ifndef RVEHUB_RVE_SERVER_COMMON_VERSION_H_
#define RVEHUB_RVE_SERVER_COMMON_VERSION_H_

namespace rvehub {

inline constexpr char kVersion[] = "0.3.0";

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_VERSION_H_
