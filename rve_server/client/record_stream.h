// The client halves of the Export and Import streams of rvehub.v1, shared by
// rve_cli and the MPM client's remote endpoints: records converted from and
// to the wire, the declared record count checked, Import chunks kept under a
// byte budget, and a failed stream cancelled (Import is then all or nothing
// on the server). The caller opens the stream and maps its final status.
#ifndef RVEHUB_RVE_SERVER_CLIENT_RECORD_STREAM_H_
#define RVEHUB_RVE_SERVER_CLIENT_RECORD_STREAM_H_

#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <cstdint>
#include <functional>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "rve_server/values/record.h"
#include "rvehub/v1/rve_service.grpc.pb.h"

namespace rvehub::client {

// The final status of a stream (grpc::Status, OK included) as the caller
// reports it.
using StreamStatusFn = std::function<absl::Status(const grpc::Status&)>;

// Bytes of records per Import chunk: below the smaller of the server's and
// the client's message limits (non-positive: none; 2^31 − 1 at most), with
// the headroom the server keeps for its export chunks.
std::int64_t ImportChunkBudget(std::int64_t server_max_message_bytes,
                               std::int64_t client_max_message_bytes);

// Reads the Export stream of run `run` to its end, each record converted and
// handed to `sink`. A record that does not convert (DataLoss) or an error of
// `sink` cancels the call and is returned as it is. Otherwise the stream's
// final status through `check` when that is not OK, then DataLoss when the
// stream declared another number of records than it carried.
absl::Status ReadExport(grpc::ClientContext& ctx, grpc::ClientReader<v1::RveChunk>& reader,
                        absl::string_view run, const std::function<absl::Status(RveRecord&&)>& sink,
                        const StreamStatusFn& check);

// Writes `n` records to an Import stream, `record(k, out)` filling record k,
// in chunks of at most `budget_bytes` of records (the first chunk declares
// n). A record over the budget is ResourceExhausted and cancels the call;
// otherwise the stream's final status through `check` (a broken stream's
// reason comes with it). `chunks`, when given, is set to the chunks written.
absl::Status WriteImport(grpc::ClientContext& ctx, grpc::ClientWriter<v1::RveChunk>& writer,
                         std::size_t n,
                         const std::function<void(std::size_t k, v1::RveRecord* out)>& record,
                         std::int64_t budget_bytes, const StreamStatusFn& check,
                         std::int64_t* chunks = nullptr);

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_RECORD_STREAM_H_
