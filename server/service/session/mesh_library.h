// Where session meshes come from: the server's library folder (--mesh-dir) and uploads.
// A MeshRef is immutable and shared: identical files share one MeshRef, and every file
// whose engine mesh has the same content hash shares one PreparedMesh.
#pragma once

#include "engine/deform/deformer.h"
#include "engine/io/mesh_io.h"
#include "engine/mesh/repair.h"
#include "service/frames/frames.h"
#include "service/infra/cache.h"

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hdeform::service {

struct MeshRef {
  std::string hash;          // content hash of the engine mesh (V and F bytes)
  std::string library_name;  // set for library meshes
  std::string filename;      // upload file name (its extension is the format)
  std::shared_ptr<const std::string> file_bytes;  // the original file
  std::shared_ptr<const PreparedMesh> prepared;
  std::shared_ptr<const FrameLayout> layout;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero(), bbox_max = Eigen::Vector3d::Zero();
  std::vector<std::string> warnings;
  // An upload repaired on request (CreateSessionHeader.repair): the options, what changed,
  // and base-GLB vertex → the upload's vertex id (empty: the same ids).
  std::optional<RepairOptions> repair;
  RepairReport repair_report;
  std::vector<int> repair_base_to_input;

  const std::string& display_name() const {
    return library_name.empty() ? filename : library_name;
  }
  std::size_t memory_bytes() const;  // excluding the shared PreparedMesh
};

struct LibraryEntry {
  std::string name;  // file stem
  std::string path;           // on the server's disk: never sent to clients
  std::string relative_path;  // inside the library folder (what ListMeshes shows)
  bool has_benchmark = false;  // NAME.sel and NAME.def beside it
};

class MeshLibrary {
 public:
  explicit MeshLibrary(std::string dir);
  const std::string& dir() const { return dir_; }
  // The folder and its sub-folders (two levels: data/models, data/botsch-sorkine), sorted
  // by path; the first file of a stem wins.
  std::vector<LibraryEntry> list() const;
  std::optional<LibraryEntry> find(const std::string& name) const;

 private:
  std::string dir_;
};

// The bundled data/ folder (compile-time path), or "" when it does not exist.
std::string default_mesh_dir();

// Parses a mesh file, enforces the vertex limit while parsing (LimitExceeded →
// RESOURCE_EXHAUSTED), polls limits' cancellation (ReadCancelled → CANCELLED), repairs it
// when asked (repair_loaded_mesh) and finds or builds its MeshRef / PreparedMesh in the
// cache. Throws InvalidInput for a bad mesh. order: when a PreparedMesh built here orders
// its β = 0 system (a session's open leaves it to the background orders while its user
// picks regions; a restore that factors at once and has no stored order asks for it now).
std::shared_ptr<const MeshRef> load_mesh(std::shared_ptr<const std::string> bytes,
                                         const std::string& filename,
                                         const std::string& library_name, Cache& cache,
                                         const ReadLimits& limits,
                                         const std::optional<RepairOptions>& repair = {},
                                         PrepareOrder order = PrepareOrder::on_first_use);

std::string read_file(const std::string& path);  // throws ServiceError NOT_FOUND

// What the repair of a repaired upload changed (MeshRef::repair set).
void describe_repair(const MeshRef& mesh, hdeform::v1::MeshRepairReport* out);

}  // namespace hdeform::service
