#pragma once
// Multi-view inputs: a scan2model view manifest (JSON: one point-cloud file per view and its world_T_scan)
// and Stanford range-scan .conf files ("bmesh <file> tx ty tz qx qy qz qw"). Paths inside are relative to the
// manifest's folder.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "registration/scan.h"

namespace s2m {

// .json (schema scan2model.views/1) or .conf, by extension. Throws FormatError naming the manifest, the line
// or view, and the problem (including a view file that is missing or unreadable).
ScanSet ReadScanSet(const std::filesystem::path& manifest);

// Writes one binary PLY per view (view_000.ply, ...) beside `manifest` and the manifest itself, atomically,
// creating the manifest's folder when it does not exist.
// `document_extra` (an object) adds members to the manifest and `view_extra[k]` (objects; empty or one per
// view) to view k's entry, e.g. how a registration found the poses; readers ignore them.
void WriteScanSet(const std::filesystem::path& manifest, const ScanSet& set,
                  const nlohmann::json& document_extra = nlohmann::json::object(),
                  const std::vector<nlohmann::json>& view_extra = {});

}  // namespace s2m
