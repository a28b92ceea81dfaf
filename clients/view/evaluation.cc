#include "clients/view/evaluation.h"

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <set>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/geometry/surface_distance.h"
#include "common/render/mesh_data.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::view {
namespace {

// The reconstructed surface at `frame`: every valid part posed in the world.
void PosedParts(const VdtmModel& model, int frame, Eigen::Matrix3Xd* vertices,
                std::vector<Eigen::Vector3i>* triangles) {
  int total = 0;
  for (int b = 0; b < model.num_parts(); ++b) {
    if (model.pose(frame, b).valid)
      total += static_cast<int>(model.part(b).positions_in_part_m.cols());
  }
  vertices->resize(3, total);
  triangles->clear();
  int offset = 0;
  for (int b = 0; b < model.num_parts(); ++b) {
    if (!model.pose(frame, b).valid) continue;
    const PartMesh& part = model.part(b);
    const Eigen::Affine3d world_from_part = model.pose(frame, b).WorldFromPartScaled();
    const int n = static_cast<int>(part.positions_in_part_m.cols());
    vertices->middleCols(offset, n) = world_from_part * part.positions_in_part_m.cast<double>();
    for (const Eigen::Vector3i& t : part.triangles) {
      triangles->push_back(t + Eigen::Vector3i::Constant(offset));
    }
    offset += n;
  }
}

// The reconstructed surface at `frame` of a body-model reenactment: the
// posed body mesh (skinning plus the frame's offsets), triangles over the
// model vertices; nothing when the pose is not valid.
absl::Status PosedBody(const BodyMesh& body, const std::optional<BodyFramePose>& pose,
                       Eigen::Matrix3Xd* vertices, std::vector<Eigen::Vector3i>* triangles) {
  triangles->clear();
  if (!pose || !pose->valid) return absl::OkStatus();
  ASSIGN_OR_RETURN(body::PosedBody posed, PoseBodyMesh(body, *pose));
  *vertices = std::move(posed.vertices_m);
  *triangles = body.triangles;
  return absl::OkStatus();
}

struct SurfaceSums {
  double accuracy_m = 0, completeness_m = 0;
  int64_t accuracy_count = 0, completeness_count = 0;
  int frames = 0;
};

absl::Status AddSurfaceFrame(const Eigen::Matrix3Xd& recon,
                             const std::vector<Eigen::Vector3i>& recon_triangles,
                             const Eigen::Matrix3Xd& truth,
                             const std::vector<Eigen::Vector3i>& truth_triangles, double cell_m,
                             SurfaceSums* sums) {
  if (recon_triangles.empty()) return absl::OkStatus();  // Nothing posed: no surface.
  ASSIGN_OR_RETURN(auto truth_index, TriangleSurfaceIndex::Build(truth, truth_triangles, cell_m));
  ASSIGN_OR_RETURN(auto recon_index, TriangleSurfaceIndex::Build(recon, recon_triangles, cell_m));
  for (int i = 0; i < recon.cols(); ++i) sums->accuracy_m += truth_index.Distance(recon.col(i));
  for (int i = 0; i < truth.cols(); ++i) sums->completeness_m += recon_index.Distance(truth.col(i));
  sums->accuracy_count += recon.cols();
  sums->completeness_count += truth.cols();
  ++sums->frames;
  return absl::OkStatus();
}

absl::StatusOr<RgbImage> DecodePng(const std::string& bytes) {
  if (bytes.empty()) return RgbImage();
  const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8UC1,
                        const_cast<char*>(bytes.data()));
  const cv::Mat bgr = cv::imdecode(encoded, cv::IMREAD_COLOR);
  if (bgr.empty()) return absl::DataLossError("ground truth albedo is not a decodable PNG");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  RgbImage image(rgb.cols, rgb.rows);
  for (int y = 0; y < rgb.rows; ++y) {
    std::memcpy(&image.at(0, y), rgb.ptr(y), static_cast<size_t>(rgb.cols) * 3);
  }
  return image;
}

