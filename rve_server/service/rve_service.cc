#include "rve_server/service/rve_service.h"

#include <google/protobuf/arena.h>
#include <grpcpp/impl/codegen/method_handler.h>

#include <algorithm>
#include <atomic>
#include <functional>
#include <new>
#include <stdexcept>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/element_test.h"
#include "rve_server/service/log.h"
#include "rve_server/wire/convert.h"

namespace rvehub::service {

// The wire conversions (rve_server/wire/convert.h).
using wire::FromProto;
using wire::kMaxResultMessageBytes;
using wire::ToProto;

namespace {

constexpr std::int64_t kChunkOverheadBytes = 64 << 10;  // headroom below the message limit

std::vector<std::int64_t> Ids(const google::protobuf::RepeatedField<std::int64_t>& ids) {
  return {ids.begin(), ids.end()};
}

// Deadline or cancellation of the call, as the registry's CancelFn (asked
// once per RVE, from any worker). The deadline is a clock read; asking gRPC
// whether the client cancelled polls the call's completion queue (a syscall,
// ~20 µs here), so that is done at most every kCancelPollInterval.
constexpr auto kCancelPollInterval = std::chrono::milliseconds(5);

// Index of a method among the service's: gRPC adds them in the proto's order.
int MethodIndex(const char* name) {
  return v1::ApplyRequest::descriptor()
      ->file()
      ->FindServiceByName("RveService")
      ->FindMethodByName(name)
      ->index();
}

// Arena blocks for ApplyOnArena: after a first small block, blocks of up to
// 64 KB, a few dozen for a reply of 2048 RVEs (~1 MB).
google::protobuf::ArenaOptions ReplyArenaOptions() {
  google::protobuf::ArenaOptions options;
  options.start_block_size = 4 << 10;
  options.max_block_size = 64 << 10;
  return options;
}

// A handler's body, with allocation failures turned into RESOURCE_EXHAUSTED:
// a last line of defence only (validation refuses requests that would need
// that much); gRPC would otherwise answer UNKNOWN.
template <typename F>
grpc::Status GuardHandler(const char* method, F&& body) {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    Log("error", "out of memory", {{"method", method}});
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        absl::StrCat(method, ": the server ran out of memory for this request"));
  } catch (const std::length_error&) {
    Log("error", "array too large", {{"method", method}});
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        absl::StrCat(method,
                                     ": the request needs a larger array than the server "
                                     "allows"));
  }
}

// Serialised bytes of one RveResult at most: every int64 at its widest, the
// state with a tangent (or not) or a message of the longest kept length.
std::int64_t MaxResultBytes(bool want_tangent) {
  auto widest = [](v1::RveResult& r) {
    r.set_id(-1);
    r.set_code(-1);
    r.set_step(-1);
    r.set_engine_seconds(1.0);
  };
  v1::RveResult with_state;
  widest(with_state);
  dem::RveState state;
  if (want_tangent) state.tangent.emplace(Eigen::Matrix<double, 9, 9>::Zero());
  ToProto(state, Eigen::Matrix3d::Identity(), with_state.mutable_state());
  // Zero scalars are not serialised: set every one.
  v1::RveState* st = with_state.mutable_state();
  for (auto set : {&v1::RveState::set_fabric_anisotropy, &v1::RveState::set_void_ratio,
                   &v1::RveState::set_porosity, &v1::RveState::set_coordination,
                   &v1::RveState::set_mechanical_coordination, &v1::RveState::set_permeability,
                   &v1::RveState::set_mean_rotation, &v1::RveState::set_kinetic_energy,
                   &v1::RveState::set_unbalanced_force_ratio, &v1::RveState::set_volume,
                   &v1::RveState::set_time_step, &v1::RveState::set_mass_scale,
                   &v1::RveState::set_mean_pressure, &v1::RveState::set_deviator_stress}) {
    (st->*set)(1.0);
  }
  st->set_num_contacts(-1);
  st->set_steps(-1);
  st->set_fabric_defined(true);
  v1::RveResult with_message;
  widest(with_message);
  with_message.set_message(std::string(kMaxResultMessageBytes, 'x'));
  return static_cast<std::int64_t>(
             std::max(with_state.ByteSizeLong(), with_message.ByteSizeLong())) +
         4;  // field tag and length of the repeated entry
}

