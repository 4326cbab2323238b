#include "snapshot_file.h"

#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cctype>

namespace hdeform::cli {

namespace pbu = google::protobuf::util;

bool snapshot_path_is_json(const std::string& path) {
  if (path.size() < 5) return false;
  std::string ext = path.substr(path.size() - 5);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".json";
}

std::size_t write_snapshot(const std::string& path, const pb::Snapshot& snapshot) {
  std::string bytes;
  if (snapshot_path_is_json(path)) {
    pbu::JsonPrintOptions o;
    o.add_whitespace = true;
    o.preserve_proto_field_names = true;  // the .proto's names, as in docs/api.md
    const auto st = pbu::MessageToJsonString(snapshot, &bytes, o);
    if (!st.ok()) throw CliError(path + ": cannot encode the snapshot as JSON: " +
                                 std::string(st.message()));
  } else if (!snapshot.SerializeToString(&bytes)) {
    throw CliError(path + ": cannot encode the snapshot");
  }
  write_file(path, bytes);
  return bytes.size();
}

pb::Snapshot read_snapshot(const std::string& path) {
  const std::string bytes = read_file(path);
  const auto first = std::find_if(bytes.begin(), bytes.end(),
                                  [](unsigned char c) { return !std::isspace(c); });
  pb::Snapshot snap;
  if (first != bytes.end() && *first == '{') {
    const auto st = pbu::JsonStringToMessage(bytes, &snap);  // unknown keys are errors
    if (!st.ok())
      throw CliError(path + ": not a session snapshot (JSON: " + std::string(st.message()) +
                     ")");
  } else {
    // Binary protobuf parses almost any bytes; fields a Snapshot does not have betray a
    // file that is something else.
    if (!snap.ParseFromString(bytes) ||
        !snap.GetReflection()->GetUnknownFields(snap).empty())
      throw CliError(path + ": not a session snapshot (neither a binary Snapshot nor JSON; "
                            "write one with hdeform sessions export)");
  }
  if (snap.mesh_hash().empty() && snap.library_mesh().empty() && snap.mesh_bytes().empty())
    throw CliError(path + ": not a session snapshot (it names no mesh)");
  return snap;
}

}  // namespace hdeform::cli
