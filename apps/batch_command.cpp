// `scan2model batch <manifest>`: docs/batch.md.

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <regex>
#include <sstream>
#include <thread>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "apps/stop_signal.h"
#include "pipeline/batch.h"
#include "pipeline/batch_mpi.h"
#include "pipeline/output.h"

namespace s2m::app {
namespace fs = std::filesystem;
namespace {

struct BatchCommandOptions {
  std::string manifest;
  std::string shard;  // "i/N"
  bool mpi = false;
  bool summary_only = false;
  bool quiet = false;
  BatchOptions run;
};

// Entries of several ranks (each a JSON array of [position, entry] pairs) merged in manifest order.
std::vector<nlohmann::json> MergeByPosition(const std::vector<std::string>& parts) {
  std::vector<std::pair<std::size_t, nlohmann::json>> all;
  for (const std::string& part : parts) {
    for (const nlohmann::json& pair : nlohmann::json::parse(part))
      all.emplace_back(pair[0].get<std::size_t>(), pair[1]);
  }
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<nlohmann::json> out;
  for (auto& [position, entry] : all) out.push_back(std::move(entry));
  return out;
}

int Run(BatchCommandOptions& o) {
  int shard_index = 0, shard_count = 1;
  if (!o.shard.empty()) {
    std::smatch m;
    const std::regex pattern(R"((\d+)/(\d+))");
    if (!std::regex_match(o.shard, m, pattern) || std::stoi(m[2]) < 1 || std::stoi(m[1]) >= std::stoi(m[2])) {
      std::cerr << "scan2model batch: error: --shard " << o.shard
                << ": expected i/N with 0 <= i < N, e.g. 0/4\n";
      return kUsage;
    }
    shard_index = std::stoi(m[1]);
    shard_count = std::stoi(m[2]);
  }
  const bool use_mpi = o.mpi || (MpiBuilt() && LaunchedByMpi());
  if (use_mpi && !MpiBuilt()) {
    std::cerr
        << "scan2model batch: error: --mpi: this scan2model was built without MPI (install libopenmpi-dev "
           "and rebuild; docs/batch.md)\n";
    return kUsage;
  }
  std::unique_ptr<MpiSession> mpi = use_mpi ? StartMpi() : nullptr;
  const int rank = mpi ? mpi->rank() : 0, ranks = mpi ? mpi->size() : 1;
  int exit_code = kOk;
  std::string stopped_by;  // the signal that stopped the run early, if one did
  // From the start: a signal while the manifest is read stops the batch before its first object.
  StopOnSignals stop_on_signals;
  try {
    const BatchManifest manifest = ReadBatchManifest(o.manifest);
    if (o.run.output_dir.empty()) {
      const fs::path m(o.manifest);
      o.run.output_dir = (m.parent_path() / (m.stem().string() + "_results")).string();
    }
    // Shard, then MPI rank: both every k-th object in manifest order.
    const std::vector<std::size_t> shard = ShardPositions(manifest.objects.size(), shard_index, shard_count);
    std::vector<std::size_t> mine;
    for (std::size_t i = 0; i < shard.size(); ++i) {
      if (static_cast<int>(i % static_cast<std::size_t>(ranks)) == rank) mine.push_back(shard[i]);
    }
    if (mpi) {
      o.run.progress_prefix = "[rank " + std::to_string(rank) + "/" + std::to_string(ranks) + "] ";
      if (o.run.jobs == 0) {  // share the machine with the other ranks on it
        const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
        o.run.jobs = std::max(1, cores / std::max(1, mpi->local_size()));
      }
    }
    o.run.progress = !o.quiet;
    if (const char* kill = std::getenv("S2M_BATCH_KILL_AFTER")) o.run.kill_after = std::atoi(kill);
    BatchCounts counts;
    std::vector<nlohmann::json> entries;
    if (o.summary_only) {
      for (const std::size_t p : mine) {
        const BatchObject& object = manifest.objects[p];
        const std::string path = (fs::path(o.run.output_dir) / "objects" / (object.id + ".json")).string();
        std::ifstream in(path);
        nlohmann::json record = nullptr;
        if (in) {
          try {
            record = nlohmann::json::parse(in);
          } catch (const nlohmann::json::exception&) {
          }
        }
        entries.push_back(SummaryEntry(object, &record, path));
      }
    } else {
      o.run.stop = &StopOnSignals::Flag();
      entries = RunBatchObjects(manifest, mine, o.run, counts);
      o.run.stop = nullptr;
      if (StopOnSignals::Requested()) {
        stopped_by = StopOnSignals::SignalName();
        if (stopped_by.empty()) stopped_by = "a signal";
      }
    }
    if (mpi && !o.summary_only) {
      // One write: the ranks share standard error, and a line written piecewise interleaves with another's.
      std::cerr << (o.run.progress_prefix + "done: " + std::to_string(mine.size()) + " objects (" +
                    std::to_string(counts.computed) + " computed, " + std::to_string(counts.skipped) +
                    " skipped)\n")
                << std::flush;
    }
    nlohmann::json pairs = nlohmann::json::array();
    for (std::size_t i = 0; i < mine.size(); ++i) pairs.push_back({mine[i], entries[i]});
    std::vector<nlohmann::json> all;
    if (mpi) {
      all = MergeByPosition(mpi->GatherToRoot(pairs.dump()));
    } else {
      all = entries;
    }
    if (rank == 0 && !stopped_by.empty()) {
      // No summary: it would list the objects not started as missing as if the batch had finished.
      std::cerr << ("[batch] stopped by " + stopped_by + ": " + std::to_string(counts.computed) +
                    " objects computed in this run, " + std::to_string(counts.skipped) +
                    " finished before, " + std::to_string(counts.not_started) +
                    " not started; every finished object is written in " +
                    (fs::path(o.run.output_dir) / "objects").string() +
                    ". Run the same command again to resume (no summary was written).\n")
                << std::flush;
      exit_code = kInterrupted;
    } else if (rank == 0) {
      const std::string name = shard_count == 1 ? "summary"
                                                : "summary_shard_" + std::to_string(shard_index) + "_of_" +
                                                      std::to_string(shard_count);
      WriteBatchSummary(o.run.output_dir, name, manifest, all);
      int ok = 0, failed = 0, missing = 0, inadequate = 0;
      for (const nlohmann::json& e : all) {
        const std::string status = e["status"].get<std::string>();
        (status == "ok" ? ok : status == "missing" ? missing : failed) += 1;
        inadequate += e.value("adequate", nlohmann::json(nullptr)) == false;
      }
      {
        std::ostringstream line;  // one write (the other ranks may still be printing)
        line << "[batch] " << all.size() << " objects: " << ok << " ok, " << failed << " failed";
        if (missing > 0) line << ", " << missing << " missing";
        if (inadequate > 0) line << ", " << inadequate << " NOT adequate (uncertainties not trustworthy)";
        if (!o.summary_only && !mpi)
          line << " (" << counts.computed << " computed, " << counts.skipped << " skipped)";
        line << "; summary " << (fs::path(o.run.output_dir) / (name + ".csv")).string() << "\n";
        std::cerr << line.str() << std::flush;
      }
      exit_code = failed + missing > 0 ? kFitError : kOk;
    }
  } catch (const FormatError& e) {
    ReportError("batch", e.what(), kInputError, false);
    exit_code = kInputError;
  } catch (const std::filesystem::filesystem_error& e) {
    ReportError("batch", e.what(), kInputError, false);
    exit_code = kInputError;
  }
  // Every rank exits with rank 0's verdict (mpirun reports the first non-zero one).
  if (mpi && ranks > 1) exit_code = mpi->Broadcast(exit_code);
  return exit_code;
}

}  // namespace

Runner AddBatchCommand(CLI::App& app) {
  auto o = std::make_shared<BatchCommandOptions>();
  CLI::App* cmd = app.add_subcommand("batch",
                                     "Fit many objects listed in a manifest (CSV or JSON), in parallel, "
                                     "resumable, with a summary (docs/batch.md)");
  cmd->add_option("manifest", o->manifest,
                  "The manifest: .json (scan2model.batch/1) or CSV (id,input,model,...)")
      ->required();
  cmd->add_option(
      "-o,--output,--output-dir", o->run.output_dir,
      "Where results go (default: MANIFEST_STEM_results beside the manifest): objects/ID.json per "
      "object, summary.csv, summary.json (--output-dir: the old spelling, an alias for one release)");
  cmd->add_option("--jobs,-j", o->run.jobs, "Objects fitted in parallel (default: one per core)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--threads-per-job", o->run.threads_per_job,
                  "OpenMP threads inside each fit (default: cores / jobs, at least 1)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--force", o->run.force, "Recompute objects already finished by an earlier run");
  cmd->add_flag("--report", o->run.reports, "Also write an HTML report per object (objects/ID.html)");
  cmd->add_option(
      "--shard", o->shard,
      "Process shard i of N (0 <= i < N): every N-th object from the i-th, for cluster job arrays; "
      "writes summary_shard_i_of_N.{csv,json}");
  cmd->add_flag("--mpi", o->mpi,
                "Distribute the objects over MPI ranks (automatic under mpirun when built with MPI); rank 0 "
                "writes the summary");
  cmd->add_flag("--summary-only", o->summary_only,
                "Fit nothing: collect the summary from the results already in the output folder");
  cmd->add_flag("--quiet,-q", o->quiet, "No progress line (the closing line and errors are still printed)");
  return [o]() { return Run(*o); };
}

}  // namespace s2m::app
