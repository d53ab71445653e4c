// Small gRPC helpers shared by the service tests.
#ifndef RVEHUB_TESTS_SUPPORT_RPC_TEST_UTIL_H_
#define RVEHUB_TESTS_SUPPORT_RPC_TEST_UTIL_H_

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "rvehub/v1/rve_service.grpc.pb.h"

namespace rvehub::service {

// The full state of one RVE through Export (an empty record, and a test
// failure, when the stream fails).
inline v1::RveRecord ExportOne(v1::RveService::Stub& stub, grpc::ClientContext& ctx,
                               const std::string& run, std::int64_t id) {
  v1::ExportRequest req;
  req.set_run_id(run);
  req.add_ids(id);
  std::unique_ptr<grpc::ClientReader<v1::RveChunk>> reader = stub.Export(&ctx, req);
  v1::RveChunk chunk;
  v1::RveRecord out;
  while (reader->Read(&chunk))
    if (chunk.records_size() > 0) out = chunk.records(0);
  EXPECT_TRUE(reader->Finish().ok());
  return out;
}

}  // namespace rvehub::service

#endif  // RVEHUB_TESTS_SUPPORT_RPC_TEST_UTIL_H_
