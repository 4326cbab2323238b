// Session snapshots on disk (`hdeform sessions export/import`): the Snapshot message as
// binary protobuf, or as JSON in protobuf's JSON mapping (JsonUtil) when the file name ends
// in .json. Reading detects JSON by its first non-blank character '{'.
#pragma once

#include "common.h"

#include <string>

namespace hdeform::cli {

// True when `path` ends in .json (case-insensitive): write JSON, else binary.
bool snapshot_path_is_json(const std::string& path);
// The file's bytes; returns their count.
std::size_t write_snapshot(const std::string& path, const pb::Snapshot& snapshot);
// Throws CliError "FILE: not a session snapshot (…)" when the file is neither form, holds
// fields a Snapshot does not have, or names no mesh.
pb::Snapshot read_snapshot(const std::string& path);

}  // namespace hdeform::cli