// One page of a listing (see ListTemplatesRequest): the entries after
// `page_token` in key order, as `list(after, limit)` gives them, at most
// `page_size` (0: no count) and while they fit in `budget` bytes; the token
// of the next page when more follow.
template <typename T, typename M, typename ListFn, typename KeyFn>
grpc::Status ListPage(const char* what, std::int32_t page_size, const std::string& page_token,
                      std::int64_t budget, const ListFn& list, const KeyFn& key,
                      google::protobuf::RepeatedPtrField<M>* out, std::string* next_page_token) {
  if (page_size < 0) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        absl::StrCat(what, ": page_size = ", page_size,
                                     " must be >= 0 (0: as many as fit in one reply)"));
  }
  if (!page_token.empty()) {
    if (absl::Status s = ValidateName("page_token", page_token); !s.ok()) {
      return grpc::Status(
          grpc::StatusCode::INVALID_ARGUMENT,
          absl::StrCat(what, ": ", s.message(), " (give a reply's next_page_token, or none)"));
    }
  }
  // A few hundred at a time: a page of a long list costs its own entries.
  constexpr std::size_t kBatch = 256;
  const std::size_t limit = page_size > 0 ? static_cast<std::size_t>(page_size) : SIZE_MAX;
  std::string cursor = page_token;
  std::size_t count = 0;
  std::int64_t bytes = 0;
  bool more = false;
  while (!more) {
    // One past the page's count, to know whether more follow.
    const std::size_t want = limit - count < kBatch ? limit - count + 1 : kBatch;
    const std::vector<T> batch = list(cursor, want);
    for (const T& entry : batch) {
      M message;
      ToProto(entry, &message);
      const auto size = static_cast<std::int64_t>(message.ByteSizeLong()) + 8;  // tag, length
      if (count == limit || (count > 0 && bytes + size > budget)) {
        more = true;
        break;
      }
      *out->Add() = std::move(message);
      bytes += size;
      ++count;
      cursor = key(entry);
    }
    if (batch.size() < want) break;
  }
  if (more) *next_page_token = cursor;
  return grpc::Status::OK;
}

}  // namespace

CancelFn RveServiceImpl::Canceller(grpc::ServerContext* ctx) const {
  struct State {
    std::atomic<std::int64_t> next_poll_ns{0};
    std::atomic<bool> cancelled{false};
  };
  auto state = std::make_shared<State>();
  const std::atomic<bool>* cancel_all = &cancel_all_;
  return [ctx, state, cancel_all]() -> absl::Status {
    if (cancel_all->load(std::memory_order_relaxed)) {
      return absl::CancelledError("the server is shutting down and the drain time ran out");
    }
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::system_clock::now() > ctx->deadline())
      return absl::DeadlineExceededError("the call's deadline passed");
    const std::int64_t now_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(now.time_since_epoch()).count();
    std::int64_t next = state->next_poll_ns.load(std::memory_order_relaxed);
    if (now_ns >= next &&
        state->next_poll_ns.compare_exchange_strong(
            next, now_ns + std::chrono::nanoseconds(kCancelPollInterval).count())) {
      if (ctx->IsCancelled()) state->cancelled = true;
    }
    if (state->cancelled) return absl::CancelledError("the call was cancelled");
    return absl::OkStatus();
  };
}

namespace {

std::string Peer(grpc::ServerContext* ctx) { return ctx->peer(); }

}  // namespace