// Renders the reenactment and the truth from the novel viewpoint and pools
// the colour error and silhouette overlap.
class NovelViewScorer {
 public:
  // `first_mesh`: a true posed mesh, uploaded once (AddFrame moves it).
  static absl::StatusOr<std::unique_ptr<NovelViewScorer>> Create(const Reenactment& data,
                                                                 const GroundTruth& truth,
                                                                 const Eigen::Matrix3Xd& first_mesh,
                                                                 const SensorCalibration& sensor,
                                                                 const Eigen::Vector3d& pivot,
                                                                 const EvaluationOptions& options) {
    auto scorer = std::unique_ptr<NovelViewScorer>(new NovelViewScorer(options));
    render::RendererOptions renderer_options;
    renderer_options.max_width = options.novel_width;
    renderer_options.max_height = options.novel_height;
    ASSIGN_OR_RETURN(scorer->renderer_, render::OffscreenRenderer::Create(renderer_options));
    ASSIGN_OR_RETURN(render::RenderCamera base,
                     SensorRenderCamera(sensor, options.novel_width, options.novel_height));
    scorer->camera_ = OrbitCamera(base, pivot, options.novel_angle_deg);
    ReenactmentRendererOptions reenactment_options;
    reenactment_options.mode = options.mode;
    ASSIGN_OR_RETURN(scorer->reenactment_, ReenactmentRenderer::Create(
                                               data, scorer->renderer_.get(), reenactment_options));
    RETURN_IF_ERROR(scorer->SetUpTruth(truth, first_mesh));
    return scorer;
  }

  absl::Status AddFrame(int frame, const Eigen::Matrix3Xd& truth_positions) {
    render::RenderOutputs recon;
    recon.requested = render::kRenderColour | render::kRenderLabel;
    RETURN_IF_ERROR(reenactment_->Render(frame, camera_, &recon));
    RETURN_IF_ERROR(
        renderer_->UpdateMeshPositions(truth_item_.mesh, truth_positions.cast<float>()));
    render::RenderOutputs truth;
    truth.requested = render::kRenderColour | render::kRenderLabel;
    RETURN_IF_ERROR(renderer_->Render(camera_, {truth_item_}, &truth));
    int64_t both = 0, either = 0;
    std::vector<uint8_t> overlap(recon.label.data.size(), 0);
    for (size_t i = 0; i < recon.label.data.size(); ++i) {
      const bool a = recon.label.data[i] > 0, b = truth.label.data[i] > 0;
      either += a || b;
      if (!(a && b)) continue;
      ++both;
      overlap[i] = 1;
      for (int c = 0; c < 3; ++c) {
        const double d =
            static_cast<double>(recon.colour.data[3 * i + c]) - truth.colour.data[3 * i + c];
        squared_error_ += d * d;
      }
    }
    if (has_albedo_) {
      samples_ += 3 * both;
      const SsimSums ssim = MaskedSsim(recon.colour, truth.colour, overlap);
      ssim_sum_ += ssim.sum;
      ssim_pixels_ += ssim.pixels;
    }
    if (either > 0) {
      iou_sum_ += static_cast<double>(both) / either;
      ++frames_;
    }
    if (!options_.image_dir.empty()) RETURN_IF_ERROR(WriteSideBySide(frame, recon, truth));
    return absl::OkStatus();
  }

  void Finish(EvaluationResult* result) const {
    result->novel_view_frames = frames_;
    if (frames_ > 0) result->iou_90 = iou_sum_ / frames_;
    result->psnr_pixels = samples_ / 3;
    if (has_albedo_) result->psnr_db_90 = PsnrDb(squared_error_, samples_);
    if (has_albedo_ && ssim_pixels_ > 0) result->ssim_90 = ssim_sum_ / ssim_pixels_;
  }

