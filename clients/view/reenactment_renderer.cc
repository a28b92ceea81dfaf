#include "clients/view/reenactment_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/geometry/camera.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/video_reader.h"
#include "common/render/intrinsics_camera.h"
#include "common/render/mesh_data.h"

namespace reenact::view {
namespace {

// Spreads the colours of opaque texels into the transparent texels next to
// them, `rings` texels deep, so that bilinear filtering at the mask's edge
// does not blend in the background's colour (the alpha test still cuts there).
void BleedColours(render::RgbaImage* image, int rings) {
  const int w = image->width, h = image->height;
  std::vector<uint8_t> filled(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) filled[static_cast<size_t>(y) * w + x] = image->at(x, y, 3) >= 128;
  }
  for (int ring = 0; ring < rings; ++ring) {
    std::vector<uint8_t> next = filled;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (filled[static_cast<size_t>(y) * w + x]) continue;
        int sum[3] = {0, 0, 0}, count = 0;
        const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
        for (int n = 0; n < 4; ++n) {
          const int nx = x + dx[n], ny = y + dy[n];
          if (nx < 0 || ny < 0 || nx >= w || ny >= h || !filled[static_cast<size_t>(ny) * w + nx]) {
            continue;
          }
          for (int c = 0; c < 3; ++c) sum[c] += image->at(nx, ny, c);
          ++count;
        }
        if (count == 0) continue;
        for (int c = 0; c < 3; ++c) image->at(x, y, c) = static_cast<uint8_t>(sum[c] / count);
        next[static_cast<size_t>(y) * w + x] = 1;
      }
    }
    filled = std::move(next);
  }
}

// The keyframe's crop with its actor mask as alpha (the mask resampled to the
// crop image's size when they differ; no mask: all opaque).
absl::StatusOr<render::RgbaImage> DecodeKeyframe(const TextureKeyframe& keyframe) {
  auto colour = DecodeJpeg(keyframe.color_jpeg);
  if (!colour.ok()) {
    return absl::DataLossError(absl::StrCat("keyframe of frame ", keyframe.frame_index, ", sensor ",
                                            keyframe.sensor_id,
                                            ": colour: ", colour.status().message()));
  }
  MaskImage mask;
  if (!keyframe.mask_rle.empty()) {
    auto decoded = DecodeMaskRle(keyframe.mask_rle);
    if (!decoded.ok()) {
      return absl::DataLossError(absl::StrCat("keyframe of frame ", keyframe.frame_index,
                                              ", sensor ", keyframe.sensor_id,
                                              ": mask: ", decoded.status().message()));
    }
    mask = std::move(*decoded);
  }
  render::RgbaImage image(colour->width, colour->height);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = colour->at(x, y, c);
      bool actor = true;
      if (!mask.empty()) {
        const int mx = std::min(mask.width - 1, x * mask.width / image.width);
        const int my = std::min(mask.height - 1, y * mask.height / image.height);
        actor = mask.at(mx, my) > 0;
      }
      image.at(x, y, 3) = actor ? 255 : 0;
    }
  }
  if (!mask.empty()) BleedColours(&image, 3);
  return image;
}

}  // namespace

// The triangles of one part drawn with one texture.
struct ReenactmentRenderer::Group {
  int part = 0;
  int keyframe = -1;          // Texture source; -1: baked or untextured.
  bool baked = false;         // Baked texture and the mesh's own uvs.
  bool underlay = false;      // Drawn behind the keyframe groups (DrawItem::underlay).
  float blend_weight = 1.0f;  // Below 1: a second keyframe blended over the first.
  render::TextureId texture;  // Invalid: untextured (lit flat colour).
  int texture_width = 0, texture_height = 0;
  std::vector<int> triangles;  // Indices into the part's triangles.
};

struct ReenactmentRenderer::Body {
  bool uploaded = false;    // Upload tried (mesh and atlas).
  render::MeshId gpu_mesh;  // Over the texture vertices; positions per frame.
  render::TextureId atlas;  // Invalid: no atlas (lit flat colour).
  // Per-frame appearance: the video's reader (null: the static atlas) and
  // the texture of the frame last drawn.
  std::unique_ptr<VideoReader> appearance;
  render::TextureId frame_texture;
  int frame_texture_index = -1;
};

absl::StatusOr<TextureMode> ParseTextureMode(const std::string& name) {
  if (name == "vdtm") return TextureMode::kVdtm;
  if (name == "baked") return TextureMode::kBaked;
  return absl::InvalidArgumentError(
      absl::StrCat("texture mode must be 'vdtm' or 'baked', got '", name, "'"));
}

