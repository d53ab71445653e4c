// The case's "output" section: frames, timeseries, checkpoints, plot and
// summary.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_join.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

// Static storage for the list (the table outlives every read).
const Table<std::string> kPlots = {{"stress-strain", "stress-strain"},
                                   {"load-settlement", "load-settlement"},
                                   {"collapse", "collapse"},
                                   {"none", "none"}};

bool LoadSettlement(const OutputSpec& o) { return o.plot == "load-settlement"; }
bool StressStrain(const OutputSpec& o) { return o.plot == "stress-strain"; }

const Table<std::string> kSummaries = {
    {"footing", "footing"}, {"pipe", "pipe"},       {"collapse", "collapse"},
    {"biaxial", "biaxial"}, {"shaking", "shaking"}, {"consolidation", "consolidation"},
    {"crs", "crs"},         {"wave", "wave"},       {"none", "none"}};

bool ConsolidationSummary(const OutputSpec& o) { return o.summary == "consolidation"; }
bool WaveSummary(const OutputSpec& o) { return o.summary == "wave"; }

bool FootingSummary(const OutputSpec& o) {
  return o.summary == "footing" || (o.summary.empty() && o.plot == "load-settlement");
}

// `bodies`: the case's, for the plot body's check (null when only writing).
// `base_dir`: the case file's directory, for a relative reference curve.
Fields<OutputSpec> OutputFields(const std::vector<RigidBody>* bodies, const std::string& base_dir) {
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  constexpr absl::string_view kOnlyLoadSettlement = "only for plot \"load-settlement\"";
  Field<OutputSpec> plot_body = TextField("plot_body", &OutputSpec::plot_body, Need::kRequired,
                                          /*non_empty=*/true);
  const auto read_body = plot_body.read;
  plot_body.read = [=](const Object& o, OutputSpec* out) -> absl::Status {
    RETURN_IF_ERROR(read_body(o, out));
    if (bodies != nullptr && std::none_of(bodies->begin(), bodies->end(), [&](const RigidBody& b) {
          return b.name == out->plot_body;
        })) {
      return Bad(o.At("plot_body"), "no body named ", Quote(out->plot_body),
                 " (bodies: ", absl::StrJoin(NamesOf(*bodies), ", "), ")");
    }
    return absl::OkStatus();
  };
  return {
      IntegerField("frame_every", &OutputSpec::frame_every, 1, kMax),
      {"frame_times",
       [](const Object& o, OutputSpec* out) -> absl::Status {
         const Json* v = o.Get("frame_times");
         if (v == nullptr) return absl::OkStatus();
         if (!v->is_array()) return Bad(o.At("frame_times"), "must be an array of times (s)");
         for (std::size_t i = 0; i < v->size(); ++i) {
           double t = 0.0;
           RETURN_IF_ERROR(ReadNumber((*v)[i], Child(o.At("frame_times"), i), kNonNegative, &t));
           if (!out->frame_times.empty() && !(t > out->frame_times.back())) {
             return Bad(Child(o.At("frame_times"), i), "times must increase, got ", Num(t),
                        " s after ", Num(out->frame_times.back()), " s");
           }
           out->frame_times.push_back(t);
         }
         return absl::OkStatus();
       },
       [](const OutputSpec& out, OrderedJson& j) {
         if (!out.frame_times.empty()) j["frame_times"] = out.frame_times;
       }},
      IntegerField("timeseries_every", &OutputSpec::timeseries_every, 1, kMax),
      IntegerField("checkpoint_every", &OutputSpec::checkpoint_every, 0, kMax),
      IntegerField("progress_every", &OutputSpec::progress_every, 1, kMax),
      {"plot",
       [](const Object& o, OutputSpec* out) {
         return GetEnum(o, "plot", Need::kOptional, "plot", kPlots, &out->plot);
       },
       [](const OutputSpec& out, OrderedJson& j) { j["plot"] = out.plot; }},
      Only(&LoadSettlement, kOnlyLoadSettlement, plot_body),
      Only(&LoadSettlement, kOnlyLoadSettlement,
           NumberField("plot_width", &OutputSpec::plot_width, Need::kOptional, kPositive)),
      {"summary",
       [](const Object& o, OutputSpec* out) {
         return GetEnum(o, "summary", Need::kOptional, "summary", kSummaries, &out->summary);
       },
       [](const OutputSpec& out, OrderedJson& j) {
         if (!out.summary.empty()) j["summary"] = out.summary;
       }},
      Only(&FootingSummary, "only for a footing summary",
           {"phi_deg",
            [](const Object& o, OutputSpec* out) {
              return GetNumber(o, "phi_deg", Need::kOptional, Range{0.0, 90.0, true, true},
                               &out->phi_deg);
            },
            [](const OutputSpec& out, OrderedJson& j) {
              if (out.phi_deg > 0.0) j["phi_deg"] = out.phi_deg;
            }}),
      Only(&ConsolidationSummary, "only for a consolidation summary",
           NumberField("constrained_modulus", &OutputSpec::constrained_modulus, Need::kRequired,
                       kPositive)),
      Only(&WaveSummary, "only for a wave summary",
           TextField("wave_from", &OutputSpec::wave_from, Need::kRequired, /*non_empty=*/true)),
      Only(&WaveSummary, "only for a wave summary",
           TextField("wave_to", &OutputSpec::wave_to, Need::kRequired, /*non_empty=*/true)),
      Only(&WaveSummary, "only for a wave summary",
           NumberField("wave_window", &OutputSpec::wave_window, Need::kRequired, kPositive)),
      Only(&StressStrain, "only for plot \"stress-strain\"",
           {"reference_curve",
            [base_dir](const Object& o, OutputSpec* out) {
              return o.Has("reference_curve")
                         ? GetFile(o, "reference_curve", base_dir, &out->reference_curve)
                         : absl::OkStatus();
            },
            [](const OutputSpec& out, OrderedJson& j) {
              if (!out.reference_curve.empty()) j["reference_curve"] = out.reference_curve;
            }}),
  };
}

}  // namespace

absl::Status ParseOutput(const Json& j, const std::string& ptr,
                         const std::vector<RigidBody>& bodies, const std::string& base_dir,
                         OutputSpec* out) {
  return ReadFields(j, ptr, OutputFields(&bodies, base_dir), out).status();
}

OrderedJson WriteOutput(const OutputSpec& out) {
  return WriteFields(OutputFields(nullptr, ""), out);
}

}  // namespace rvehub::mpm::case_internal