 private:
  explicit NovelViewScorer(const EvaluationOptions& options) : options_(options) {}

  absl::Status SetUpTruth(const GroundTruth& truth, const Eigen::Matrix3Xd& first_mesh) {
    const GroundTruthTopology& topology = truth.topology;
    const Eigen::Matrix3Xf rest = first_mesh.cast<float>();
    ASSIGN_OR_RETURN(RgbImage albedo, DecodePng(topology.albedo_png));
    has_albedo_ = !albedo.empty() && !topology.uvs.empty() &&
                  topology.uv_triangles.size() == topology.triangles.size();
    render::MeshData mesh;
    if (has_albedo_) {
      ASSIGN_OR_RETURN(mesh, render::MeshFromCornerUvs(rest, topology.triangles, topology.uvs,
                                                       topology.uv_triangles));
      ASSIGN_OR_RETURN(truth_item_.texture, renderer_->UploadTexture(albedo));
    } else {
      mesh.positions_m = rest;
      mesh.triangles = topology.triangles;
      mesh.normals = render::ComputeVertexNormals(rest, topology.triangles);
    }
    ASSIGN_OR_RETURN(truth_item_.mesh, renderer_->UploadMesh(mesh));
    truth_item_.lit = true;
    truth_item_.label = 1;
    render::ShadingOptions shading;  // The light the take's colour was rendered under.
    const Eigen::Vector3d& light = topology.direction_to_light_in_world;
    if (light.norm() > 0) {
      shading.headlight = false;
      shading.direction_to_light_in_world = light;
      shading.ambient = topology.ambient;
      shading.diffuse = topology.diffuse;
    }
    return renderer_->SetShading(shading);
  }

  absl::Status WriteSideBySide(int frame, const render::RenderOutputs& recon,
                               const render::RenderOutputs& truth) const {
    const int w = recon.colour.width, h = recon.colour.height;
    cv::Mat image(h, 2 * w, CV_8UC3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int c = 0; c < 3; ++c) {
          image.at<cv::Vec3b>(y, x)[2 - c] = recon.colour.at(x, y, c);
          image.at<cv::Vec3b>(y, w + x)[2 - c] = truth.colour.at(x, y, c);
        }
      }
    }
    std::error_code ec;
    std::filesystem::create_directories(options_.image_dir, ec);
    const std::string path =
        (std::filesystem::path(options_.image_dir) / absl::StrFormat("novel_%05d.png", frame))
            .string();
    if (!cv::imwrite(path, image))
      return absl::PermissionDeniedError(absl::StrCat(path, ": cannot write"));
    return absl::OkStatus();
  }

  EvaluationOptions options_;
  std::unique_ptr<render::OffscreenRenderer> renderer_;
  std::unique_ptr<ReenactmentRenderer> reenactment_;
  render::RenderCamera camera_;
  render::DrawItem truth_item_;
  bool has_albedo_ = false;
  double squared_error_ = 0.0;
  int64_t samples_ = 0;
  double iou_sum_ = 0.0;
  double ssim_sum_ = 0.0;
  int64_t ssim_pixels_ = 0;
  int frames_ = 0;
};

// Sensor 0 of the reenactment (else the take's first sensor).
absl::StatusOr<SensorCalibration> FirstSensor(const Reenactment& data, const GroundTruth& truth) {
  if (!data.info.sensors.empty()) return data.info.sensors.front();
  if (!truth.sensors.empty()) return truth.sensors.front();
  return absl::FailedPreconditionError("neither the reenactment nor the take has a sensor");
}

// Every options.every-th instant of `num_frames`.
std::set<int64_t> EveryKth(int num_frames, int every) {
  std::set<int64_t> frames;
  for (int f = 0; f < num_frames; f += every) frames.insert(f);
  return frames;
}

}  // namespace

