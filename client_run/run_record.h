// DIR/run.json, the run record of a continuum client's run: what ran, where
// and when, so that an output directory says how it was made. Written when
// the run starts (outcome "running"), at each checkpoint and at its end; a
// resume keeps the records before it under "previous".
#ifndef RVEHUB_CLIENT_RUN_RUN_RECORD_H_
#define RVEHUB_CLIENT_RUN_RUN_RECORD_H_

#include <cstdint>
#include <string>

#include "nlohmann/json.hpp"

namespace rvehub::client_run {

class RunRecord {
 public:
  using Json = nlohmann::ordered_json;

  // `program` (e.g. "mpm_client") and its `version` (git describe), the
  // command line and its command (run, resume); the host, the working
  // directory and the start time are taken here.
  RunRecord(const std::string& program, const std::string& version, int argc, char** argv,
            const std::string& command);

  // The case as run (canonical JSON text, after --set) and where the outputs
  // go; writes the record.
  void Started(const std::string& dir, const std::string& case_json, bool resumed);

  // A checkpoint written at `step`, `wall_s` s into this invocation's
  // stepping: kept as "last_checkpoint", so that a run killed before its end
  // (its host or session gone) still says how far it got and at what cost,
  // the work a resume continues from.
  void Checkpointed(std::int64_t step, double wall_s);

  // The end: outcome "failed" with `error`.
  void Failed(const std::string& error);
  // The end: `outcome` ("finished", "stopped") and the run's figures
  // (`fields`' keys in order, e.g. final_step, wall_s).
  void Finished(const std::string& outcome, const Json& fields);

 private:
  std::string Path() const { return dir_ + "/run.json"; }
  // A record that cannot be written is reported on stderr, not fatal: the
  // results are. Each write reserves room beyond the record's end, which a
  // later write takes when the disk is full.
  void Write() const;

  std::string program_;
  Json json_;
  std::string dir_;
};

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_RUN_RECORD_H_
