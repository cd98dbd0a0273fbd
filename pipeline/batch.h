#pragma once
// `scan2model batch`: many objects, each fitted by the code of `scan2model fit` (ComputeFit, in-process),
// in parallel, resumable, with one summary. Manifest format and output layout: docs/batch.md.

#include <atomic>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipeline/fit_options.h"

namespace s2m::pipeline {

// One object of a manifest.
struct BatchObject {
  std::string id;  // unique, a file name: letters, digits, '.', '_', '-'
  FitOptions fit;  // input and part file resolved against the manifest's folder
  nlohmann::json
      spec;  // {input, model, options} as resolved: a re-run recomputes an object whose spec changed
};

struct BatchManifest {
  std::string path;
  std::vector<BatchObject> objects;
};

// A scan2model.batch/1 JSON manifest (.json) or a CSV manifest (any other extension). Throws FormatError
// naming the manifest, the line or object, and the problem (unknown option, bad value, duplicate or unusable
// id).
BatchManifest ReadBatchManifest(const std::string& path);

struct BatchOptions {
  std::string output_dir;
  int jobs = 0;             // objects in parallel; 0: one per core
  int threads_per_job = 0;  // OpenMP threads inside each fit; 0: cores / jobs (at least 1)
  bool force = false;       // recompute finished objects too
  bool reports = false;     // write an HTML report per object
  bool progress = true;     // the progress line on standard error
  std::string progress_prefix;
  // Test hook (environment S2M_BATCH_KILL_AFTER=k): the process kills itself with SIGKILL right after the
  // k-th object it computed was written, as a crash or power cut would.
  int kill_after = 0;
  // When given and set (a SIGTERM or Ctrl-C, apps/stop_signal.h), no further object starts; the objects in
  // flight finish and are written, the others stay "missing" in the entries (BatchCounts::not_started), and
  // a rerun resumes with them.
  const std::atomic<bool>* stop = nullptr;
};

// What happened to the objects of one run.
struct BatchCounts {
  int computed = 0;     // fitted now (ok or error)
  int skipped = 0;      // finished by an earlier run
  int ok = 0;           // with a result (computed or skipped)
  int failed = 0;       // with an error record
  int not_started = 0;  // left for a rerun because BatchOptions::stop was set
};

// The positions (into manifest.objects) of shard `index` of `count`: every count-th object, deterministic in
// the manifest's order.
std::vector<std::size_t> ShardPositions(std::size_t objects, int index, int count);

// Runs the objects at `positions` (skipping those finished unless options.force) and returns one summary
// entry per position, in the same order. Writes OUTPUT/objects/<id>.json (atomically, last) and, where they
// apply, <id>_profile.csv, <id>_profile.svg, <id>.html.
std::vector<nlohmann::json> RunBatchObjects(const BatchManifest& manifest,
                                            const std::vector<std::size_t>& positions,
                                            const BatchOptions& options, BatchCounts& counts);

// The summary entry of one object from its record (an object result document) or a missing one.
nlohmann::json SummaryEntry(const BatchObject& object, const nlohmann::json* record,
                            const std::string& record_file);
// Writes OUTPUT/<name>.json and OUTPUT/<name>.csv (atomically) from the entries, in the given order.
void WriteBatchSummary(const std::string& output_dir, const std::string& name, const BatchManifest& manifest,
                       const std::vector<nlohmann::json>& entries);

// The flattened parameters of a fit document (any schema of `scan2model fit`) as [{name, value, uncertainty,
// unit, ...}]: what the summary and the report's table show.
nlohmann::json FlatParameters(const nlohmann::json& document);

}  // namespace s2m::pipeline