absl::Status EvaluationOptions::Validate() const {
  if (every < 1) return absl::InvalidArgumentError("--every must be >= 1");
  if (novel_width < 16 || novel_height < 16 || novel_width > 8192 || novel_height > 8192) {
    return absl::InvalidArgumentError("the novel view must be 16..8192 pixels wide and high");
  }
  if (!std::isfinite(novel_angle_deg)) return absl::InvalidArgumentError("bad novel view angle");
  if (!(grid_cell_m > 0) || !std::isfinite(grid_cell_m)) {
    return absl::InvalidArgumentError("grid_cell_m must be > 0");
  }
  return absl::OkStatus();
}

std::map<std::string, double> EvaluationResult::Figures() const {
  return {{"frames_evaluated", frames_evaluated},
          {"surface_mm", surface_mm},
          {"surface_accuracy_mm", surface_accuracy_mm},
          {"surface_completeness_mm", surface_completeness_mm},
          {"surface_frames", surface_frames},
          {"psnr_db_90", psnr_db_90},
          {"iou_90", iou_90},
          {"ssim_90", ssim_90},
          {"psnr_pixels", static_cast<double>(psnr_pixels)},
          {"novel_view_frames", novel_view_frames},
          {"mpjpe_mm", mpjpe_mm},
          {"mpjpe_joints", static_cast<double>(mpjpe_joints)}};
}

SsimSums MaskedSsim(const RgbImage& a, const RgbImage& b, const std::vector<uint8_t>& mask) {
  SsimSums out;
  const int w = a.width, h = a.height;
  if (b.width != w || b.height != h || mask.size() != static_cast<size_t>(w) * h || w == 0 ||
      h == 0) {
    return out;
  }
  cv::Mat m(h, w, CV_64F);
  for (int i = 0; i < w * h; ++i) m.at<double>(i) = mask[i] ? 1.0 : 0.0;
  // Gaussian sums restricted to the mask (zero outside the image).
  const auto blur = [](const cv::Mat& in) {
    cv::Mat result;
    cv::GaussianBlur(in, result, cv::Size(11, 11), 1.5, 1.5, cv::BORDER_CONSTANT);
    return result;
  };
  const cv::Mat weight = blur(m);
  constexpr double kC1 = (0.01 * 255) * (0.01 * 255), kC2 = (0.03 * 255) * (0.03 * 255);
  std::vector<double> ssim(static_cast<size_t>(w) * h, 0.0);
  for (int c = 0; c < 3; ++c) {
    cv::Mat x(h, w, CV_64F), y(h, w, CV_64F);
    for (int i = 0; i < w * h; ++i) {
      x.at<double>(i) = mask[i] ? a.data[3 * i + c] : 0.0;
      y.at<double>(i) = mask[i] ? b.data[3 * i + c] : 0.0;
    }
    const cv::Mat sx = blur(x), sy = blur(y), sxx = blur(x.mul(x)), syy = blur(y.mul(y)),
                  sxy = blur(x.mul(y));
    for (int i = 0; i < w * h; ++i) {
      if (!mask[i]) continue;
      const double wt = weight.at<double>(i);  // > 0: the centre is in the mask.
      const double mx = sx.at<double>(i) / wt, my = sy.at<double>(i) / wt;
      const double vx = std::max(0.0, sxx.at<double>(i) / wt - mx * mx);
      const double vy = std::max(0.0, syy.at<double>(i) / wt - my * my);
      const double cxy = sxy.at<double>(i) / wt - mx * my;
      ssim[i] += ((2 * mx * my + kC1) * (2 * cxy + kC2)) /
                 ((mx * mx + my * my + kC1) * (vx + vy + kC2)) / 3.0;
    }
  }
  for (int i = 0; i < w * h; ++i) {
    if (!mask[i]) continue;
    out.sum += ssim[i];
    ++out.pixels;
  }
  return out;
}

