// A reenactment in memory as plain values (thesis ch. 3 and 4): the moving,
// textured body a method makes from a take, and what every viewer draws.
// Two kinds:
//  * rigid parts (methods rigid-cylinders and rigid-carved): one mesh per
//    body part in the part's frame, a pose per part and instant (Eq. 3.1),
//    and the texture keyframes VDTM ranks (Eq. 3.6, 3.13);
//  * a body model (method body): one skinned mesh with its atlas and a body
//    pose per instant (Eq. 4.1-4.4).
// The file format and the wire use the reenact.v1 messages of
// reenactment.proto; common/io/reenactment_convert.h converts between them
// and checks everything on the way in, so algorithms and viewers work on
// these types and never on messages.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#include "common/body/body_model.h"
#include "common/methods/method_spec.h"
#include "common/model/sensor_calibration.h"

namespace reenact {

// Consecutive instants a method does not vouch for (DoubtfulSpan).
struct DoubtfulSpan {
  int first_frame = 0;   // Inclusive.
  int last_frame = 0;    // Inclusive.
  double start_s = 0.0;  // Take-timeline seconds from the first instant.
  double end_s = 0.0;
  std::string reason;  // For people.
};

// What a reenactment is and how it was made (ReenactmentInfo).
struct ReenactmentInfo {
  std::string reenactment_id;
  std::string take_id;
  std::string job_id;
  std::string method;  // Registry name, e.g. "rigid-carved".
  std::map<std::string, std::string> options;
  int64_t created_unix_ns = 0;
  std::string generator;  // Program and version that wrote it.
  int frame_count = 0;    // Equals Reenactment::frames.size().
  double fps = 0.0;
  std::vector<std::string> part_names;  // In part-id order; empty for a body.
  std::vector<SensorCalibration> sensors;
  std::map<std::string, double> figures;  // What the method measured.
  // How its texture is chosen when drawn; nullopt in files written before
  // the field existed (viewers then go by the method).
  std::optional<methods::TextureMode> texture_mode;
  // In frame order, not overlapping; empty: none judged doubtful.
  std::vector<DoubtfulSpan> doubtful_spans;
};

// One rigid part's mesh in its own frame, metres (PartMesh).
struct PartMesh {
  int part = 0;      // Part id: its index in ReenactmentInfo::part_names.
  std::string name;  // ReenactmentInfo::part_names[part].
  Eigen::Matrix3Xf positions_in_part_m;
  Eigen::Matrix3Xf normals_in_part;  // 3 x N or empty.
  Eigen::Matrix2Xf uvs;              // Of the baked texture; 2 x N or empty.
  std::vector<Eigen::Vector3i> triangles;
  std::string baked_texture_jpeg;  // Empty: none.
  // Cylinders (thesis 3.3.3): the radius over the bone length and the bone
  // length the mesh was made for; 0 for other parts.
  float radius_rate = 0.0f;
  float reference_length_m = 0.0f;

  int num_vertices() const { return static_cast<int>(positions_in_part_m.cols()); }
};

// One part's pose at one instant (Eq. 3.1): point_in_world = scale *
// (world_from_part.linear() * point_in_part) + world_from_part.translation().
struct PartPose {
  Eigen::Isometry3d world_from_part = Eigen::Isometry3d::Identity();
  double scale = 1.0;
  bool valid = false;  // False: the part is hidden at this instant.

  // world_from_part with the scale folded into its linear part.
  Eigen::Affine3d WorldFromPartScaled() const;
};

// How well a body fit explains one sensor's view at one instant (SensorFit).
struct SensorFit {
  int sensor = 0;                      // Index into ReenactmentInfo::sensors.
  int points = 0;                      // The sensor's actor points.
  float explained_fraction = 0.0f;     // Of them, within explained_m of the surface.
  float rms_mm = 0.0f;                 // Of the explained ones, to the surface.
  float surface_seen_fraction = 0.0f;  // Of the surface facing it, confirmed by its points.
};

// A body-model reenactment's pose at one instant (thesis 4.3): the model's
// joint rotations and root translation, and the optional free-form vertex
// offsets, kept at the resolution the file stores (0.05 mm steps).
struct BodyFramePose {
  body::BodyPose pose;
  // 3 x V, in units of 0.05 mm; empty: no offsets.
  Eigen::Matrix<int16_t, 3, Eigen::Dynamic> vertex_offsets_50um;
  bool valid = false;                  // False: the body is hidden at this instant.
  float point_rms_mm = 0.0f;           // The fit's residual, as the method measured it.
  std::vector<SensorFit> sensor_fits;  // Per sensor that saw the instant.

