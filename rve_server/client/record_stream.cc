#include "rve_server/client/record_stream.h"

#include <algorithm>
#include <limits>
#include <utility>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/wire/convert.h"

namespace rvehub::client {
namespace {

// Headroom below the message limit for framing, as the server keeps for its
// export chunks, bytes.
constexpr std::int64_t kChunkOverheadBytes = 64 << 10;

// Bytes of an empty chunk, and of a record's field tag and length prefix.
constexpr std::int64_t kFramingBytes = 16;

}  // namespace

std::int64_t ImportChunkBudget(std::int64_t server_max_message_bytes,
                               std::int64_t client_max_message_bytes) {
  std::int64_t limit = std::numeric_limits<std::int32_t>::max();
  if (server_max_message_bytes > 0) limit = std::min(limit, server_max_message_bytes);
  if (client_max_message_bytes > 0) limit = std::min(limit, client_max_message_bytes);
  return std::max(limit - kChunkOverheadBytes, limit / 2);
}

absl::Status ReadExport(grpc::ClientContext& ctx, grpc::ClientReader<v1::RveChunk>& reader,
                        absl::string_view run, const std::function<absl::Status(RveRecord&&)>& sink,
                        const StreamStatusFn& check) {
  v1::RveChunk chunk;
  std::int64_t declared = -1, received = 0;
  absl::Status failed;
  while (failed.ok() && reader.Read(&chunk)) {
    if (declared < 0) declared = chunk.total_records();
    for (const v1::RveRecord& r : chunk.records()) {
      absl::StatusOr<RveRecord> record = wire::FromProto(r);
      if (!record.ok()) {
        failed =
            absl::DataLossError(absl::StrCat("run \"", run, "\" record ", received, " (id ", r.id(),
                                             ") is malformed: ", record.status().message()));
        break;
      }
      failed = sink(*std::move(record));
      if (!failed.ok()) break;
      ++received;
    }
  }
  if (!failed.ok()) {
    ctx.TryCancel();
    (void)reader.Finish();  // the stream is abandoned; its status adds nothing
    return failed;
  }
  RETURN_IF_ERROR(check(reader.Finish()));
  if (declared > 0 && declared != received) {
    return absl::DataLossError(absl::StrCat("export of run \"", run, "\" declared ", declared,
                                            " records but carried ", received));
  }
  return absl::OkStatus();
}

absl::Status WriteImport(grpc::ClientContext& ctx, grpc::ClientWriter<v1::RveChunk>& writer,
                         std::size_t n,
                         const std::function<void(std::size_t k, v1::RveRecord* out)>& record,
                         std::int64_t budget_bytes, const StreamStatusFn& check,
                         std::int64_t* chunks) {
  v1::RveChunk chunk;
  chunk.set_total_records(static_cast<std::int64_t>(n));
  std::int64_t chunk_bytes = kFramingBytes, written = 0;
  if (chunks != nullptr) *chunks = 0;
  bool stream_ok = true;
  absl::Status failed;
  for (std::size_t k = 0; k < n; ++k) {
    v1::RveRecord r;
    record(k, &r);
    const std::int64_t size = static_cast<std::int64_t>(r.ByteSizeLong()) + kFramingBytes;
    if (size > budget_bytes) {
      failed = absl::ResourceExhaustedError(
          absl::StrCat("RVE (\"", r.run_id(), "\", ", r.id(), ") takes ", size,
                       " bytes, over the budget of ", budget_bytes, " bytes per Import message"));
      break;
    }
    if (chunk.records_size() > 0 && chunk_bytes + size > budget_bytes) {
      stream_ok = writer.Write(chunk);
      if (!stream_ok) break;
      ++written;
      chunk.Clear();
      chunk_bytes = kFramingBytes;
    }
    *chunk.add_records() = std::move(r);
    chunk_bytes += size;
  }
  if (!failed.ok()) {
    ctx.TryCancel();  // the server then drops what it got (all or nothing)
    (void)writer.Finish();
    return failed;
  }
  if (stream_ok && chunk.records_size() > 0) {
    stream_ok = writer.Write(chunk);
    if (stream_ok) ++written;
  }
  if (stream_ok) writer.WritesDone();
  if (chunks != nullptr) *chunks = written;
  // A broken stream's reason comes with Finish.
  return check(writer.Finish());
}

}  // namespace rvehub::client