grpc::Status RveServiceImpl::CheckReplySize(std::int64_t count, bool want_tangent,
                                            const char* what) const {
  static const std::int64_t kWithTangent = MaxResultBytes(true);
  static const std::int64_t kWithout = MaxResultBytes(false);
  const std::int64_t each = want_tangent ? kWithTangent : kWithout;
  const std::int64_t budget = options_.max_message_bytes - kChunkOverheadBytes;
  if (count * each <= budget) return grpc::Status::OK;
  return grpc::Status(
      grpc::StatusCode::INVALID_ARGUMENT,
      absl::StrCat(what, ": the reply for ", count, " RVEs", want_tangent ? " with tangents" : "",
                   " could take ", count * each, " bytes, over the server's message limit of ",
                   options_.max_message_bytes, " bytes; ask for at most ",
                   std::max<std::int64_t>(1, budget / each), " per call. Nothing was changed"));
}

grpc::Status ToGrpc(const absl::Status& s) {
  if (s.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(s.code()), std::string(s.message()));
}

bool Authorized(const std::multimap<grpc::string_ref, grpc::string_ref>& metadata,
                const std::string& token) {
  if (token.empty()) return true;
  auto it = metadata.find("authorization");
  if (it == metadata.end()) return false;
  const std::string_view value(it->second.data(), it->second.size());
  const std::string expected = absl::StrCat("Bearer ", token);
  // Compare every byte whatever the first mismatch (no timing hint).
  if (value.size() != expected.size()) return false;
  unsigned char diff = 0;
  for (std::size_t k = 0; k < value.size(); ++k) diff |= value[k] ^ expected[k];
  return diff == 0;
}

RveServiceImpl::RveServiceImpl(Registry& registry, ServiceOptions options)
    : registry_(registry),
      options_(std::move(options)),
      started_(std::chrono::steady_clock::now()) {
  MarkMethodStreamed(
      MethodIndex("Apply"),
      new grpc::internal::StreamedUnaryHandler<grpc::ByteBuffer, grpc::ByteBuffer>(
          [this](grpc::ServerContext* ctx,
                 grpc::ServerUnaryStreamer<grpc::ByteBuffer, grpc::ByteBuffer>* stream) {
            return GuardHandler("Apply", [&] { return ApplyOnArena(ctx, stream); });
          }));
  MarkMethodStreamed(
      MethodIndex("Import"),
      new grpc::internal::ClientStreamingHandler<RveServiceImpl, grpc::ByteBuffer,
                                                 v1::ImportResponse>(
          [](RveServiceImpl* service, grpc::ServerContext* ctx,
             grpc::ServerReader<grpc::ByteBuffer>* reader, v1::ImportResponse* resp) {
            return GuardHandler("Import", [&] { return service->ImportBytes(ctx, reader, resp); });
          },
          this));
}

grpc::Status RveServiceImpl::UploadTemplate(grpc::ServerContext* ctx,
                                            const v1::UploadTemplateRequest* req,
                                            v1::TemplateInfo* resp) {
  return GuardHandler("UploadTemplate", [&] { return DoUploadTemplate(ctx, req, resp); });
}
grpc::Status RveServiceImpl::CreateRves(grpc::ServerContext* ctx, const v1::CreateRvesRequest* req,
                                        v1::CreateRvesResponse* resp) {
  return GuardHandler("CreateRves", [&] { return DoCreateRves(ctx, req, resp); });
}
grpc::Status RveServiceImpl::Apply(grpc::ServerContext* ctx, const v1::ApplyRequest* req,
                                   v1::ApplyResponse* resp) {
  return GuardHandler("Apply", [&] { return DoApply(ctx, req, resp); });
}
grpc::Status RveServiceImpl::GetStates(grpc::ServerContext* ctx, const v1::GetStatesRequest* req,
                                       v1::GetStatesResponse* resp) {
  return GuardHandler("GetStates", [&] { return DoGetStates(ctx, req, resp); });
}
grpc::Status RveServiceImpl::Export(grpc::ServerContext* ctx, const v1::ExportRequest* req,
                                    grpc::ServerWriter<v1::RveChunk>* writer) {
  return GuardHandler("Export", [&] { return DoExport(ctx, req, writer); });
}
grpc::Status RveServiceImpl::Import(grpc::ServerContext*, grpc::ServerReader<v1::RveChunk>*,
                                    v1::ImportResponse*) {
  return grpc::Status(grpc::StatusCode::INTERNAL, "Import is served by ImportBytes");
}
grpc::Status RveServiceImpl::Drop(grpc::ServerContext* ctx, const v1::DropRequest* req,
                                  v1::DropResponse* resp) {
  return GuardHandler("Drop", [&] { return DoDrop(ctx, req, resp); });
}
grpc::Status RveServiceImpl::RunElementTest(grpc::ServerContext* ctx,
                                            const v1::ElementTestRequest* req,
                                            grpc::ServerWriter<v1::ElementTestUpdate>* writer) {
  return GuardHandler("RunElementTest", [&] { return DoRunElementTest(ctx, req, writer); });
}

