// One RVE server as a client sees it: a remote rve_server reached over gRPC
// (RemoteServer, remote_server.h) or a registry in this process (embedded:
// direct calls, no gRPC, no marshalling; rve_server/embedded supplies it).
// Both give the same results bit for bit (the wire carries doubles exactly),
// so a run may mix them or move between them. Values only: no engine, no
// server internals.
#ifndef RVEHUB_RVE_SERVER_CLIENT_ENDPOINT_H_
#define RVEHUB_RVE_SERVER_CLIENT_ENDPOINT_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "rve_server/client/channel.h"
#include "rve_server/values/increment.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"

namespace rvehub::client {

// Receives exported RVE states one at a time; an error stops the export.
using RecordSink = std::function<absl::Status(RveRecord&&)>;

// `s` with "<label>: " before its message (OK stays OK): how every error of
// an endpoint names it.
inline absl::Status Labelled(absl::string_view label, const absl::Status& s) {
  if (s.ok()) return s;
  return absl::Status(s.code(), absl::StrCat(label, ": ", s.message()));
}

// An Apply under way (RveEndpoint::StartApply).
class PendingApply {
 public:
  virtual ~PendingApply() = default;
  // Waits for the call to end: its outcomes, or the whole-call error. Once.
  virtual absl::StatusOr<std::vector<RveOutcome>> Finish() = 0;
  // Wall time from the start of the call to its end, s (after Finish).
  virtual double seconds() const = 0;
};

// Whole-call errors come back as the status of a call; per-RVE results as
// RveOutcome (in the order of the ids or increments given). Every error of
// an endpoint starts with its label().
class RveEndpoint {
 public:
  virtual ~RveEndpoint() = default;

  // "embedded", or the server's HOST:PORT.
  virtual std::string name() const = 0;
  // For messages: "embedded RVE registry" or "RVE server HOST:PORT".
  virtual std::string label() const = 0;
  // Worker threads evaluating a batch (the server's --threads).
  virtual int workers() const = 0;
  // True when calls run in the caller's process and thread (StartApply does
  // the work before it returns): callers start remote calls first.
  virtual bool in_process() const { return false; }

  // Uploads a template, replacing one of the same name.
  virtual absl::Status PutTemplate(const TemplateRecord& record) = 0;

  // Creates RVEs of `template_name` with ids `ids` in run `run`, consolidated
  // to `initial` (empty: the template's state; one for all; or one per id)
  // with optional other controls. Outcomes carry the state after creation.
  // All or nothing.
  virtual absl::StatusOr<std::vector<RveOutcome>> Create(
      absl::string_view run, absl::string_view template_name, std::span<const std::int64_t> ids,
      std::span<const InitialStress> initial, const std::optional<dem::Controls>& controls) = 0;

  // Starts an increment of step `step` (≥ 1) for a batch and returns
  // without blocking the caller on a remote server: its messages go out
  // through gRPC's callback API, so one thread drives any number of servers.
  // The embedded endpoint works inside StartApply, on the registry's workers.
  // `deadline`: time the call may take. The spans must outlive Finish().
  //
  // kCommit: each RVE at committed step − 1 is deformed by its ΔF and
  // commits `step`. An RVE already at `step` answers the stored result when
  // the ΔF is the same bit for bit (a safe retry; it is observed again when
  // the options ask for more than was stored, e.g. a tangent), and
  // FailedPrecondition for another ΔF.
  //
  // kTrial: each RVE at committed step − 1 computes the same increment on a
  // copy and returns that state (the tangent when the options ask for it),
  // with RveOutcome::step the committed step (`step` − 1, unchanged) and
  // deformation_gradient the trial's F. The RVE is left exactly as it was
  // (only the server's guess of its next increment's work, which orders a
  // batch and never a result, follows the trial), so TRIALs of `step` may
  // repeat any number of times, each computed afresh from the committed
  // state, and a COMMIT of `step` with the same ΔF and options returns
  // the state a TRIAL did, bit for bit. There is no stored answer: an RVE
  // already at `step` (or at any step but `step` − 1) gets
  // FailedPrecondition ("is at step E; step S needs it at step S − 1").
  //
  // In both modes per-RVE failures (that error, a ΔF the engine refuses, an
  // increment stopped at the deadline) are outcomes and leave that RVE at
  // its committed step; a malformed batch (bad step, ΔF, options or ids) or
  // an unknown run or id fails the whole call and changes nothing.
  virtual std::unique_ptr<PendingApply> StartApply(absl::string_view run, std::int64_t step,
                                                   ApplyMode mode,
                                                   std::span<const Increment> increments,
                                                   const dem::ApplyOptions& options,
                                                   absl::Duration deadline) = 0;
  // StartApply, then Finish.
  absl::StatusOr<std::vector<RveOutcome>> Apply(absl::string_view run, std::int64_t step,
                                                ApplyMode mode,
                                                std::span<const Increment> increments,
                                                const dem::ApplyOptions& options,
                                                absl::Duration deadline) {
    return StartApply(run, step, mode, increments, options, deadline)->Finish();
  }

  // Current states of `ids` (unknown ids: a NotFound outcome).
  virtual absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run,
                                                      std::span<const std::int64_t> ids,
                                                      bool want_tangent) = 0;

  // Full states of `ids` (empty: the whole run), in id order, one at a time
  // to `sink`; stops at the first error of `sink`.
  virtual absl::Status Export(absl::string_view run, std::span<const std::int64_t> ids,
                              const RecordSink& sink) = 0;

  // All or nothing per call (a remote import is one stream): AlreadyExists
  // when a (run, id) is hosted.
  virtual absl::Status Import(std::vector<RveRecord> records) = 0;

  // Drops RVEs of the run (empty ids: all of them); NotFound when the
  // endpoint hosts none of the run or not one of `ids` (then nothing is
  // dropped).
  virtual absl::Status Drop(absl::string_view run, std::span<const std::int64_t> ids = {}) = 0;

  // OK when the endpoint answers a cheap call within `timeout`: a client
  // asks a server it lost whether it is back. Unavailable otherwise.
  virtual absl::Status Ping(absl::Duration timeout) = 0;

  // The deadline of Get, Export, Import, Drop and PutTemplate from now on
  // (not while one is under way): a client that finds hung servers by
  // deadlines shortens it to what such calls were measured to take. A
  // remote endpoint starts with RemoteOptions::call_timeout; the embedded
  // one works in the caller's thread, has nothing to wait on and ignores it.
  virtual void SetCallTimeout(absl::Duration timeout) { (void)timeout; }
  // The same for Create (RemoteOptions::create_timeout at first).
  virtual void SetCreateTimeout(absl::Duration timeout) { (void)timeout; }
};

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_ENDPOINT_H_
