// Draws a reenactment (common/model/reenactment.h) at one instant from any
// camera, headless, through OffscreenRenderer. Rigid-part reenactments:
//  * TextureMode::kVdtm: view-dependent texture mapping from the texture
//    keyframes (clients/view/texture_selection.h: Eq. 3.13 for
//    "rigid-carved", Eq. 3.6 for "rigid-cylinders", next-best keyframe where
//    a triangle is occluded, Eq. 3.14-3.15 lookup). Every (part, keyframe)
//    group of triangles is one unlit textured draw (the keyframe colours
//    already carry the scene's light). Keyframe crops are uploaded as
//    alpha-tested textures whose alpha is the keyframe's actor mask, so
//    lookups that land on background are discarded (thesis 3.4.2: "an
//    extraneous part caused by the simplified geometry model"; the viewer
//    sees what lies behind; for carved parts, whose mesh is the actor's
//    surface, the part's baked texture drawn beneath shows instead,
//    ReenactmentRendererOptions::underlay_baked).
//  * TextureMode::kBaked: every part with its static baked texture
//    (PartMesh.uvs_f32 + baked_texture_jpeg), unlit.
// Triangles that no keyframe shows (visible in none) use the baked texture
// when the part has one, else the best-ranked keyframe regardless of
// visibility. Parts without any texture are drawn lit in flat grey.
//
// Keyframe textures are decoded from JPEG once and kept on the GPU in a
// least-recently-used cache bounded in bytes; baked textures are uploaded
// once. Meshes are built per frame (only the triangles of each group) and
// released after the draw.
//
// Body-model reenactments (Reenactment::is_body()) are one textured
// mesh in both texture modes: the frame's BodyPose is applied on the CPU
// (PoseBodyMesh: skinning plus the frame's vertex offsets), the posed model
// vertices are spread over the texture vertices (BodyMesh seams), normals
// are area-weighted over the closed surface, and the atlas is the texture
// (unlit: it holds the light the sensors saw; no atlas: lit flat grey). A
// pose that is not valid hides the body (as an invalid part pose does). The
// mesh is decoded once (Create) and uploaded once with the atlas (first
// Render, counted in FrameStats::textures_uploaded); each frame updates only
// its positions. The label of the body is 1. A body with an appearance
// video (BodyMesh::appearance_mp4) is drawn at each instant with that
// instant's atlas, decoded in step with the frames asked for (the next frame
// decodes on, a jump back seeks to the key frame before it) and uploaded
// over the previous one; a video that holds another number of frames, does
// not decode or breaks part-way leaves the static atlas drawn from then on,
// and appearance_note() says why.
#pragma once

#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/view/texture_selection.h"
#include "common/model/reenactment.h"
#include "common/render/offscreen_renderer.h"
#include "common/render/render_types.h"

namespace reenact::view {

enum class TextureMode { kVdtm, kBaked };

// "vdtm" / "baked"; InvalidArgument for anything else.
absl::StatusOr<TextureMode> ParseTextureMode(const std::string& name);

struct ReenactmentRendererOptions {
  TextureMode mode = TextureMode::kVdtm;
  // Keyframe ranking; by default the one the reenactment records
  // (SelectionForReenactment of ReenactmentInfo).
  bool selection_from_method = true;
  TextureSelection selection = TextureSelection::kRotation;
  // VDTM: draw each part's baked texture (when it has one) behind its
  // keyframe textures, so that lookups landing off a keyframe's actor mask
  // show the baked colour instead of what lies behind the part. By default
  // on for carved parts (kRotation: the mesh is the actor's surface, so an
  // off-mask lookup is a texture misregistration) and off for cylinders
  // (kPose: there it is extraneous geometry, thesis 3.4.2).
  bool underlay_from_method = true;
  bool underlay_baked = false;
  // VDTM: blend each triangle's two best visible keyframes (true), weighted
  // by the inverse of their ranking distance (angle of Eq. 3.13, or pose
  // distance of Eq. 3.6), so that the texture changes smoothly as the view
  // turns; false: the thesis' single best frame.
  bool blend_keyframes = true;
  // GPU memory for keyframe textures (RGBA with mipmaps), bytes: after each
  // frame, the least recently used are released until the cache fits (a
  // frame's textures stay while it is drawn, whatever the budget).
  int64_t texture_cache_bytes = int64_t{256} << 20;
  // Colour of parts without any texture, sRGB in [0,1] (drawn lit).
  Eigen::Vector3f untextured_srgb{0.6f, 0.6f, 0.6f};
  // Bodies: draw each instant's atlas from the reenactment's appearance
  // video when it has one (false: the static atlas at every instant).
  bool appearance = true;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What one Render call drew.
struct FrameStats {
  int parts_drawn = 0;  // A drawn body counts as one.
  int draw_items = 0;
  int triangles = 0;
  // VDTM: triangles coloured from a keyframe below their part's best usable
  // one (occluded there: the next-best frame of thesis 3.4.2), and triangles
  // that no keyframe shows (baked or best-ranked fallback).
  int triangles_next_best = 0;
  int triangles_unseen = 0;
  // VDTM with blend_keyframes: triangles drawn with a second keyframe
  // blended over the first.
  int triangles_blended = 0;
  // Per part: the best-ranked usable keyframe (index into
  // Reenactment::keyframes), -1 where the part is hidden or has none.
  std::vector<int> best_keyframe;
  // Keyframe textures decoded and uploaded during this call.
  int textures_uploaded = 0;
  // A body drawn with the instant's atlas of its appearance video.
  bool per_frame_appearance = false;
};

class ReenactmentRenderer {
 public:
  // `data` and `renderer` must outlive the returned object, which uploads
  // into `renderer` and leaves its shading alone. InvalidArgument for a
  // reenactment that does not validate (a body mesh that does not decode
  // included) or bad options.
  static absl::StatusOr<std::unique_ptr<ReenactmentRenderer>> Create(
      const Reenactment& data, render::OffscreenRenderer* renderer,
      const ReenactmentRendererOptions& options = {});
  ~ReenactmentRenderer();
  ReenactmentRenderer(const ReenactmentRenderer&) = delete;
  ReenactmentRenderer& operator=(const ReenactmentRenderer&) = delete;