grpc::Status RveServiceImpl::CheckAuth(grpc::ServerContext* ctx) const {
  if (Authorized(ctx->client_metadata(), options_.auth_token)) return grpc::Status::OK;
  Log("warn", "unauthenticated", {{"peer", Peer(ctx)}});
  return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                      "this server needs \"authorization: Bearer <token>\" metadata");
}

grpc::Status RveServiceImpl::DoUploadTemplate(grpc::ServerContext* ctx,
                                              const v1::UploadTemplateRequest* req,
                                              v1::TemplateInfo* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  if (!req->has_entry()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "entry (the template) is missing");
  }
  absl::StatusOr<dem::RveSnapshot> packing = FromProto(req->entry().packing());
  if (!packing.ok()) return ToGrpc(packing.status());
  TemplateRecord record{req->entry().name(), req->entry().description(), *std::move(packing)};
  absl::StatusOr<TemplateInfo> s = registry_.PutTemplate(std::move(record), req->replace());
  if (!s.ok()) return ToGrpc(s.status());
  ToProto(*s, resp);
  Log("info", "template uploaded",
      {{"name", s->name}, {"particles", absl::StrCat(s->num_particles)}});
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::ListTemplates(grpc::ServerContext* ctx,
                                           const v1::ListTemplatesRequest* req,
                                           v1::ListTemplatesResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  return ListPage<TemplateInfo>(
      "ListTemplates", req->page_size(), req->page_token(),
      options_.max_message_bytes - kChunkOverheadBytes,
      [&](absl::string_view after, std::size_t limit) {
        return registry_.ListTemplates(after, limit);
      },
      [](const TemplateInfo& t) { return t.name; }, resp->mutable_templates(),
      resp->mutable_next_page_token());
}

