// The case's "output" section: intervals, the Gauss points recorded, the
// plot.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "fem_client/case/sections.h"

namespace rvehub::fem::case_internal {
namespace {

constexpr Table<PlotKind> kPlots = {{"stress-strain", PlotKind::kStressStrain},
                                    {"simple-shear", PlotKind::kSimpleShear},
                                    {"none", PlotKind::kNone}};

absl::string_view PlotName(PlotKind kind) {
  switch (kind) {
    case PlotKind::kStressStrain:
      break;
    case PlotKind::kSimpleShear:
      return "simple-shear";
    case PlotKind::kNone:
      return "none";
  }
  return "stress-strain";
}

bool Plotted(const OutputSpec& out) { return out.plot != PlotKind::kNone; }

// What reading the output needs besides its JSON (null: only writing).
struct OutputContext {
  const MeshSpec* mesh = nullptr;
  const LoadingSpec* loading = nullptr;
  std::string base_dir;
};

// A list of distinct Gauss point ids of the mesh, written always (empty: none).
Field<OutputSpec> GaussPointsField(absl::string_view key, std::vector<std::int64_t> OutputSpec::*m,
                                   const OutputContext& c) {
  return {key,
          [=](const Object& o, OutputSpec* out) -> absl::Status {
            std::vector<const Json*> ids;
            RETURN_IF_ERROR(GetArray(o, key, Need::kOptional, &ids));
            const std::int64_t count = GaussPointCount(*c.mesh);
            std::map<std::int64_t, std::size_t> first;  // id -> its index
            std::vector<std::int64_t> read;
            for (std::size_t i = 0; i < ids.size(); ++i) {
              const std::string at = Child(o.At(key), i);
              std::int64_t id = 0;
              RETURN_IF_ERROR(ReadInteger(*ids[i], at, 0, count - 1, &id));
              if (auto [it, added] = first.emplace(id, i); !added) {
                return Bad(at, "Gauss point ", id, " is listed twice (also ",
                           Child(o.At(key), it->second), ")");
              }
              read.push_back(id);
            }
            out->*m = read;
            return absl::OkStatus();
          },
          [=](const OutputSpec& out, OrderedJson& j) {
            j[std::string(key)] = OrderedJson::array();
            for (std::int64_t id : out.*m) j[std::string(key)].push_back(id);
          }};
}

Fields<OutputSpec> OutputFields(const OutputContext& c) {
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  return {
      IntegerField("timeseries_every", &OutputSpec::timeseries_every, 1, kMax),
      IntegerField("frame_every", &OutputSpec::frame_every, 1, kMax),
      IntegerField("checkpoint_every", &OutputSpec::checkpoint_every, 0, kMax),
      IntegerField("progress_every", &OutputSpec::progress_every, 1, kMax),
      GaussPointsField("monitor", &OutputSpec::monitor, c),
      GaussPointsField("packings", &OutputSpec::packings, c),
      {"plot",
       [c](const Object& o, OutputSpec* out) -> absl::Status {
         RETURN_IF_ERROR(GetEnum(o, "plot", Need::kOptional, "plot", kPlots, &out->plot));
         // Each plot reads its loading's curves: the platen's stress against
         // the axial strain, or the shear stress against γ.
         const bool compression = c.loading->kind == LoadingKind::kCompression;
         if ((out->plot == PlotKind::kStressStrain && !compression) ||
             (out->plot == PlotKind::kSimpleShear && compression)) {
           return Bad(o.At("plot"), Quote(PlotName(out->plot)), " is the plot of ",
                      compression ? "the shear loadings" : "loading \"compression\"",
                      "; this case's loading is ", Quote(LoadingKindName(c.loading->kind)),
                      ", whose plot is ", Quote(PlotName(DefaultPlot(*c.loading))));
         }
         return absl::OkStatus();
       },
       [](const OutputSpec& out, OrderedJson& j) { j["plot"] = PlotName(out.plot); }},
      Only(&Plotted, "only with a plot",
           {"reference_curve",
            [c](const Object& o, OutputSpec* out) {
              return o.Has("reference_curve")
                         ? GetFile(o, "reference_curve", c.base_dir, &out->reference_curve)
                         : absl::OkStatus();
            },
            [](const OutputSpec& out, OrderedJson& j) {
              if (!out.reference_curve.empty()) j["reference_curve"] = out.reference_curve;
            }}),
  };
}

}  // namespace

PlotKind DefaultPlot(const LoadingSpec& loading) {
  return loading.kind == LoadingKind::kCompression ? PlotKind::kStressStrain
                                                   : PlotKind::kSimpleShear;
}

absl::Status ParseOutput(const Json& j, const std::string& ptr, const MeshSpec& mesh,
                         const LoadingSpec& loading, const std::string& base_dir, OutputSpec* out) {
  return ReadFields(j, ptr, OutputFields({&mesh, &loading, base_dir}), out).status();
}

OrderedJson WriteOutput(const OutputSpec& out) { return WriteFields(OutputFields({}), out); }

}  // namespace rvehub::fem::case_internal