double PsnrDb(double sum_squared_error, int64_t count) {
  if (count <= 0) return EvaluationResult::kNaN;
  const double mse = sum_squared_error / static_cast<double>(count);
  if (mse <= 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

std::set<int64_t> EvaluationMeshFrames(const Reenactment& data, const EvaluationOptions& options) {
  if (!(options.surface || options.novel_view) || options.every < 1) return {};
  return EveryKth(static_cast<int>(data.frames.size()), options.every);
}

absl::StatusOr<EvaluationResult> EvaluateReenactment(const Reenactment& data,
                                                     const GroundTruth& truth,
                                                     const EvaluationOptions& options,
                                                     const ProgressCallback& progress) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(VdtmModel model, VdtmModel::Create(data));
  const std::set<int64_t> wanted = EveryKth(model.num_frames(), options.every);
  const bool need_mesh = options.surface || options.novel_view;
  std::vector<int> frames;  // Evaluated instants: every k-th with ground truth.
  for (int64_t f : wanted) {
    if (truth.joints.count(f) && (!need_mesh || truth.meshes.count(f)))
      frames.push_back(static_cast<int>(f));
  }
  if (frames.empty()) {
    return absl::FailedPreconditionError(
        "the reenactment and the take's ground truth share no instant");
  }
  EvaluationResult result;
  result.frames_evaluated = static_cast<int>(frames.size());
  std::unique_ptr<NovelViewScorer> scorer;
  if (options.novel_view) {
    Eigen::Vector3d pivot = Eigen::Vector3d::Zero();  // Mean true root (SpineBase).
    for (int f : frames) pivot += truth.joints.at(f)[0];
    pivot /= static_cast<double>(frames.size());
    ASSIGN_OR_RETURN(SensorCalibration sensor, FirstSensor(data, truth));
    ASSIGN_OR_RETURN(scorer, NovelViewScorer::Create(data, truth, truth.meshes.at(frames.front()),
                                                     sensor, pivot, options));
  }
  SurfaceSums surface;
  double joint_error_m = 0.0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const int f = frames[i];
    if (options.surface) {
      Eigen::Matrix3Xd recon;
      std::vector<Eigen::Vector3i> recon_triangles;
      if (data.is_body()) {
        RETURN_IF_ERROR(PosedBody(*data.body, data.frames[f].body, &recon, &recon_triangles));
      } else {
        PosedParts(model, f, &recon, &recon_triangles);
      }
      RETURN_IF_ERROR(AddSurfaceFrame(recon, recon_triangles, truth.meshes.at(f),
                                      truth.topology.triangles, options.grid_cell_m, &surface));
    }
    if (scorer != nullptr) RETURN_IF_ERROR(scorer->AddFrame(f, truth.meshes.at(f)));
    if (options.joints) {
      for (int j = 0; j < kNumSkeletonJoints; ++j) {
        if (!model.joints_valid(f)[j]) continue;
        joint_error_m += (model.joints(f)[j] - truth.joints.at(f)[j]).norm();
        ++result.mpjpe_joints;
      }
    }
    if (progress && !progress({"evaluate", (i + 1.0) / frames.size(), static_cast<int64_t>(i + 1),
                               static_cast<int64_t>(frames.size())})) {
      return absl::CancelledError("evaluation cancelled");
    }
  }
  if (surface.accuracy_count > 0 && surface.completeness_count > 0) {
    result.surface_accuracy_mm = 1e3 * surface.accuracy_m / surface.accuracy_count;
    result.surface_completeness_mm = 1e3 * surface.completeness_m / surface.completeness_count;
    result.surface_mm = 0.5 * (result.surface_accuracy_mm + result.surface_completeness_mm);
  }
  result.surface_frames = surface.frames;
  if (scorer != nullptr) scorer->Finish(&result);
  if (result.mpjpe_joints > 0) result.mpjpe_mm = 1e3 * joint_error_m / result.mpjpe_joints;
  return result;
}

}  // namespace reenact::view