grpc::Status RveServiceImpl::DoCreateRves(grpc::ServerContext* ctx,
                                          const v1::CreateRvesRequest* req,
                                          v1::CreateRvesResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  if (req->want_state()) {
    if (grpc::Status r = CheckReplySize(req->ids_size(), false, "CreateRves"); !r.ok()) return r;
  }
  if (req->has_initial_stress() && req->initial_stresses_size() > 0) {
    return grpc::Status(
        grpc::StatusCode::INVALID_ARGUMENT,
        "give initial_stress (one for all) or initial_stresses (one per id), not both");
  }
  std::vector<InitialStress> initial;
  if (req->has_initial_stress()) {
    absl::StatusOr<InitialStress> one = FromProto(req->initial_stress());
    if (!one.ok()) return ToGrpc(one.status());
    initial.push_back(*one);
  }
  for (int k = 0; k < req->initial_stresses_size(); ++k) {
    absl::StatusOr<InitialStress> one = FromProto(req->initial_stresses(k));
    if (!one.ok()) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          absl::StrCat("initial_stresses[", k, "]: ", one.status().message()));
    }
    initial.push_back(*one);
  }
  std::optional<dem::Controls> controls;
  if (req->has_controls()) controls = FromProto(req->controls());
  const std::vector<std::int64_t> ids = Ids(req->ids());
  const auto t0 = std::chrono::steady_clock::now();
  absl::StatusOr<std::vector<RveOutcome>> out =
      registry_.Create(req->run_id(), req->template_name(), ids, initial, controls,
                       req->want_state(), Canceller(ctx));
  if (!out.ok()) return ToGrpc(out.status());
  for (const RveOutcome& o : *out) {
    v1::RveResult* r = resp->add_results();
    r->set_id(o.id);
    r->set_step(o.step);
    if (req->want_state()) ToProto(o.state, o.deformation_gradient, r->mutable_state());
  }
  Log("info", "created",
      {{"run", req->run_id()},
       {"template", req->template_name()},
       {"count", absl::StrCat(ids.size())},
       {"seconds",
        absl::StrCat(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count())}});
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::DoApply(grpc::ServerContext* ctx, const v1::ApplyRequest* req,
                                     v1::ApplyResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  // Sized before anything is computed: a COMMIT that could not be answered
  // would commit and fail on every retry.
  if (grpc::Status r =
          CheckReplySize(req->increments_size(), req->options().want_tangent(), "Apply");
      !r.ok()) {
    return r;
  }
  absl::StatusOr<ApplyMode> mode = FromProto(req->mode());
  if (!mode.ok()) return ToGrpc(mode.status());
  const dem::ApplyOptions options = FromProto(req->options());
  absl::StatusOr<std::vector<Increment>> increments = FromProto(req->increments());
  if (!increments.ok()) return ToGrpc(increments.status());
  // One result per increment, made here so that the workers only fill them
  // in (distinct messages: no lock; on an arena, allocation is thread-safe).
  // None for a batch over the limit (ApplyEach refuses it).
  google::protobuf::RepeatedPtrField<v1::RveResult>* results = resp->mutable_results();
  if (static_cast<std::int64_t>(increments->size()) <= registry_.options().max_batch) {
    results->Reserve(static_cast<int>(increments->size()));
    for (std::size_t k = 0; k < increments->size(); ++k) results->Add();
  }
  std::atomic<std::int64_t> failed{0};
  const absl::Status s =
      registry_.ApplyEach(req->run_id(), req->step(), *mode, options, *increments, Canceller(ctx),
                          [&](std::size_t k, RveOutcome&& o) {
                            if (!o.status.ok()) failed.fetch_add(1, std::memory_order_relaxed);
                            ToProto(o, results->Mutable(static_cast<int>(k)));
                          });
  if (!s.ok()) return ToGrpc(s);
  resp->set_failed(failed.load());
  if (failed > 0) {
    Log("warn", "apply had failures",
        {{"run", req->run_id()},
         {"step", absl::StrCat(req->step())},
         {"failed", absl::StrCat(failed.load())},
         {"of", absl::StrCat(increments->size())}});
  }
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::ApplyOnArena(
    grpc::ServerContext* ctx,
    grpc::ServerUnaryStreamer<grpc::ByteBuffer, grpc::ByteBuffer>* stream) {
  google::protobuf::Arena arena(ReplyArenaOptions());
  auto* req = google::protobuf::Arena::CreateMessage<v1::ApplyRequest>(&arena);
  auto* resp = google::protobuf::Arena::CreateMessage<v1::ApplyResponse>(&arena);
  grpc::ByteBuffer bytes;
  if (!stream->Read(&bytes)) {
    return grpc::Status(grpc::StatusCode::CANCELLED, "Apply: the request never arrived");
  }
  if (!grpc::SerializationTraits<v1::ApplyRequest>::Deserialize(&bytes, req).ok()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "Apply: the request is not a valid ApplyRequest message");
  }
  if (grpc::Status s = DoApply(ctx, req, resp); !s.ok()) return s;
  bool own_buffer = false;
  if (grpc::Status s =
          grpc::SerializationTraits<v1::ApplyResponse>::Serialize(*resp, &bytes, &own_buffer);
      !s.ok()) {
    return s;
  }
  stream->Write(bytes);  // false: the client has gone; the status tells it nothing more
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::DoGetStates(grpc::ServerContext* ctx, const v1::GetStatesRequest* req,
                                         v1::GetStatesResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  if (absl::Status n = ValidateName("run id", req->run_id()); !n.ok()) return ToGrpc(n);
  const std::vector<std::int64_t> ids = Ids(req->ids());
  const std::int64_t count =
      ids.empty() ? registry_.CountRves(req->run_id()) : static_cast<std::int64_t>(ids.size());
  if (grpc::Status r = CheckReplySize(count, req->want_tangent(), "GetStates"); !r.ok()) return r;
  absl::StatusOr<std::vector<RveOutcome>> out =
      registry_.Get(req->run_id(), ids, req->want_tangent());
  if (!out.ok()) return ToGrpc(out.status());
  for (const RveOutcome& o : *out) ToProto(o, resp->add_results());
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::DoExport(grpc::ServerContext* ctx, const v1::ExportRequest* req,
                                      grpc::ServerWriter<v1::RveChunk>* writer) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  const std::vector<std::int64_t> ids = Ids(req->ids());
  // Chunks stay below the message limit with headroom for framing.
  const std::int64_t budget = std::max<std::int64_t>(
      options_.max_message_bytes - kChunkOverheadBytes, options_.max_message_bytes / 2);
  std::int64_t chunk_bytes = 0;  // serialised size of the records in `chunk`
  v1::RveChunk chunk;
  std::int64_t sent = 0;
  const std::int64_t total =
      ids.empty() ? registry_.CountRves(req->run_id()) : static_cast<std::int64_t>(ids.size());
  auto flush = [&]() -> absl::Status {
    if (chunk.records_size() == 0) return absl::OkStatus();
    if (sent == 0) chunk.set_total_records(total);
    sent += chunk.records_size();
    if (!writer->Write(chunk)) return absl::CancelledError("the client went away during export");
    chunk.Clear();
    chunk_bytes = 0;
    return absl::OkStatus();
  };
  absl::Status s = registry_.Export(req->run_id(), ids, [&](RveRecord&& r) {
    v1::RveRecord record;
    ToProto(r, &record);
    const std::int64_t size = static_cast<std::int64_t>(record.ByteSizeLong());
    if (chunk.records_size() > 0 && chunk_bytes + size > budget) {
      RETURN_IF_ERROR(flush());
    }
    chunk_bytes += size + 8;  // + field tag and length
    *chunk.add_records() = std::move(record);
    return absl::OkStatus();
  });
  if (s.ok()) s = flush();
  if (!s.ok()) return ToGrpc(s);
  Log("info", "exported", {{"run", req->run_id()}, {"count", absl::StrCat(sent)}});
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::ImportBytes(grpc::ServerContext* ctx,
                                         grpc::ServerReader<grpc::ByteBuffer>* reader,
                                         v1::ImportResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  // All or nothing: every rule below is checked before anything is hosted,
  // and a stream that breaks one imports nothing.
  auto malformed = [](const std::string& why) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        absl::StrCat("malformed import stream: ", why, "; nothing imported"));
  };
  const std::int64_t max_records = registry_.options().max_rves;
  std::vector<RveRecord> records;
  grpc::ByteBuffer bytes;
  std::int64_t declared = 0;
  int chunks = 0;
  // What the stream has carried, bytes: held until the end (all or nothing),
  // in the budget all streams share (each alone once held six times the
  // memory limit together).
  std::int64_t held = 0;
  struct Release {
    RveServiceImpl* service;
    const std::int64_t* held;
    ~Release() { service->ReleaseImportBytes(*held); }
  } release{this, &held};
  while (reader->Read(&bytes)) {
    if (grpc::Status r = ReserveImportBytes(static_cast<std::int64_t>(bytes.Length()), held);
        !r.ok()) {
      return r;
    }
    v1::RveChunk chunk;
    if (!grpc::SerializationTraits<v1::RveChunk>::Deserialize(&bytes, &chunk).ok()) {
      return malformed(absl::StrCat("chunk ", chunks, " is not a valid RveChunk message"));
    }
    if (chunks == 0) {
      declared = chunk.total_records();
      if (declared < 1 || declared > max_records) {
        return malformed(absl::StrCat("the first chunk must set total_records to 1..", max_records,
                                      ", got ", declared));
      }
    } else if (chunk.total_records() != 0 && chunk.total_records() != declared) {
      return malformed(absl::StrCat("chunk ", chunks, " declares total_records ",
                                    chunk.total_records(), " after the first declared ", declared));
    }
    if (chunk.records_size() == 0) {
      return malformed(absl::StrCat("chunk ", chunks, " carries no records"));
    }
    if (static_cast<std::int64_t>(records.size()) + chunk.records_size() > declared) {
      return malformed(absl::StrCat("the stream carries more than the ", declared,
                                    " records it declared (chunk ", chunks, ")"));
    }
    for (int k = 0; k < chunk.records_size(); ++k) {
      absl::StatusOr<RveRecord> r = FromProto(chunk.records(k));
      if (!r.ok()) {
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            absl::StrCat("import chunk ", chunks, " record ", k, ": ",
                                         r.status().message(), "; nothing imported"));
      }
      records.push_back(*std::move(r));
    }
    ++chunks;
  }
  if (ctx->IsCancelled()) {
    return grpc::Status(grpc::StatusCode::CANCELLED, "import cancelled; nothing imported");
  }
  if (chunks == 0) return malformed("no chunks");
  if (declared != static_cast<std::int64_t>(records.size())) {
    return malformed(absl::StrCat("it declared ", declared, " records but carried ", records.size(),
                                  " (truncated stream?)"));
  }
  absl::StatusOr<std::int64_t> n = registry_.Import(std::move(records));
  if (!n.ok()) return ToGrpc(n.status());
  resp->set_imported(*n);
  Log("info", "imported", {{"count", absl::StrCat(*n)}, {"chunks", absl::StrCat(chunks)}});
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::ReserveImportBytes(std::int64_t bytes, std::int64_t& held) {
  const std::int64_t limit = registry_.options().max_memory_bytes;
  const std::int64_t hosted = registry_.Stats().memory_bytes;
  const std::int64_t budget = std::max<std::int64_t>(0, limit - hosted);
  absl::MutexLock lock(&import_mu_);
  if (import_bytes_ + bytes > budget) {
    return grpc::Status(
        grpc::StatusCode::RESOURCE_EXHAUSTED,
        absl::StrCat("import streams in flight may hold together at most the room left under the "
                     "server's memory limit, ",
                     budget, " bytes (", limit, " less ", hosted, " hosted); this stream's ",
                     held + bytes, " bytes with the others' ", import_bytes_ - held,
                     " would pass it; nothing imported"));
  }
  import_bytes_ += bytes;
  held += bytes;
  return grpc::Status::OK;
}

