// The "templates" section: packings prepared from a parameter set or read
// from a file.
#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_join.h"
#include "client_case/sections.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "toolkit/field_table.h"

namespace rvehub::client_case {
namespace {

using fields::Bad;
using fields::Fields;
using fields::Forbid;
using fields::GetFile;
using fields::GetInteger;
using fields::GetNumber;
using fields::GetString;
using fields::Json;
using fields::NameField;
using fields::Need;
using fields::Object;
using fields::OrderedJson;
using fields::Quote;
using fields::Range;
using fields::ReadFields;
using fields::ReadSeed;
using fields::WriteFields;

bool FromSet(const TemplateSpec& t) { return t.file.empty(); }

// Keys that shape the preparation: a template file holds its own packing.
absl::Status OnlyFromParameterSet(const Object& o, absl::string_view key) {
  if (o.Has("parameter_set")) return absl::OkStatus();
  return Forbid(o, key,
                "only for templates prepared from a parameter set (a file holds its own packing)");
}

// `base_dir`: the case file's directory, for relative template files.
Fields<TemplateSpec> TemplateFields(const std::string& base_dir) {
  return {
      NameField<TemplateSpec>(),
      {"parameter_set",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         if (o.Has("file") == o.Has("parameter_set")) {
           return Bad(o.ptr(),
                      "give exactly one of \"file\" (a template file) or \"parameter_set\" ",
                      "(prepare from a named parameter set)");
         }
         if (!o.Has("parameter_set")) return absl::OkStatus();
         RETURN_IF_ERROR(Forbid(o, "template_name", "only for templates read from a file"));
         RETURN_IF_ERROR(GetString(o, "parameter_set", Need::kRequired, true, &t->parameter_set));
         if (!dem::FindParameterSet(t->parameter_set).ok()) {
           return Bad(o.At("parameter_set"), "unknown parameter set ", Quote(t->parameter_set),
                      " (known: ", absl::StrJoin(dem::ParameterSetNames(), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t)) j["parameter_set"] = t.parameter_set;
       }},
      {"seed",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "seed"));
         const Json* seed = o.Get("seed");
         return seed == nullptr ? absl::OkStatus() : ReadSeed(*seed, o.At("seed"), &t->seed);
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t)) j["seed"] = t.seed;
       }},
      {"pressure",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "pressure"));
         return GetNumber(o, "pressure", Need::kOptional,
                          Range{0.0, dem::kMaxPressure, true, false}, &t->pressure);
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.pressure > 0) j["pressure"] = t.pressure;
       }},
      {"void_ratio",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "void_ratio"));
         return GetNumber(o, "void_ratio", Need::kOptional, Range{0.0, 1.0, true, true},
                          &t->void_ratio);
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.void_ratio > 0) j["void_ratio"] = t.void_ratio;
       }},
      {"particles",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "particles"));
         std::int64_t n = t->particles;
         RETURN_IF_ERROR(
             GetInteger(o, "particles", 2, static_cast<std::int64_t>(dem::kMaxParticles), &n));
         t->particles = static_cast<int>(n);
         return absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.particles > 0) j["particles"] = t.particles;
       }},
      {"rolling_eta",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "rolling_eta"));
         if (!o.Has("rolling_eta")) return absl::OkStatus();
         double eta = 0;
         RETURN_IF_ERROR(GetNumber(o, "rolling_eta", Need::kRequired,
                                   Range{0.0, dem::kMaxRollingEta, false, false}, &eta));
         // The set is known here: "parameter_set" is read first.
         const absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet(t->parameter_set);
         if (set.ok() && !dem::HasRollingResistance(set->material)) {
           return Bad(o.At("rolling_eta"), "parameter set ", Quote(t->parameter_set),
                      " has no rolling resistance (β = 0)");
         }
         t->rolling_eta = eta;
         return absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.rolling_eta.has_value()) j["rolling_eta"] = *t.rolling_eta;
       }},
      {"file",
       [base_dir](const Object& o, TemplateSpec* t) -> absl::Status {
         return o.Has("file") ? GetFile(o, "file", base_dir, &t->file) : absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (!FromSet(t)) j["file"] = t.file;
       }},
      {"template_name",
       [](const Object& o, TemplateSpec* t) {
         return o.Has("file")
                    ? GetString(o, "template_name", Need::kOptional, true, &t->template_name)
                    : absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (!FromSet(t) && !t.template_name.empty()) j["template_name"] = t.template_name;
       }},
  };
}

}  // namespace

absl::Status ParseTemplate(const Json& j, const std::string& ptr, const std::string& base_dir,
                           TemplateSpec* t) {
  return ReadFields(j, ptr, TemplateFields(base_dir), t).status();
}

OrderedJson WriteTemplate(const TemplateSpec& t) { return WriteFields(TemplateFields(""), t); }

int EstimatedDiscs(const TemplateSpec& t) {
  // A prepared template's disc count is known; a file's is not read here.
  absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet(t.parameter_set);
  int discs = t.file.empty() && set.ok() ? set->preparation.num_particles : 400;
  if (t.file.empty() && t.particles > 0) discs = t.particles;
  return discs;
}

}  // namespace rvehub::client_case