  // The offsets in metres (3 x V), or an empty matrix.
  Eigen::Matrix3Xd OffsetsMetres() const;
  // Stores `offsets_m` (3 x V) to 0.05 mm, clamped at +-1.6 m.
  void SetOffsetsMetres(const Eigen::Matrix3Xd& offsets_m);
};

// One instant (PartFrame).
struct ReenactmentFrame {
  int frame_index = 0;  // Its index in Reenactment::frames.
  int64_t stamp_ns = 0;
  std::vector<PartPose> parts;  // One per part; empty for a body.
  // The take's fused skeleton (25 Kinect v2 joints, world, metres; NaN
  // where unknown), or empty.
  std::vector<Eigen::Vector3d> joints_in_world_m;
  std::optional<BodyFramePose> body;  // Body-model reenactments.
};

// A kept colour image of one sensor at one instant, cropped to the actor
// (TextureKeyframe). VDTM projects part vertices into it (Eq. 3.14-3.15).
struct TextureKeyframe {
  int frame_index = 0;  // Into Reenactment::frames.
  std::string sensor_id;
  int64_t stamp_ns = 0;
  std::string color_jpeg;  // The crop.
  int crop_x_px = 0;       // The crop's origin in the full-size image.
  int crop_y_px = 0;
  std::string mask_rle;  // The actor's mask over the crop; empty: none.
  // Per part, one bit per vertex (LSB first): the vertex is seen; empty:
  // every vertex counts as seen.
  std::vector<std::string> vertex_visible_bits;
  float crop_scale = 0.0f;  // Crop pixels per full-size pixel; 0 reads as 1.
};

// The skinned body of a body-model reenactment (BodyMesh): the rest pose
// with the fitted shape applied, its skinning, and its texture atlas.
struct BodyMesh {
  std::string model_name;
  std::vector<double> shape;  // Shape coefficients the rest pose applies.
  std::vector<std::string> shape_names;
  Eigen::Matrix3Xd rest_vertices_m;  // 3 x V.
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> rest_joints_m;
  std::vector<std::string> joint_names;
  std::vector<Eigen::Vector3i> triangles;  // Over model vertices.
  std::vector<std::array<int, body::kMaxInfluences>> skin_joints;
  std::vector<std::array<float, body::kMaxInfluences>> skin_weights;
  // Texture vertices: their model vertex and atlas uv; triangles over them.
  std::vector<uint32_t> texture_vertex_source;
  std::vector<Eigen::Vector2f> texture_uvs;
  std::vector<Eigen::Vector3i> texture_triangles;
  std::string atlas_jpeg;  // Empty while texturing has not run.
  // Per-frame appearance (AppearanceVideo): the atlas of every instant as
  // an MP4 video, frame k for reenactment frame k; empty: none.
  std::string appearance_mp4;
  int appearance_size_px = 0;
  int appearance_frame_count = 0;
  std::string appearance_codec;

  int num_vertices() const { return static_cast<int>(rest_vertices_m.cols()); }
};

// A whole reenactment.
struct Reenactment {
  ReenactmentInfo info;
  std::vector<PartMesh> parts;  // In part-id order.
  std::vector<ReenactmentFrame> frames;
  std::vector<TextureKeyframe> keyframes;
  std::optional<BodyMesh> body;  // Body-model reenactments.

  bool is_body() const { return body.has_value(); }
};

// Checks that the parts of `data` agree: part names, meshes (sizes, triangle
// indices in range, finite values), one pose per part in every frame, a
// body pose in every frame of a body reenactment with offsets that match its
// mesh, keyframes that name known frames and sensors with one visibility
// string of the right size per part. InvalidArgument naming the first
// problem. What a file reader converts passes; values built in code are
// checked by the viewers before they index by them.
absl::Status ValidateReenactment(const Reenactment& data);

// The BodyMesh of `model` with shape coefficients `shape` (rest pose, shape
// applied; pose correctives are not carried) and the atlas `atlas_jpeg`
// (may be empty while texturing has not run). Positions and skin weights are
// rounded to float32, as the file stores them, so that what a method
// computes on the mesh is what a reader of its file gets. Texture vertices
// are the distinct (vertex, uv) corners of the model's triangles.
// InvalidArgument when the model does not validate or the shape is too long.
absl::StatusOr<BodyMesh> BuildBodyMesh(const body::BodyModel& model, const Eigen::VectorXd& shape,
                                       std::string atlas_jpeg);

// The posed body of `mesh` at `pose`: linear blend skinning (Eq. 4.3) plus
// the pose's vertex offsets, with joints and joint frames. InvalidArgument
// when the pose's offsets do not match the mesh.
absl::StatusOr<body::PosedBody> PoseBodyMesh(const BodyMesh& mesh, const BodyFramePose& pose);

}  // namespace reenact
