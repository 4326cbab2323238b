// What a session gives out and takes in whole: sweeps, deformed positions, mesh files,
// snapshots for export and restore, and a handle's harmonic weights.
#include "service/session/session.h"

#include "engine/io/mesh_io.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/session_detail.h"

#include <spdlog/spdlog.h>

#include <filesystem>

namespace hdeform::service {

using detail::kNoConstraints;
using detail::make_field;

namespace {
MeshFileFormat file_format(pb::MeshFormat f) {
  switch (f) {
    case pb::MESH_FORMAT_OBJ: return MeshFileFormat::obj;
    case pb::MESH_FORMAT_OFF: return MeshFileFormat::off;
    case pb::MESH_FORMAT_PLY: return MeshFileFormat::ply;
    case pb::MESH_FORMAT_GLB: return MeshFileFormat::glb;
    default: break;
  }
  fail(grpc::StatusCode::INVALID_ARGUMENT, "unknown mesh format " + std::to_string(f));
}
}  // namespace

Vertices Session::deformed_positions() {
  std::shared_ptr<const ConstraintSet> cs;
  std::vector<HandleTransform> transforms;
  SessionBeta beta;
  std::int64_t version;
  {
    std::lock_guard lock(mutex_);
    if (!cs_) return mesh_->prepared->mesh().V;
    // Only an exact frame answers GetMesh (a drag frame is within kDragTolerance only).
    if (last_frame_ && last_frame_version_ == version_ && last_frame_->exact)
      return last_frame_->positions;
    cs = cs_;
    transforms = transforms_;
    beta = beta_;
    version = version_;
  }
  UpdateOptions options;
  options.energies = false;
  options.normals = false;
  auto frame = std::make_shared<const hdeform::Frame>(solve_at(*cs, transforms, beta, options));
  std::lock_guard lock(mutex_);
  if (version == version_) {
    last_frame_ = frame;
    last_frame_version_ = version;
  }
  return frame->positions;
}

std::string Session::mesh_file(const pb::GetMeshRequest& request) {
  touch();
  const bool rest = request.rest();
  const MeshFileFormat f = file_format(request.format());
  const pb::UpAxis up = request.up();
  const pb::PlyEncoding ply = request.ply_encoding();
  if (up != pb::UP_AXIS_Y && up != pb::UP_AXIS_Z)
    throw InvalidInput("GetMesh: unknown up axis " + std::to_string(up));
  if (ply < pb::PLY_ENCODING_AS_INPUT || ply > pb::PLY_ENCODING_BINARY)
    throw InvalidInput("GetMesh: unknown PLY encoding " + std::to_string(ply));
  WriteOptions options;
  switch (request.glb_compression()) {
    case pb::GLB_COMPRESSION_NONE: break;
    case pb::GLB_COMPRESSION_QUANTIZED: options.glb_compression = GlbCompression::quantized; break;
    case pb::GLB_COMPRESSION_MESHOPT: options.glb_compression = GlbCompression::meshopt; break;
    default:
      throw InvalidInput("GetMesh: unknown glb_compression " +
                         std::to_string(request.glb_compression()));
  }
  const bool compressed = options.glb_compression != GlbCompression::none;
  if (compressed && f != MeshFileFormat::glb)
    throw InvalidInput("GetMesh: glb_compression applies to GLB only, not to " +
                       pb::MeshFormat_Name(request.format()));
  options.up_z = up == pb::UP_AXIS_Z;
  // A binary PLY upload comes back binary: its header says so in the first line after "ply".
  const bool input_binary_ply =
      mesh_->file_bytes && mesh_->file_bytes->compare(0, 24, "ply\nformat binary_little") == 0;
  options.binary_ply = ply == pb::PLY_ENCODING_BINARY ||
                       (ply == pb::PLY_ENCODING_AS_INPUT && input_binary_ply);
  if (rest && f == MeshFileFormat::glb && !options.up_z && !compressed)
    return mesh_->layout->base_glb();
  const Vertices V = rest ? mesh_->prepared->mesh().V : deformed_positions();
  // A glTF upload's deformed GLB is its own file with new positions and normals: UVs,
  // materials, textures, nodes and other primitives stay (glTF is y-up already).
  std::string ext = std::filesystem::path(mesh_->filename).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool gltf_upload =
      mesh_->file_bytes && mesh_->library_name.empty() && (ext == ".glb" || ext == ".gltf");
  if (!rest && f == MeshFileFormat::glb && gltf_upload) {
    if (compressed)
      throw InvalidInput("GetMesh: glb_compression: this session's deformed GLB is its glTF "
                         "upload rewritten (materials and UVs kept), which is not compressed; "
                         "ask GLB_COMPRESSION_NONE, or rest = true for the compressed base mesh");
    return mesh_->layout->input_gltf(*mesh_->file_bytes, mesh_->filename, V);
  }
  return mesh_->layout->mesh_file(f, V, options);
}

pb::Snapshot Session::export_snapshot(bool include_mesh, std::int64_t* version) const {
  pb::Snapshot s;
  s.set_mesh_hash(mesh_->hash);
  s.set_library_mesh(mesh_->library_name);
  s.set_filename(mesh_->library_name.empty() ? upload_name_ : mesh_->filename);
  if (include_mesh && mesh_->file_bytes) s.set_mesh_bytes(*mesh_->file_bytes);
  if (mesh_->repair) s.mutable_repair()->set_merge_tolerance(mesh_->repair->merge_tolerance);
  std::lock_guard lock(mutex_);
  if (version) *version = version_;
  if (cs_ && given_) *s.mutable_constraints() = *given_;
  beta_to_proto(beta_, s.mutable_beta());
  for (const auto& t : transforms_) to_proto(t, s.add_transforms());
  if (timeline_->keys_size() > 0) *s.mutable_timeline() = *timeline_;
  return s;
}

void Session::name_upload(const std::string& filename) {
  if (!mesh_->library_name.empty() || filename.empty()) return;
  upload_name_ = std::filesystem::path(filename).filename().string();
  // The name must keep saying the bytes' format (an export re-imports by it).
  const auto ext = std::filesystem::path(mesh_->filename).extension().string();
  const auto given = std::filesystem::path(upload_name_).extension().string();
  if (!std::equal(ext.begin(), ext.end(), given.begin(), given.end(),
                  [](char a, char b) { return std::tolower(a) == std::tolower(b); }))
    upload_name_ += ext;
}

const std::string& Session::mesh_name() const {
  return mesh_->library_name.empty() ? upload_name_ : mesh_->library_name;
}

bool snapshot_has_constraints(const pb::Snapshot& s) {
  return s.has_constraints() &&
         (s.constraints().fixed().selectors_size() > 0 || s.constraints().handles_size() > 0);
}

void Session::restore(const pb::Snapshot& s) {
  name_upload(s.filename());
  // An automatic β keeps the snapshot's pick (`value`): the restored session deforms exactly
  // as the exported one, whatever transforms the pick was made at.
  SessionBeta beta = s.has_beta() ? parse_beta(s.beta(), true) : SessionBeta{};
  {
    std::lock_guard lock(mutex_);
    beta_ = std::move(beta);
  }
  if (!snapshot_has_constraints(s)) {
    if (s.transforms_size() > 0)
      throw InvalidInput("snapshot has transforms but no constraints");
    return;
  }
  set_constraints(s.constraints(), 0);
  std::shared_ptr<const ConstraintSet> cs;
  {
    std::lock_guard lock(mutex_);
    cs = cs_;
  }
  std::vector<HandleTransform> transforms =
      s.transforms_size() > 0 ? from_proto(s.transforms(), *cs)
                              : std::vector<HandleTransform>(cs->num_handles());
  if (s.timeline().keys_size() > 0) parse_timeline(s.timeline(), *cs);  // a bad one is refused
  std::lock_guard lock(mutex_);
  transforms_ = std::move(transforms);
  timeline_ = std::make_shared<const pb::Timeline>(s.timeline());
  ++version_;
  last_frame_.reset();
}

void Session::adopt(std::int64_t version, const SessionTokens& tokens, std::int64_t create_ms,
                    std::int64_t update_ms) {
  std::lock_guard lock(mutex_);
  version_ = version;
  // Not stored: a client's config_version from before the restart is refused (it reloads).
  config_version_ = version;
  tokens_ = tokens;
  history_.clear();  // adopt_history brings the stored one
  create_ms_ = create_ms;
  update_ms_ = update_ms;
}

pb::HandleWeights Session::handle_weights(int handle) const {
  std::shared_ptr<const ConstraintSet> cs;
  pb::HandleWeights out;
  {
    std::lock_guard lock(mutex_);
    if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
    cs = cs_;
    out.set_version(version_);
  }
  if (handle < 0 || handle >= cs->num_handles())
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "GetHandleWeights: handle " + std::to_string(handle) + " is not a handle of " + name_ +
             " (it has " + std::to_string(cs->num_handles()) + ")");
  out.set_handle(handle);
  out.set_weights(mesh_->layout->pack_vertex_scalars(cs->harmonic_basis(), handle));
  return out;
}

}  // namespace hdeform::service