void RveServiceImpl::ReleaseImportBytes(std::int64_t held) {
  absl::MutexLock lock(&import_mu_);
  import_bytes_ -= held;
}

std::int64_t RveServiceImpl::import_bytes() const {
  absl::MutexLock lock(&import_mu_);
  return import_bytes_;
}

grpc::Status RveServiceImpl::DoDrop(grpc::ServerContext* ctx, const v1::DropRequest* req,
                                    v1::DropResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  const std::vector<std::int64_t> ids = Ids(req->ids());
  absl::StatusOr<std::int64_t> n = registry_.Drop(req->run_id(), ids);
  if (!n.ok()) return ToGrpc(n.status());
  resp->set_dropped(*n);
  Log("info", "dropped", {{"run", req->run_id()}, {"count", absl::StrCat(*n)}});
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::ListRuns(grpc::ServerContext* ctx, const v1::ListRunsRequest* req,
                                      v1::ListRunsResponse* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  return ListPage<RunInfo>(
      "ListRuns", req->page_size(), req->page_token(),
      options_.max_message_bytes - kChunkOverheadBytes,
      [&](absl::string_view after, std::size_t limit) { return registry_.ListRuns(after, limit); },
      [](const RunInfo& r) { return r.run_id; }, resp->mutable_runs(),
      resp->mutable_next_page_token());
}

grpc::Status RveServiceImpl::GetServerInfo(grpc::ServerContext* ctx, const v1::ServerInfoRequest*,
                                           v1::ServerInfo* resp) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  const RegistryStats s = registry_.Stats();
  const RegistryOptions& o = registry_.options();
  resp->set_version(options_.version);
  resp->set_api_version("rvehub.v1");
  resp->set_threads(o.threads);
  resp->set_num_rves(s.num_rves);
  resp->set_max_rves(o.max_rves);
  resp->set_memory_bytes(s.memory_bytes);
  resp->set_max_memory_bytes(o.max_memory_bytes);
  resp->set_num_runs(s.num_runs);
  resp->set_num_templates(s.num_templates);
  resp->set_max_templates(o.max_templates);
  resp->set_import_bytes(import_bytes());
  resp->set_max_batch(o.max_batch);
  resp->set_max_message_bytes(options_.max_message_bytes);
  resp->set_uptime_seconds(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count());
  resp->set_auth_required(!options_.auth_token.empty());
  resp->set_tls(options_.tls);
  return grpc::Status::OK;
}