  // Draws the instant `frame_index` (PartFrame.frame_index) seen by `camera`
  // into `out` (outputs as OffscreenRenderer::Render; the label of part b is
  // b + 1; of a body, 1). NotFound for an unknown frame; InvalidArgument for
  // a bad camera; DataLoss when a keyframe's JPEG or mask, or a body's
  // atlas, does not decode.
  absl::Status Render(int frame_index, const render::RenderCamera& camera,
                      render::RenderOutputs* out, FrameStats* stats = nullptr);

  const VdtmModel& model() const { return model_; }
  // Bytes of keyframe textures held on the GPU now.
  int64_t cached_texture_bytes() const { return cache_bytes_; }
  // Why a body's appearance video is not drawn (it is missing no reason:
  // empty), for the user; set by the first Render that finds out.
  const std::string& appearance_note() const { return appearance_note_; }

 private:
  struct CachedTexture {
    render::TextureId id;
    int width = 0;
    int height = 0;
    int64_t bytes = 0;
    std::list<int>::iterator lru;  // Position in lru_ (front = most recent).
  };
  // A texture and the uv mapping that goes with it for one part.
  struct Group;
  // The decoded body mesh and its GPU mesh and atlas (body reenactments).
  struct Body;

  ReenactmentRenderer(const Reenactment& data, render::OffscreenRenderer* renderer,
                      const ReenactmentRendererOptions& options, VdtmModel model,
                      std::unique_ptr<Body> body);
  absl::StatusOr<const CachedTexture*> KeyframeTexture(int keyframe, int* uploaded);
  absl::StatusOr<render::TextureId> BakedTexture(int part);
  void EvictTextures();
  absl::Status BuildVdtmGroups(int frame, const Eigen::Isometry3d& camera_from_world,
                               std::vector<Group>* groups, FrameStats* stats);
  absl::Status BuildBakedGroups(int frame, std::vector<Group>* groups, FrameStats* stats);
  absl::StatusOr<render::MeshData> GroupMesh(int frame, const Group& group) const;
  absl::Status UploadBody(FrameStats* stats);
  // Opens the body's appearance video, or says in appearance_note_ why not.
  void OpenAppearance();
  // The texture of the body at `frame`: the instant's atlas from the video,
  // or the static atlas (after a failure, for the rest of the run).
  render::TextureId BodyTexture(int frame, FrameStats* stats);
  absl::Status RenderBody(int frame, const render::RenderCamera& camera, render::RenderOutputs* out,
                          FrameStats* stats);

  const Reenactment& data_;
  render::OffscreenRenderer* renderer_;
  ReenactmentRendererOptions options_;
  TextureSelection selection_;
  bool underlay_baked_;
  VdtmModel model_;
  std::map<int, CachedTexture> textures_;  // By keyframe.
  std::list<int> lru_;
  int64_t cache_bytes_ = 0;
  std::vector<render::TextureId> baked_;  // By part; invalid until uploaded.
  std::vector<bool> baked_tried_;
  std::unique_ptr<Body> body_;  // Null for rigid-part reenactments.
  std::string appearance_note_;
};

// The colour camera of `calibration` as a render camera of width x height
// pixels (the intrinsics scaled to that size; distortion is not rendered).
// InvalidArgument for an invalid calibration or size.
absl::StatusOr<render::RenderCamera> SensorRenderCamera(const SensorCalibration& calibration,
                                                        int width, int height);

// `camera` turned by `angle_deg` about the vertical (+Y) axis through
// `pivot_in_world` (right-handed: +90 deg takes +Z to +X).
render::RenderCamera OrbitCamera(const render::RenderCamera& camera,
                                 const Eigen::Vector3d& pivot_in_world, double angle_deg);

// The actor's mean position over the reenactment: the mean SpineBase joint
// of the frames that have one, else the mean origin of the valid parts.
// NotFound when there is neither.
absl::StatusOr<Eigen::Vector3d> MeanActorPosition(const Reenactment& data);

}  // namespace reenact::view
