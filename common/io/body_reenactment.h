// Body-model reenactments (thesis ch. 4) in reenact.v1 messages: the fitted
// body as one skinned mesh (BodyMesh, reenactment.proto) and its pose per
// instant (BodyPose). Makes the messages from a body model, decodes them and
// poses the mesh the way every viewer must (linear blend skinning, plus the
// optional free-form vertex offsets of the frame).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/body_model.h"
#include "common/model/reenactment.h"
#include "reenact/v1/reenactment.pb.h"

namespace reenact {

// A BodyMesh unpacked: the plain type of common/model.
using DecodedBodyMesh = BodyMesh;

// The BodyMesh of `model` with shape coefficients `shape` (rest pose, shape
// applied; pose correctives are not carried) and the atlas `atlas_jpeg`
// (may be empty while texturing has not run). Texture vertices are the
// distinct (vertex, uv) corners of the model's triangles. InvalidArgument
// when the model does not validate or the shape is too long.
absl::StatusOr<v1::BodyMesh> MakeBodyMesh(const body::BodyModel& model,
                                          const Eigen::VectorXd& shape, std::string atlas_jpeg);

// Unpacks and checks a BodyMesh: sizes agree, indices in range, 25 rest
// joints, weights >= 0 summing to 1, finite numbers. InvalidArgument naming
// the first problem.
absl::StatusOr<DecodedBodyMesh> DecodeBodyMesh(const v1::BodyMesh& mesh);

// Checks a BodyPose against a mesh of `num_vertices` vertices: 25 non-zero
// finite rotations, a finite translation, offsets empty or one per vertex.
// InvalidArgument naming `what` and the problem.
absl::Status ValidateBodyPose(const v1::BodyPose& pose, int num_vertices, const std::string& what);

// Conversions of the pose (rotations and translation only).
v1::BodyPose BodyPoseToProto(const body::BodyPose& pose);
absl::StatusOr<body::BodyPose> BodyPoseFromProto(const v1::BodyPose& pose);

// Per-vertex offsets of a BodyPose in the file's units, 0.05 mm (3 x V, as
// BodyFramePose::vertex_offsets_50um keeps them), or an empty matrix when
// the pose has none. InvalidArgument when the size disagrees with V.
using VertexOffsets50um = Eigen::Matrix<int16_t, 3, Eigen::Dynamic>;
absl::StatusOr<VertexOffsets50um> BodyPoseOffsets(const v1::BodyPose& pose, int num_vertices);
// Packs offsets (3 x V, 0.05 mm units) into `pose`.
void SetBodyPoseOffsets(const VertexOffsets50um& offsets, v1::BodyPose* pose);

// The posed body of `mesh` at `pose`: skinned vertices plus the pose's
// offsets, joints and joint frames. Errors as ValidateBodyPose.
absl::StatusOr<body::PosedBody> PoseBodyMesh(const DecodedBodyMesh& mesh, const v1::BodyPose& pose);

}  // namespace reenact