grpc::Status RveServiceImpl::DoRunElementTest(grpc::ServerContext* ctx,
                                              const v1::ElementTestRequest* req,
                                              grpc::ServerWriter<v1::ElementTestUpdate>* writer) {
  if (grpc::Status a = CheckAuth(ctx); !a.ok()) return a;
  absl::StatusOr<dem::ElementTestSpec> spec = FromProto(*req);
  if (!spec.ok()) return ToGrpc(spec.status());
  absl::StatusOr<TemplateRecord> tmpl = registry_.FindTemplate(req->template_name());
  if (!tmpl.ok()) return ToGrpc(tmpl.status());
  absl::StatusOr<dem::Rve> rve = dem::Rve::Create(tmpl->packing);
  if (!rve.ok()) return ToGrpc(rve.status());
  // A fresh RVE of the template, tested in this call's thread (an element
  // test is one long sequential run). Progress goes out every 5 %.
  double last_sent = -1.0;
  bool client_gone = false;
  absl::StatusOr<std::vector<dem::ElementTestRow>> rows = dem::RunElementTest(
      *rve, *spec,
      [&](double fraction) {
        if (client_gone || fraction - last_sent < 0.05) return;
        v1::ElementTestUpdate u;
        u.set_progress(fraction);
        client_gone = !writer->Write(u) || ctx->IsCancelled();
        last_sent = fraction;
      },
      Canceller(ctx));
  if (!rows.ok()) return ToGrpc(rows.status());
  if (client_gone) return grpc::Status(grpc::StatusCode::CANCELLED, "the client went away");
  constexpr int kRowsPerMessage = 1000;
  for (std::size_t k = 0; k < rows->size(); k += kRowsPerMessage) {
    v1::ElementTestUpdate u;
    u.set_progress(1.0);
    for (std::size_t r = k; r < std::min(rows->size(), k + kRowsPerMessage); ++r)
      ToProto((*rows)[r], u.add_rows());
    if (!writer->Write(u)) return grpc::Status(grpc::StatusCode::CANCELLED, "the client went away");
  }
  Log("info", "element test",
      {{"template", req->template_name()}, {"rows", absl::StrCat(rows->size())}});
  return grpc::Status::OK;
}

}  // namespace rvehub::service
