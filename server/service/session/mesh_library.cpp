#include "service/session/mesh_library.h"

#include "engine/io/mesh_io.h"
#include "engine/io/repair_loaded.h"
#include "service/infra/service_error.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace fs = std::filesystem;

namespace hdeform::service {

namespace {
bool is_mesh_extension(std::string ext) {
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  static const std::set<std::string> kExt = {".off", ".obj", ".ply", ".stl", ".glb", ".gltf"};
  return kExt.count(ext) > 0;
}
}  // namespace

std::size_t MeshRef::memory_bytes() const {
  std::size_t b = sizeof(MeshRef) + (file_bytes ? file_bytes->size() : 0) +
                  sizeof(int) * repair_base_to_input.size();
  if (layout) b += 16u * static_cast<std::size_t>(layout->vertex_count()) +
                   12u * static_cast<std::size_t>(layout->triangle_count());
  return b;
}

MeshLibrary::MeshLibrary(std::string dir) : dir_(std::move(dir)) {}

std::vector<LibraryEntry> MeshLibrary::list() const {
  std::vector<LibraryEntry> out;
  if (dir_.empty()) return out;
  std::error_code ec;
  if (!fs::is_directory(dir_, ec)) return out;
  std::vector<fs::path> files;
  for (auto it = fs::recursive_directory_iterator(
           dir_, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it.depth() > 1) {
      it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file(ec) && is_mesh_extension(it->path().extension().string()))
      files.push_back(it->path());
  }
  std::sort(files.begin(), files.end());
  std::set<std::string> seen;
  for (const auto& p : files) {
    LibraryEntry e;
    e.name = p.stem().string();
    if (!seen.insert(e.name).second) continue;
    e.path = p.string();
    e.relative_path = p.lexically_relative(dir_).generic_string();
    fs::path sel = p, def = p;
    sel.replace_extension(".sel");
    def.replace_extension(".def");
    e.has_benchmark = fs::exists(sel, ec) && fs::exists(def, ec);
    out.push_back(std::move(e));
  }
  return out;
}

std::optional<LibraryEntry> MeshLibrary::find(const std::string& name) const {
  for (auto& e : list())
    if (e.name == name) return e;
  return std::nullopt;
}

std::string default_mesh_dir() {
#ifdef HDEFORM_DATA_DIR
  std::error_code ec;
  if (fs::is_directory(HDEFORM_DATA_DIR, ec)) return HDEFORM_DATA_DIR;
#endif
  return "";
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(grpc::StatusCode::NOT_FOUND, "cannot open mesh file " + path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return std::move(ss).str();
}

std::shared_ptr<const MeshRef> load_mesh(std::shared_ptr<const std::string> bytes,
                                         const std::string& filename,
                                         const std::string& library_name, Cache& cache,
                                         const ReadLimits& limits,
                                         const std::optional<RepairOptions>& repair,
                                         PrepareOrder order) {
  std::string ext = fs::path(filename).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (!is_mesh_extension(ext))
    throw InvalidInput("unsupported mesh format '" + filename +
                       "' (use .obj .off .ply .stl .gltf .glb)");
  // Identical files (same format, same bytes) share one MeshRef. SHA-256 keys, and every
  // hit is verified byte for byte: a shared entry can be neither forged nor mistaken.
  std::string file_key =
      "file/" + Sha256().add(ext).add(std::string_view("\0", 1)).add(*bytes).hex() + "/" +
      library_name;
  if (repair) file_key += fmt::format("/repair:{}", repair->merge_tolerance);
  auto build = [&]() -> std::shared_ptr<const MeshRef> {
    // The vertex limit is applied while parsing (a header count over it fails at once).
    LoadedMesh loaded = read_mesh_bytes(*bytes, filename, limits);
    auto r = std::make_shared<MeshRef>();
    if (repair) {
      r->repair = repair;
      r->repair_report = repair_loaded_mesh(loaded, *repair);
      if (loaded.repair_renumbered) r->repair_base_to_input = loaded.repair_to_input;
    }
    r->hash = mesh_hash(loaded.mesh);
    r->library_name = library_name;
    r->filename = fs::path(filename).filename().string();
    r->file_bytes = bytes;
    r->warnings = loaded.warnings;
    if (loaded.mesh.num_vertices() > 0) {
      r->bbox_min = loaded.mesh.V.colwise().minCoeff().transpose();
      r->bbox_max = loaded.mesh.V.colwise().maxCoeff().transpose();
    }
    auto make_prepared = [&]() -> std::shared_ptr<const PreparedMesh> {
      spdlog::info("preparing mesh {} ({} vertices, {} triangles)", r->hash,
                   loaded.mesh.num_vertices(), loaded.mesh.num_triangles());
      return PreparedMesh::create(loaded.mesh, order);
    };
    r->prepared = cache.get_or_create<PreparedMesh>(
        "mesh/" + r->hash, make_prepared, [](const PreparedMesh& pm) { return pm.memory_bytes(); });
    if (r->prepared->mesh().V != loaded.mesh.V || r->prepared->mesh().F != loaded.mesh.F) {
      spdlog::warn("cache: mesh/{} holds different geometry; preparing a private copy", r->hash);
      r->prepared = make_prepared();
    }
    loaded.mesh = TriMesh{};  // the prepared mesh keeps the geometry
    r->layout = std::make_shared<const FrameLayout>(std::move(loaded), r->prepared);
    return r;
  };
  auto ref = cache.get_or_create<MeshRef>(file_key, build,
                                          [](const MeshRef& r) { return r.memory_bytes(); });
  if (!ref->file_bytes || *ref->file_bytes != *bytes) {
    spdlog::warn("cache: {} holds a different file; loading a private copy", file_key);
    ref = build();
  }
  return ref;
}

void describe_repair(const MeshRef& mesh, hdeform::v1::MeshRepairReport* out) {
  const RepairReport& r = mesh.repair_report;
  out->set_merged_vertices(r.merged_vertices);
  out->set_degenerate_triangles(r.degenerate_triangles);
  out->set_duplicate_triangles(r.duplicate_triangles);
  out->set_unreferenced_vertices(r.unreferenced_vertices);
  out->set_split_vertices(r.split_vertices);
  out->set_added_vertices(r.added_vertices);
  for (const auto& line : r.lines) out->add_lines(line);
  out->mutable_base_to_input()->Add(mesh.repair_base_to_input.begin(),
                                    mesh.repair_base_to_input.end());
}

}  // namespace hdeform::service
