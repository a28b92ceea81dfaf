// Body model posing (SMPL formulation) and the ".rbm" file format.
//
// Posing follows Loper et al. 2015: shape blend (Eq. 8), joint regression
// (Eq. 10), pose correctives (Eq. 9), world transforms along the kinematic
// tree (Eq. 4) and linear blend skinning (Eq. 2).
//
// Root translation: G_root = [R_root | J_root + root_translation_m], i.e. the
// pose's translation is added to the root joint's rest position, so an
// identity pose with zero translation reproduces the rest mesh where it
// stands (feet on y = 0).
#include "common/body/body_model.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact::body {
namespace {

constexpr char kMagic[4] = {'R', 'B', 'M', '1'};
constexpr uint32_t kFormatVersion = 1;
constexpr double kRowSumTolerance = 1e-6;
constexpr double kWeightSumTolerance = 1e-4;
constexpr int kNumCorrectives = 9 * (kNumKinectV2Joints - 1);

bool AllFinite(const Eigen::Matrix3Xd& m) { return m.allFinite(); }

absl::Status ValidateMesh(const BodyModel& model) {
  const int num_vertices = model.num_vertices();
  if (num_vertices == 0) return absl::InvalidArgumentError("body model has no vertices");
  if (!AllFinite(model.template_vertices_m)) {
    return absl::InvalidArgumentError("body model template has non-finite vertices");
  }
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = model.triangles[t];
    if ((tri.array() < 0).any() || (tri.array() >= num_vertices).any()) {
      return absl::InvalidArgumentError(
          absl::StrCat("triangle ", t, " indexes a vertex outside [0, ", num_vertices, ")"));
    }
  }
  if (!model.uv_triangles.empty() && model.uv_triangles.size() != model.triangles.size()) {
    return absl::InvalidArgumentError(absl::StrCat("body model has ", model.uv_triangles.size(),
                                                   " uv triangles for ", model.triangles.size(),
                                                   " triangles"));
  }
  const int num_uvs = static_cast<int>(model.uvs.size());
  for (size_t t = 0; t < model.uv_triangles.size(); ++t) {
    const Eigen::Vector3i& tri = model.uv_triangles[t];
    if ((tri.array() < 0).any() || (tri.array() >= num_uvs).any()) {
      return absl::InvalidArgumentError(
          absl::StrCat("uv triangle ", t, " indexes a uv outside [0, ", num_uvs, ")"));
    }
  }
  for (size_t i = 0; i < model.uvs.size(); ++i) {
    if (!model.uvs[i].allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("uv ", i, " is not finite"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateRegressor(const BodyModel& model) {
  const auto& regressor = model.joint_regressor;
  if (regressor.rows() != kNumKinectV2Joints || regressor.cols() != model.num_vertices()) {
    return absl::InvalidArgumentError(
        absl::StrCat("joint regressor is ", regressor.rows(), " x ", regressor.cols(),
                     ", expected ", kNumKinectV2Joints, " x ", model.num_vertices()));
  }
  for (int row = 0; row < regressor.outerSize(); ++row) {
    double sum = 0.0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(regressor, row); it; ++it) {
      if (!std::isfinite(it.value())) {
        return absl::InvalidArgumentError(
            absl::StrCat("joint regressor row ", row, " has a non-finite entry"));
      }
      sum += it.value();
    }
    if (std::abs(sum - 1.0) > kRowSumTolerance) {
      return absl::InvalidArgumentError(
          absl::StrCat("joint regressor row ", row, " sums to ", sum, ", expected 1"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateSkinning(const BodyModel& model) {
  const size_t num_vertices = static_cast<size_t>(model.num_vertices());
  if (model.skin_joints.size() != num_vertices || model.skin_weights.size() != num_vertices) {
    return absl::InvalidArgumentError(
        absl::StrCat("skinning has ", model.skin_joints.size(), " joint and ",
                     model.skin_weights.size(), " weight entries for ", num_vertices, " vertices"));
  }
  for (size_t v = 0; v < num_vertices; ++v) {
    double sum = 0.0;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const float weight = model.skin_weights[v][k];
      const int joint = model.skin_joints[v][k];
      if (!std::isfinite(weight) || weight < 0.0f) {
        return absl::InvalidArgumentError(
            absl::StrCat("vertex ", v, " has an invalid skin weight ", weight));
      }
      if (joint < 0 || joint >= kNumKinectV2Joints) {
        return absl::InvalidArgumentError(
            absl::StrCat("vertex ", v, " is skinned to joint ", joint, " outside [0, 25)"));
      }
      sum += weight;
    }
    if (std::abs(sum - 1.0) > kWeightSumTolerance) {
      return absl::InvalidArgumentError(
          absl::StrCat("skin weights of vertex ", v, " sum to ", sum, ", expected 1"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateDirections(const std::vector<Eigen::Matrix3Xd>& directions, int num_vertices,
                                absl::string_view what) {
  for (size_t k = 0; k < directions.size(); ++k) {
    if (directions[k].cols() != num_vertices) {
      return absl::InvalidArgumentError(absl::StrCat(what, " ", k, " has ", directions[k].cols(),
                                                     " columns, expected ", num_vertices));
    }
    if (!AllFinite(directions[k])) {
      return absl::InvalidArgumentError(absl::StrCat(what, " ", k, " is not finite"));
    }
  }
  return absl::OkStatus();
}

// Pose corrective blend B_P (SMPL Eq. 9): weights are the entries of
// (R_j - I), row-major, for the non-root joints in id order.
void AddPoseCorrectives(const BodyModel& model, const BodyPose& pose,
                        Eigen::Matrix3Xd& vertices_m) {
  if (model.pose_correctives_m.empty()) return;
  int k = 0;
  for (int j = 1; j < kNumKinectV2Joints; ++j) {
    const Eigen::Matrix3d delta =
        pose.local_rotation[j].normalized().toRotationMatrix() - Eigen::Matrix3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c, ++k) {
        if (delta(r, c) != 0.0) vertices_m += delta(r, c) * model.pose_correctives_m[k];
      }
    }
  }
}

// ---- Little-endian binary writing and reading. ----

class ByteWriter {
 public:
  template <typename T>
  void Put(T value) {
    using U = std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>;
    static_assert(sizeof(T) == sizeof(U));
    const U bits = std::bit_cast<U>(value);
    for (size_t i = 0; i < sizeof(U); ++i) bytes_.push_back(static_cast<char>(bits >> (8 * i)));
  }
  void PutString(const std::string& s) {
    Put<uint32_t>(static_cast<uint32_t>(s.size()));
    bytes_ += s;
  }
  void PutMatrix(const Eigen::Matrix3Xd& m) {
    for (Eigen::Index i = 0; i < m.size(); ++i) Put<double>(m.data()[i]);
  }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

class ByteReader {
 public:
  ByteReader(absl::string_view bytes, std::string path) : bytes_(bytes), path_(std::move(path)) {}

  // Fails unless `count` items of `item_size` bytes remain.
  absl::Status Need(uint64_t count, uint64_t item_size, absl::string_view what) const {
    const uint64_t remaining = bytes_.size() - offset_;
    if (item_size != 0 && count > remaining / item_size) {
      return absl::DataLossError(absl::StrCat(path_, ": truncated or corrupt at byte offset ",
                                              offset_, " reading ", what, " (", count, " x ",
                                              item_size, " bytes, ", remaining, " left)"));
    }
    return absl::OkStatus();
  }

  template <typename T>
  absl::StatusOr<T> Get(absl::string_view what) {
    using U = std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>;
    RETURN_IF_ERROR(Need(1, sizeof(U), what));
    U bits = 0;
    for (size_t i = 0; i < sizeof(U); ++i) {
      bits |= static_cast<U>(static_cast<unsigned char>(bytes_[offset_ + i])) << (8 * i);
    }
    offset_ += sizeof(U);
    return std::bit_cast<T>(bits);
  }

  absl::StatusOr<std::string> GetString(absl::string_view what) {
    ASSIGN_OR_RETURN(const uint32_t size, Get<uint32_t>(what));
    RETURN_IF_ERROR(Need(size, 1, what));
    std::string s(bytes_.substr(offset_, size));
    offset_ += size;
    return s;
  }

  absl::StatusOr<Eigen::Matrix3Xd> GetMatrix(int num_cols, absl::string_view what) {
    RETURN_IF_ERROR(Need(3 * static_cast<uint64_t>(num_cols), sizeof(double), what));
    Eigen::Matrix3Xd m(3, num_cols);
    for (Eigen::Index i = 0; i < m.size(); ++i) {
      ASSIGN_OR_RETURN(m.data()[i], Get<double>(what));
    }
    return m;
  }

  absl::StatusOr<std::vector<Eigen::Vector3i>> GetTriangles(uint32_t count,
                                                            absl::string_view what) {
    RETURN_IF_ERROR(Need(count, 3 * sizeof(int32_t), what));
    std::vector<Eigen::Vector3i> triangles(count);
    for (Eigen::Vector3i& tri : triangles) {
      for (int c = 0; c < 3; ++c) {
        ASSIGN_OR_RETURN(tri[c], Get<int32_t>(what));
      }
    }
    return triangles;
  }

  size_t offset() const { return offset_; }
  size_t size() const { return bytes_.size(); }
  const std::string& path() const { return path_; }

 private:
  absl::string_view bytes_;
  std::string path_;
  size_t offset_ = 0;
};

struct Header {
  uint32_t num_vertices = 0;
  uint32_t num_triangles = 0;
  uint32_t num_uvs = 0;
  uint32_t num_uv_triangles = 0;
  uint32_t num_joints = 0;
  uint32_t regressor_nonzeros = 0;
  uint32_t num_shapes = 0;
  uint32_t num_correctives = 0;
};

absl::StatusOr<Header> ReadHeader(ByteReader& reader) {
  ASSIGN_OR_RETURN(const uint32_t magic, reader.Get<uint32_t>("magic"));
  uint32_t expected_magic = 0;
  for (int i = 0; i < 4; ++i) expected_magic |= static_cast<uint32_t>(kMagic[i]) << (8 * i);
  if (magic != expected_magic) {
    return absl::DataLossError(absl::StrCat(reader.path(), ": not a body model file (bad magic)"));
  }
  ASSIGN_OR_RETURN(const uint32_t version, reader.Get<uint32_t>("version"));
  if (version != kFormatVersion) {
    return absl::DataLossError(
        absl::StrCat(reader.path(), ": unsupported body model version ", version));
  }
  Header h;
  ASSIGN_OR_RETURN(h.num_vertices, reader.Get<uint32_t>("vertex count"));
  ASSIGN_OR_RETURN(h.num_triangles, reader.Get<uint32_t>("triangle count"));
  ASSIGN_OR_RETURN(h.num_uvs, reader.Get<uint32_t>("uv count"));
  ASSIGN_OR_RETURN(h.num_uv_triangles, reader.Get<uint32_t>("uv triangle count"));
  ASSIGN_OR_RETURN(h.num_joints, reader.Get<uint32_t>("joint count"));
  ASSIGN_OR_RETURN(h.regressor_nonzeros, reader.Get<uint32_t>("regressor entry count"));
  ASSIGN_OR_RETURN(h.num_shapes, reader.Get<uint32_t>("shape count"));
  ASSIGN_OR_RETURN(h.num_correctives, reader.Get<uint32_t>("corrective count"));
  if (h.num_joints != kNumKinectV2Joints) {
    return absl::DataLossError(
        absl::StrCat(reader.path(), ": ", h.num_joints, " joints, expected ", kNumKinectV2Joints));
  }
  if (h.num_vertices > static_cast<uint32_t>(std::numeric_limits<int>::max())) {
    return absl::DataLossError(absl::StrCat(reader.path(), ": implausible vertex count"));
  }
  // Fixed-size arrays must fit in what is left before anything is allocated.
  const uint64_t v = h.num_vertices;
  const uint64_t fixed_bytes = v * 3 * 8 + uint64_t{h.num_triangles} * 12 +
                               uint64_t{h.num_uvs} * 8 + uint64_t{h.num_uv_triangles} * 12 +
                               uint64_t{h.regressor_nonzeros} * 16 + v * kMaxInfluences * 8 +
                               (uint64_t{h.num_shapes} + h.num_correctives) * v * 24;
  RETURN_IF_ERROR(reader.Need(fixed_bytes, 1, "the arrays the header declares"));
  return h;
}

absl::Status ReadRegressor(ByteReader& reader, const Header& h, BodyModel& model) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(h.regressor_nonzeros);
  for (uint32_t i = 0; i < h.regressor_nonzeros; ++i) {
    const size_t at = reader.offset();
    ASSIGN_OR_RETURN(const int32_t row, reader.Get<int32_t>("regressor row"));
    ASSIGN_OR_RETURN(const int32_t col, reader.Get<int32_t>("regressor column"));
    ASSIGN_OR_RETURN(const double value, reader.Get<double>("regressor value"));
    if (row < 0 || row >= kNumKinectV2Joints || col < 0 ||
        static_cast<uint32_t>(col) >= h.num_vertices) {
      return absl::DataLossError(absl::StrCat(reader.path(),
                                              ": corrupt regressor entry at byte offset ", at, " (",
                                              row, ", ", col, ")"));
    }
    triplets.emplace_back(row, col, value);
  }
  model.joint_regressor.resize(kNumKinectV2Joints, h.num_vertices);
  model.joint_regressor.setFromTriplets(triplets.begin(), triplets.end());
  return absl::OkStatus();
}

absl::Status ReadSkinning(ByteReader& reader, const Header& h, BodyModel& model) {
  model.skin_joints.resize(h.num_vertices);
  model.skin_weights.resize(h.num_vertices);
  for (auto& joints : model.skin_joints) {
    for (int& joint : joints) {
      ASSIGN_OR_RETURN(joint, reader.Get<int32_t>("skin joints"));
    }
  }
  for (auto& weights : model.skin_weights) {
    for (float& weight : weights) {
      ASSIGN_OR_RETURN(weight, reader.Get<float>("skin weights"));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<BodyModel> ParseBodyModel(ByteReader& reader) {
  ASSIGN_OR_RETURN(const Header h, ReadHeader(reader));
  BodyModel model;
  ASSIGN_OR_RETURN(model.name, reader.GetString("model name"));
  const int num_vertices = static_cast<int>(h.num_vertices);
  ASSIGN_OR_RETURN(model.template_vertices_m, reader.GetMatrix(num_vertices, "template vertices"));
  ASSIGN_OR_RETURN(model.triangles, reader.GetTriangles(h.num_triangles, "triangles"));
  model.uvs.resize(h.num_uvs);
  for (Eigen::Vector2f& uv : model.uvs) {
    ASSIGN_OR_RETURN(uv.x(), reader.Get<float>("uvs"));
    ASSIGN_OR_RETURN(uv.y(), reader.Get<float>("uvs"));
  }
  ASSIGN_OR_RETURN(model.uv_triangles, reader.GetTriangles(h.num_uv_triangles, "uv triangles"));
  RETURN_IF_ERROR(ReadRegressor(reader, h, model));
  RETURN_IF_ERROR(ReadSkinning(reader, h, model));
  for (uint32_t k = 0; k < h.num_shapes; ++k) {
    ASSIGN_OR_RETURN(std::string name, reader.GetString("shape name"));
    model.shape_names.push_back(std::move(name));
    ASSIGN_OR_RETURN(Eigen::Matrix3Xd direction, reader.GetMatrix(num_vertices, "shape direction"));
    model.shape_directions_m.push_back(std::move(direction));
  }
  for (uint32_t k = 0; k < h.num_correctives; ++k) {
    ASSIGN_OR_RETURN(Eigen::Matrix3Xd direction, reader.GetMatrix(num_vertices, "pose corrective"));
    model.pose_correctives_m.push_back(std::move(direction));
  }
  if (reader.offset() != reader.size()) {
    return absl::DataLossError(absl::StrCat(reader.path(), ": ", reader.size() - reader.offset(),
                                            " unexpected trailing bytes at byte offset ",
                                            reader.offset()));
  }
  return model;
}

}  // namespace

const std::array<int, kNumKinectV2Joints>& KinectV2JointsParentsFirst() {
  static const std::array<int, kNumKinectV2Joints> order = [] {
    std::array<int, kNumKinectV2Joints> result{};
    std::array<bool, kNumKinectV2Joints> placed{};
    int count = 0;
    // The tree is shallow: sweep until every joint whose parent is placed is placed.
    while (count < kNumKinectV2Joints) {
      for (int j = 0; j < kNumKinectV2Joints; ++j) {
        if (placed[j]) continue;
        const auto parent = KinectV2Parent(static_cast<KinectV2Joint>(j));
        if (!parent.has_value() || placed[Index(*parent)]) {
          placed[j] = true;
          result[count++] = j;
        }
      }
    }
    return result;
  }();
  return order;
}

absl::Status ValidateBodyModel(const BodyModel& model) {
  RETURN_IF_ERROR(ValidateMesh(model));
  RETURN_IF_ERROR(ValidateRegressor(model));
  RETURN_IF_ERROR(ValidateSkinning(model));
  if (model.shape_names.size() != model.shape_directions_m.size()) {
    return absl::InvalidArgumentError(absl::StrCat("body model has ", model.shape_names.size(),
                                                   " shape names for ",
                                                   model.shape_directions_m.size(), " directions"));
  }
  RETURN_IF_ERROR(
      ValidateDirections(model.shape_directions_m, model.num_vertices(), "shape direction"));
  if (!model.pose_correctives_m.empty() && model.pose_correctives_m.size() != kNumCorrectives) {
    return absl::InvalidArgumentError(
        absl::StrCat("body model has ", model.pose_correctives_m.size(),
                     " pose correctives, expected 0 or ", kNumCorrectives));
  }
  return ValidateDirections(model.pose_correctives_m, model.num_vertices(), "pose corrective");
}

absl::StatusOr<Eigen::Matrix3Xd> ShapedRestVertices(const BodyModel& model,
                                                    const Eigen::VectorXd& shape) {
  if (shape.size() > model.num_shape_components()) {
    return absl::InvalidArgumentError(absl::StrCat("shape has ", shape.size(),
                                                   " coefficients, the model only ",
                                                   model.num_shape_components()));
  }
  if (!shape.allFinite()) return absl::InvalidArgumentError("shape coefficients are not finite");
  Eigen::Matrix3Xd vertices_m = model.template_vertices_m;  // SMPL Eq. (8).
  for (Eigen::Index k = 0; k < shape.size(); ++k) {
    if (shape[k] == 0.0) continue;
    if (model.shape_directions_m[k].cols() != vertices_m.cols()) {
      return absl::InvalidArgumentError(absl::StrCat("shape direction ", k, " has the wrong size"));
    }
    vertices_m += shape[k] * model.shape_directions_m[k];
  }
  return vertices_m;
}

absl::StatusOr<std::array<Eigen::Vector3d, kNumKinectV2Joints>> RestJointPositions(
    const BodyModel& model, const Eigen::VectorXd& shape) {
  ASSIGN_OR_RETURN(const Eigen::Matrix3Xd shaped_m, ShapedRestVertices(model, shape));
  if (model.joint_regressor.rows() != kNumKinectV2Joints ||
      model.joint_regressor.cols() != shaped_m.cols()) {
    return absl::InvalidArgumentError("joint regressor does not match the template");
  }
  // SMPL Eq. (10): J = R_J * T(beta).
  const Eigen::MatrixX3d joints = model.joint_regressor * shaped_m.transpose();
  std::array<Eigen::Vector3d, kNumKinectV2Joints> result;
  for (int j = 0; j < kNumKinectV2Joints; ++j) result[j] = joints.row(j).transpose();
  return result;
}

absl::StatusOr<PosedBody> SkinRestVertices(
    const std::vector<std::array<int, kMaxInfluences>>& skin_joints,
    const std::vector<std::array<float, kMaxInfluences>>& skin_weights,
    const Eigen::Matrix3Xd& rest_vertices_m,
    const std::array<Eigen::Vector3d, kNumKinectV2Joints>& rest_joints_m, const BodyPose& pose) {
  if (skin_joints.size() != static_cast<size_t>(rest_vertices_m.cols()) ||
      skin_weights.size() != skin_joints.size()) {
    return absl::InvalidArgumentError("skinning does not match the template");
  }
  if (!pose.root_translation_m.allFinite()) {
    return absl::InvalidArgumentError("root translation is not finite");
  }
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    if (!pose.local_rotation[j].coeffs().allFinite() || pose.local_rotation[j].norm() < 1e-9) {
      return absl::InvalidArgumentError(absl::StrCat(
          "rotation of joint ", std::string(KinectV2JointName(static_cast<KinectV2Joint>(j))),
          " is invalid"));
    }
  }
  PosedBody posed;
  // SMPL Eq. (4): G_j = G_parent * [R_j | J_j - J_parent]; the root carries
  // the pose translation on top of its rest position.
  for (int j : KinectV2JointsParentsFirst()) {
    Eigen::Isometry3d local = Eigen::Isometry3d::Identity();
    local.linear() = pose.local_rotation[j].normalized().toRotationMatrix();
    const auto parent = KinectV2Parent(static_cast<KinectV2Joint>(j));
    if (parent.has_value()) {
      local.translation() = rest_joints_m[j] - rest_joints_m[Index(*parent)];
      posed.world_from_joint[j] = posed.world_from_joint[Index(*parent)] * local;
    } else {
      local.translation() = rest_joints_m[j] + pose.root_translation_m;
      posed.world_from_joint[j] = local;
    }
    posed.joints_m[j] = posed.world_from_joint[j].translation();
  }
  // Skinning transforms A_j = G_j * [I | -J_j] (G_j(0, J)^-1 of SMPL Eq. 2).
  std::array<Eigen::Matrix<double, 3, 4>, kNumKinectV2Joints> skinning;
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    const Eigen::Matrix3d& rotation = posed.world_from_joint[j].linear();
    skinning[j].leftCols<3>() = rotation;
    skinning[j].col(3) = posed.joints_m[j] - rotation * rest_joints_m[j];
  }
  posed.vertices_m.resize(3, rest_vertices_m.cols());
  for (Eigen::Index v = 0; v < rest_vertices_m.cols(); ++v) {
    Eigen::Matrix<double, 3, 4> blended = Eigen::Matrix<double, 3, 4>::Zero();
    for (int k = 0; k < kMaxInfluences; ++k) {
      const float weight = skin_weights[v][k];
      if (weight == 0.0f) continue;
      const int joint = skin_joints[v][k];
      if (joint < 0 || joint >= kNumKinectV2Joints) {
        return absl::InvalidArgumentError(absl::StrCat("vertex ", v, " has a bad skin joint"));
      }
      blended += static_cast<double>(weight) * skinning[joint];
    }
    posed.vertices_m.col(v) = blended.leftCols<3>() * rest_vertices_m.col(v) + blended.col(3);
  }
  return posed;
}

absl::StatusOr<PosedBody> PoseBody(const BodyModel& model, const BodyPose& pose,
                                   const Eigen::VectorXd& shape) {
  if (model.skin_joints.size() != static_cast<size_t>(model.num_vertices()) ||
      model.skin_weights.size() != model.skin_joints.size()) {
    return absl::InvalidArgumentError("skinning does not match the template");
  }
  ASSIGN_OR_RETURN(Eigen::Matrix3Xd vertices_m, ShapedRestVertices(model, shape));
  ASSIGN_OR_RETURN(const auto rest_joints_m, RestJointPositions(model, shape));
  AddPoseCorrectives(model, pose, vertices_m);
  return SkinRestVertices(model.skin_joints, model.skin_weights, vertices_m, rest_joints_m, pose);
}

absl::Status SaveBodyModel(const BodyModel& model, const std::string& path) {
  RETURN_IF_ERROR(ValidateBodyModel(model));
  ByteWriter out;
  out.bytes().append(kMagic, sizeof(kMagic));
  out.Put<uint32_t>(kFormatVersion);
  const auto& regressor = model.joint_regressor;
  out.Put<uint32_t>(static_cast<uint32_t>(model.num_vertices()));
  out.Put<uint32_t>(static_cast<uint32_t>(model.triangles.size()));
  out.Put<uint32_t>(static_cast<uint32_t>(model.uvs.size()));
  out.Put<uint32_t>(static_cast<uint32_t>(model.uv_triangles.size()));
  out.Put<uint32_t>(kNumKinectV2Joints);
  out.Put<uint32_t>(static_cast<uint32_t>(regressor.nonZeros()));
  out.Put<uint32_t>(static_cast<uint32_t>(model.shape_directions_m.size()));
  out.Put<uint32_t>(static_cast<uint32_t>(model.pose_correctives_m.size()));
  out.PutString(model.name);
  out.PutMatrix(model.template_vertices_m);
  for (const Eigen::Vector3i& tri : model.triangles) {
    for (int c = 0; c < 3; ++c) out.Put<int32_t>(tri[c]);
  }
  for (const Eigen::Vector2f& uv : model.uvs) {
    out.Put<float>(uv.x());
    out.Put<float>(uv.y());
  }
  for (const Eigen::Vector3i& tri : model.uv_triangles) {
    for (int c = 0; c < 3; ++c) out.Put<int32_t>(tri[c]);
  }
  for (int row = 0; row < regressor.outerSize(); ++row) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(regressor, row); it; ++it) {
      out.Put<int32_t>(row);
      out.Put<int32_t>(static_cast<int32_t>(it.col()));
      out.Put<double>(it.value());
    }
  }
  for (const auto& joints : model.skin_joints) {
    for (int joint : joints) out.Put<int32_t>(joint);
  }
  for (const auto& weights : model.skin_weights) {
    for (float weight : weights) out.Put<float>(weight);
  }
  for (size_t k = 0; k < model.shape_directions_m.size(); ++k) {
    out.PutString(model.shape_names[k]);
    out.PutMatrix(model.shape_directions_m[k]);
  }
  for (const Eigen::Matrix3Xd& corrective : model.pose_correctives_m) out.PutMatrix(corrective);
  return WriteFileAtomically(path, out.bytes());
}

absl::StatusOr<BodyModel> LoadBodyModel(const std::string& path) {
  ASSIGN_OR_RETURN(const std::string bytes, ReadFileToString(path));
  ByteReader reader(bytes, path);
  ASSIGN_OR_RETURN(BodyModel model, ParseBodyModel(reader));
  if (absl::Status status = ValidateBodyModel(model); !status.ok()) {
    return absl::DataLossError(absl::StrCat(path, ": ", status.message()));
  }
  return model;
}

}  // namespace reenact::body