absl::Status ReenactmentRendererOptions::Validate() const {
  if (texture_cache_bytes < 0) {
    return absl::InvalidArgumentError("texture_cache_bytes must be >= 0");
  }
  if (!(untextured_srgb.array() >= 0.0f).all() || !(untextured_srgb.array() <= 1.0f).all()) {
    return absl::InvalidArgumentError("untextured_srgb must lie in [0, 1]");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<ReenactmentRenderer>> ReenactmentRenderer::Create(
    const Reenactment& data, render::OffscreenRenderer* renderer,
    const ReenactmentRendererOptions& options) {
  if (renderer == nullptr) return absl::InvalidArgumentError("ReenactmentRenderer: no renderer");
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(VdtmModel model, VdtmModel::Create(data));
  std::unique_ptr<Body> body;
  if (data.is_body()) body = std::make_unique<Body>();
  return std::unique_ptr<ReenactmentRenderer>(
      new ReenactmentRenderer(data, renderer, options, std::move(model), std::move(body)));
}

ReenactmentRenderer::ReenactmentRenderer(const Reenactment& data,
                                         render::OffscreenRenderer* renderer,
                                         const ReenactmentRendererOptions& options, VdtmModel model,
                                         std::unique_ptr<Body> body)
    : data_(data),
      renderer_(renderer),
      options_(options),
      selection_(options.selection_from_method ? SelectionForReenactment(data.info)
                                               : options.selection),
      underlay_baked_(options.underlay_from_method ? selection_ == TextureSelection::kRotation
                                                   : options.underlay_baked),
      model_(std::move(model)),
      baked_(model_.num_parts()),
      baked_tried_(model_.num_parts(), false),
      body_(std::move(body)) {}

ReenactmentRenderer::~ReenactmentRenderer() {
  if (body_ != nullptr && body_->gpu_mesh.valid()) {
    renderer_->ReleaseMesh(body_->gpu_mesh).IgnoreError();
  }
  if (body_ != nullptr && body_->atlas.valid()) {
    renderer_->ReleaseTexture(body_->atlas).IgnoreError();
  }
  if (body_ != nullptr && body_->frame_texture.valid()) {
    renderer_->ReleaseTexture(body_->frame_texture).IgnoreError();
  }
  for (auto& [keyframe, texture] : textures_) renderer_->ReleaseTexture(texture.id).IgnoreError();
  for (render::TextureId id : baked_) {
    if (id.valid()) renderer_->ReleaseTexture(id).IgnoreError();
  }
}

absl::StatusOr<const ReenactmentRenderer::CachedTexture*> ReenactmentRenderer::KeyframeTexture(
    int keyframe, int* uploaded) {
  if (auto it = textures_.find(keyframe); it != textures_.end()) {
    lru_.splice(lru_.begin(), lru_, it->second.lru);  // Most recently used.
    return &it->second;
  }
  ASSIGN_OR_RETURN(render::RgbaImage image, DecodeKeyframe(data_.keyframes[keyframe]));
  CachedTexture texture;
  ASSIGN_OR_RETURN(texture.id, renderer_->UploadTexture(image));
  texture.width = image.width;
  texture.height = image.height;
  texture.bytes = static_cast<int64_t>(image.width) * image.height * 4 * 4 / 3;  // With mipmaps.
  lru_.push_front(keyframe);
  texture.lru = lru_.begin();
  cache_bytes_ += texture.bytes;
  ++*uploaded;
  return &(textures_[keyframe] = texture);
}

absl::StatusOr<render::TextureId> ReenactmentRenderer::BakedTexture(int part) {
  if (baked_tried_[part]) return baked_[part];
  baked_tried_[part] = true;
  const PartMesh& mesh = data_.parts[part];
  if (mesh.baked_texture_jpeg.empty() || mesh.uvs.cols() == 0) return render::TextureId();
  auto image = DecodeJpeg(mesh.baked_texture_jpeg);
  if (!image.ok()) {
    return absl::DataLossError(
        absl::StrCat("baked texture of part ", part, ": ", image.status().message()));
  }
  ASSIGN_OR_RETURN(baked_[part], renderer_->UploadTexture(*image));
  return baked_[part];
}

void ReenactmentRenderer::EvictTextures() {
  // Least recently used first; runs after a frame is drawn, so the frame's
  // own textures (the most recent) go last.
  while (cache_bytes_ > options_.texture_cache_bytes && !lru_.empty()) {
    auto texture = textures_.find(lru_.back());
    renderer_->ReleaseTexture(texture->second.id).IgnoreError();
    cache_bytes_ -= texture->second.bytes;
    textures_.erase(texture);
    lru_.pop_back();
  }
}

absl::Status ReenactmentRenderer::BuildVdtmGroups(int frame,
                                                  const Eigen::Isometry3d& camera_from_world,
                                                  std::vector<Group>* groups, FrameStats* stats) {
  std::vector<int> pose_ranking;
  std::vector<double> pose_distances;
  if (selection_ == TextureSelection::kPose) {
    // Eq. 3.6, all parts.
    pose_ranking = model_.RankByPose(frame, camera_from_world, &pose_distances);
  }
  for (int b = 0; b < model_.num_parts(); ++b) {
    if (!model_.pose(frame, b).valid || model_.part(b).triangles.empty()) continue;
    ++stats->parts_drawn;
    std::vector<double> angles;
    const std::vector<int> ranking =
        selection_ == TextureSelection::kPose
            ? pose_ranking
            : model_.RankByRotation(frame, b, camera_from_world, &angles);
    const std::vector<double>& distances =
        selection_ == TextureSelection::kPose ? pose_distances : angles;
    int best = -1;
    for (int k : ranking) {
      if (model_.pose(model_.keyframe(k).frame, b).valid) {
        best = k;
        break;
      }
    }
    stats->best_keyframe[b] = best;
    int next_best = 0;
    std::vector<int> second;
    const std::vector<int> chosen = model_.AssignTriangles(
        b, ranking, &next_best, options_.blend_keyframes ? &second : nullptr);
    stats->triangles_next_best += next_best;
    ASSIGN_OR_RETURN(render::TextureId baked, BakedTexture(b));
    if (baked.valid() && underlay_baked_) {
      Group under;
      under.part = b;
      under.baked = true;
      under.underlay = true;
      under.texture = baked;
      under.triangles.resize(chosen.size());
      for (size_t t = 0; t < chosen.size(); ++t) under.triangles[t] = static_cast<int>(t);
      groups->push_back(std::move(under));
    }
    std::map<int, Group> by_keyframe;  // Keyframe -> group; -2: baked; -1: untextured.
    for (size_t t = 0; t < chosen.size(); ++t) {
      int source = chosen[t];
      if (source < 0) {
        ++stats->triangles_unseen;
        source = baked.valid() ? -2 : best;
      }
      Group& group = by_keyframe[source];
      group.part = b;
      group.triangles.push_back(static_cast<int>(t));
    }
    // The second keyframe over the first, weighted by the inverse of the
    // ranking distances: w2 = d1 / (d1 + d2), so a view that matches the
    // first exactly shows it alone and one halfway between shows both
    // equally. Grouped by keyframe and weight (in 1/32 steps).
    std::map<std::pair<int, int>, Group> blended;
    if (!second.empty()) {
      // Ranking distance per keyframe (NaN: not ranked).
      std::vector<double> distance_of(static_cast<size_t>(model_.num_keyframes()),
                                      std::numeric_limits<double>::quiet_NaN());
      for (size_t r = 0; r < ranking.size() && r < distances.size(); ++r) {
        if (ranking[r] >= 0 && ranking[r] < model_.num_keyframes()) {
          distance_of[ranking[r]] = distances[r];
        }
      }
      const auto distance = [&](int k) {
        return k < static_cast<int>(distance_of.size()) ? distance_of[k]
                                                        : std::numeric_limits<double>::quiet_NaN();
      };
      for (size_t t = 0; t < chosen.size(); ++t) {
        if (chosen[t] < 0 || second[t] < 0) continue;
        const double d1 = distance(chosen[t]);
        const double d2 = distance(second[t]);
        if (!std::isfinite(d1) || !std::isfinite(d2) || d1 + d2 <= 0.0) continue;
        const int steps = static_cast<int>(std::lround(32.0 * d1 / (d1 + d2)));
        if (steps < 2) continue;  // Under 1/16: the first alone.
        Group& group = blended[{second[t], steps}];
        group.part = b;
        group.blend_weight = static_cast<float>(steps) / 32.0f;
        group.triangles.push_back(static_cast<int>(t));
        ++stats->triangles_blended;
      }
    }
    for (auto& [source, group] : by_keyframe) {
      if (source >= 0) {
        ASSIGN_OR_RETURN(const CachedTexture* texture,
                         KeyframeTexture(source, &stats->textures_uploaded));
        group.keyframe = source;
        group.texture = texture->id;
        group.texture_width = texture->width;
        group.texture_height = texture->height;
      } else if (source == -2) {
        group.baked = true;
        group.texture = baked;
      }
      groups->push_back(std::move(group));
    }
    for (auto& [key, group] : blended) {
      ASSIGN_OR_RETURN(const CachedTexture* texture,
                       KeyframeTexture(key.first, &stats->textures_uploaded));
      group.keyframe = key.first;
      group.texture = texture->id;
      group.texture_width = texture->width;
      group.texture_height = texture->height;
      groups->push_back(std::move(group));
    }
  }
  return absl::OkStatus();
}

absl::Status ReenactmentRenderer::BuildBakedGroups(int frame, std::vector<Group>* groups,
                                                   FrameStats* stats) {
  for (int b = 0; b < model_.num_parts(); ++b) {
    const PartMesh& part = model_.part(b);
    if (!model_.pose(frame, b).valid || part.triangles.empty()) continue;
    ++stats->parts_drawn;
    Group group;
    group.part = b;
    ASSIGN_OR_RETURN(group.texture, BakedTexture(b));
    group.baked = group.texture.valid();
    group.triangles.resize(part.triangles.size());
    for (size_t t = 0; t < part.triangles.size(); ++t) group.triangles[t] = static_cast<int>(t);
    groups->push_back(std::move(group));
  }
  return absl::OkStatus();
}

absl::StatusOr<render::MeshData> ReenactmentRenderer::GroupMesh(int frame,
                                                                const Group& group) const {
  const PartMesh& part = model_.part(group.part);
  const double scale = model_.pose(frame, group.part).scale;
  std::vector<int> new_index(part.positions_in_part_m.cols(), -1);
  std::vector<int> used;
  render::MeshData mesh;
  for (int t : group.triangles) {
    Eigen::Vector3i triangle;
    for (int c = 0; c < 3; ++c) {
      int& index = new_index[part.triangles[t][c]];
      if (index < 0) {
        index = static_cast<int>(used.size());
        used.push_back(part.triangles[t][c]);
      }
      triangle[c] = index;
    }
    mesh.triangles.push_back(triangle);
  }
  const int n = static_cast<int>(used.size());
  mesh.positions_m.resize(3, n);
  if (part.normals_in_part.cols() > 0) mesh.normals.resize(3, n);
  if (group.texture.valid()) mesh.uvs.resize(2, n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f x = part.positions_in_part_m.col(used[i]);
    // Cylinders scale with the segment (PartPose.scale); the draw item's
    // pose is the rigid rest of world_from_part.
    mesh.positions_m.col(i) = static_cast<float>(scale) * x;
    if (mesh.normals.cols() > 0) mesh.normals.col(i) = part.normals_in_part.col(used[i]);
    if (group.baked) {
      mesh.uvs.col(i) = part.uvs.col(used[i]);
    } else if (group.keyframe >= 0) {
      // Eq. 3.14-3.15 through the part's pose at the keyframe's instant.
      mesh.uvs.col(i) = model_.KeyframeUv(group.keyframe, group.part, x, group.texture_width,
                                          group.texture_height);
    }
  }
  return mesh;
}

absl::Status ReenactmentRenderer::UploadBody(FrameStats* stats) {
  if (body_->uploaded) return absl::OkStatus();
  body_->uploaded = true;  // Once, whether or not the atlas decodes.
  const BodyMesh& body = *data_.body;
  const std::string& jpeg = body.atlas_jpeg;
  absl::Status atlas_status;
  if (!jpeg.empty()) {
    auto image = DecodeJpeg(jpeg);
    if (image.ok()) {
      ASSIGN_OR_RETURN(body_->atlas, renderer_->UploadTexture(*image));
      ++stats->textures_uploaded;
    } else {
      atlas_status = absl::DataLossError(absl::StrCat("body atlas of ", data_.info.reenactment_id,
                                                      ": ", image.status().message()));
    }
  }
  const Eigen::Matrix3Xf rest = body.rest_vertices_m.cast<float>();
  const Eigen::Matrix3Xf rest_normals = render::ComputeVertexNormals(rest, body.triangles);
  const int n = static_cast<int>(body.texture_vertex_source.size());
  render::MeshData mesh;
  mesh.positions_m.resize(3, n);
  mesh.normals.resize(3, n);
  mesh.uvs.resize(2, n);
  mesh.source_vertex.resize(n);
  mesh.num_source_vertices = body.num_vertices();
  for (int i = 0; i < n; ++i) {
    const int source = static_cast<int>(body.texture_vertex_source[i]);
    mesh.source_vertex[i] = source;
    mesh.positions_m.col(i) = rest.col(source);
    mesh.normals.col(i) = rest_normals.col(source);
    mesh.uvs.col(i) = body.texture_uvs[i];
  }
  mesh.triangles = body.texture_triangles;
  ASSIGN_OR_RETURN(body_->gpu_mesh, renderer_->UploadMesh(mesh));
  OpenAppearance();
  return atlas_status;
}

void ReenactmentRenderer::OpenAppearance() {
  const BodyMesh& body = *data_.body;
  if (!options_.appearance || body.appearance_mp4.empty()) return;
  const int frames = static_cast<int>(data_.frames.size());
  const auto fall_back = [this](const std::string& why) {
    appearance_note_ = absl::StrCat("per-frame appearance not drawn (", why,
                                    "): the static atlas is drawn instead");
    body_->appearance.reset();
  };
  if (body.appearance_frame_count != frames) {
    return fall_back(absl::StrCat("the video says ", body.appearance_frame_count, " frames for ",
                                  frames, " instants"));
  }
  auto reader = VideoReader::Open(body.appearance_mp4);
  if (!reader.ok()) return fall_back(std::string(reader.status().message()));
  if ((*reader)->frame_count() != frames) {
    return fall_back(absl::StrCat("the video holds ", (*reader)->frame_count(), " frames for ",
                                  frames, " instants"));
  }
  body_->appearance = std::move(*reader);
}

render::TextureId ReenactmentRenderer::BodyTexture(int frame, FrameStats* stats) {
  if (body_->appearance == nullptr) return body_->atlas;
  if (body_->frame_texture_index == frame) {
    stats->per_frame_appearance = true;
    return body_->frame_texture;
  }
  // The video's frames share one size, so one texture is updated in place
  // frame after frame; it is allocated with the first.
  absl::StatusOr<RgbImage> image = body_->appearance->Frame(frame);
  absl::Status status = image.status();
  if (status.ok() && body_->frame_texture.valid()) {
    status = renderer_->UpdateTexture(body_->frame_texture, *image);
  } else if (status.ok()) {
    absl::StatusOr<render::TextureId> id = renderer_->UploadTexture(*image);
    status = id.status();
    if (id.ok()) body_->frame_texture = *id;
  }
  if (!status.ok()) {
    appearance_note_ = absl::StrCat("per-frame appearance not drawn (frame ", frame, ": ",
                                    status.message(), "): the static atlas is drawn instead");
    body_->appearance.reset();
    return body_->atlas;
  }
  body_->frame_texture_index = frame;
  ++stats->textures_uploaded;
  stats->per_frame_appearance = true;
  return body_->frame_texture;
}

absl::Status ReenactmentRenderer::RenderBody(int frame, const render::RenderCamera& camera,
                                             render::RenderOutputs* out, FrameStats* stats) {
  RETURN_IF_ERROR(UploadBody(stats));
  const std::optional<BodyFramePose>& pose = data_.frames[frame].body;
  std::vector<render::DrawItem> items;
  if (pose && pose->valid) {
    ASSIGN_OR_RETURN(const body::PosedBody posed, PoseBodyMesh(*data_.body, *pose));
    // Normals recomputed over the model's triangles, so seams do not show.
    RETURN_IF_ERROR(
        renderer_->UpdateMeshPositions(body_->gpu_mesh, posed.vertices_m.cast<float>()));
    render::DrawItem item;
    item.mesh = body_->gpu_mesh;
    item.texture = BodyTexture(frame, stats);
    item.lit = !item.texture.valid();  // The atlas already carries the light.
    item.cull_back_faces = true;       // The body model is a closed surface.
    item.colour_srgb = options_.untextured_srgb;
    item.label = 1;
    items.push_back(item);
    stats->parts_drawn = 1;
    stats->triangles = static_cast<int>(data_.body->texture_triangles.size());
  }
  stats->draw_items = static_cast<int>(items.size());
  return renderer_->Render(camera, items, out);
}

absl::Status ReenactmentRenderer::Render(int frame_index, const render::RenderCamera& camera,
                                         render::RenderOutputs* out, FrameStats* stats) {
  if (frame_index < 0 || frame_index >= model_.num_frames()) {
    return absl::NotFoundError(absl::StrCat("frame ", frame_index, " is not in the reenactment (",
                                            model_.num_frames(), " frames)"));
  }
  RETURN_IF_ERROR(camera.Validate());
  FrameStats local;
  FrameStats& s = stats != nullptr ? *stats : local;
  s = FrameStats();
  if (body_ != nullptr) return RenderBody(frame_index, camera, out, &s);
  s.best_keyframe.assign(model_.num_parts(), -1);
  const Eigen::Isometry3d camera_from_world = camera.world_from_camera.inverse();
  std::vector<Group> groups;
  if (options_.mode == TextureMode::kVdtm) {
    RETURN_IF_ERROR(BuildVdtmGroups(frame_index, camera_from_world, &groups, &s));
  } else {
    RETURN_IF_ERROR(BuildBakedGroups(frame_index, &groups, &s));
  }
  std::vector<render::DrawItem> items;
  absl::Status status;
  for (const Group& group : groups) {
    auto mesh = GroupMesh(frame_index, group);
    if (!mesh.ok()) {
      status = mesh.status();
      break;
    }
    auto id = renderer_->UploadMesh(*mesh);
    if (!id.ok()) {
      status = id.status();
      break;
    }
    render::DrawItem item;
    item.mesh = *id;
    item.world_from_model = model_.pose(frame_index, group.part).world_from_part;
    item.texture = group.texture;
    item.lit = !group.texture.valid();  // Keyframe colours already carry the light.
    item.colour_srgb = options_.untextured_srgb;
    item.label = group.part + 1;
    item.underlay = group.underlay;
    item.blend_weight = group.blend_weight;
    items.push_back(item);
    if (!group.underlay && group.blend_weight >= 1.0f) {
      s.triangles += static_cast<int>(group.triangles.size());
    }
  }
  s.draw_items = static_cast<int>(items.size());
  if (status.ok()) status = renderer_->Render(camera, items, out);
  for (const render::DrawItem& item : items) renderer_->ReleaseMesh(item.mesh).IgnoreError();
  EvictTextures();
  return status;
}

absl::StatusOr<render::RenderCamera> SensorRenderCamera(const SensorCalibration& calibration,
                                                        int width, int height) {
  RETURN_IF_ERROR(calibration.color_intrinsics.Validate());
  ASSIGN_OR_RETURN(CameraIntrinsics k,
                   ScaledIntrinsics(calibration.color_intrinsics, width, height));
  const Rigid3d world_from_color = calibration.WorldFromColor();
  const render::RenderCamera camera = render::RenderCameraFromIntrinsics(
      k, Eigen::Isometry3d(world_from_color.ToMatrix4()), /*near_m=*/0.1, /*far_m=*/30.0);
  RETURN_IF_ERROR(camera.Validate());
  return camera;
}

render::RenderCamera OrbitCamera(const render::RenderCamera& camera,
                                 const Eigen::Vector3d& pivot_in_world, double angle_deg) {
  const double angle_rad = angle_deg * std::numbers::pi / 180.0;
  const Eigen::Isometry3d turn = Eigen::Translation3d(pivot_in_world) *
                                 Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitY()) *
                                 Eigen::Translation3d(-pivot_in_world);
  render::RenderCamera turned = camera;
  turned.world_from_camera = turn * camera.world_from_camera;
  return turned;
}

absl::StatusOr<Eigen::Vector3d> MeanActorPosition(const Reenactment& data) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (const ReenactmentFrame& frame : data.frames) {
    if (frame.joints_in_world_m.size() != kNumSkeletonJoints) continue;
    const Eigen::Vector3d& root = frame.joints_in_world_m[0];  // SpineBase.
    if (!root.allFinite()) continue;
    sum += root;
    ++count;
  }
  if (count > 0) return Eigen::Vector3d(sum / count);
  for (const ReenactmentFrame& frame : data.frames) {
    for (const PartPose& pose : frame.parts) {
      if (!pose.valid) continue;
      sum += pose.world_from_part.translation();
      ++count;
    }
  }
  if (count == 0) return absl::NotFoundError("the reenactment has no joints and no posed part");
  return Eigen::Vector3d(sum / count);
}

}  // namespace reenact::view
