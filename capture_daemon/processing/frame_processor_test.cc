#include "capture_daemon/processing/frame_processor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "capture_daemon/processing/actor_segmenter.h"
#include "capture_daemon/sensors/freenect_sensor.h"
#include "common/base/time.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/synth/depth_noise.h"
#include "common/synth/scene.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

using Mode = ProcessingOptions::Mode;

v1::SensorInfo InfoFor(const v1::SensorCalibration& calibration, const std::string& backend) {
  v1::SensorInfo info;
  info.set_sensor_id(calibration.sensor_id());
  info.set_backend(backend);
  info.set_model(calibration.model());
  info.set_depth_width_px(calibration.depth_intrinsics().width_px());
  info.set_depth_height_px(calibration.depth_intrinsics().height_px());
  info.set_color_width_px(calibration.color_intrinsics().width_px());
  info.set_color_height_px(calibration.color_intrinsics().height_px());
  info.set_nominal_fps(calibration.nominal_fps());
  *info.mutable_calibration() = calibration;
  return info;
}

CapturedFrame RawFrame(const std::string& id, int64_t index, DepthImageMm depth,
                       std::optional<RgbImage> color) {
  CapturedFrame frame;
  frame.frame.set_sensor_id(id);
  frame.frame.set_frame_index(index);
  frame.frame.set_device_stamp_ns(1000 + index * 33'333'333);
  frame.frame.set_host_stamp_ns(5'000'000'000 + index * 33'333'333);
  frame.depth_mm = std::move(depth);
  frame.color = std::move(color);
  return frame;
}

double IoU(const MaskImage& a, const MaskImage& b) {
  int inter = 0, uni = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    inter += a.data[i] != 0 && b.data[i] != 0;
    uni += a.data[i] != 0 || b.data[i] != 0;
  }
  return uni == 0 ? 1.0 : static_cast<double>(inter) / uni;
}

// ------------------------------------------------------------- encoding

TEST(FrameProcessor, EncodesRawFramesLosslesslyLikeTakes) {
  v1::SensorCalibration calibration = KinectV1DefaultCalibration("k0", "");
  v1::SensorInfo info = InfoFor(calibration, "freenect");
  info.set_provides_registration(true);  // Nothing to register.
  for (const std::string encoding : {"rvl", "rvl+zstd"}) {
    ProcessingOptions options;
    options.segmentation = Mode::kOff;
    options.depth_encoding = encoding;
    options.jpeg_quality = 85;
    auto processor = FrameProcessor::Create(info, options);
    ASSERT_TRUE(processor.ok()) << processor.status();
    DepthImageMm depth(640, 480);
    std::mt19937 rng(3);
    for (auto& v : depth.data) v = (rng() % 7 == 0) ? 0 : static_cast<uint16_t>(500 + rng() % 7000);
    RgbImage color(640, 480);
    for (int y = 0; y < 480; ++y) {
      for (int x = 0; x < 640; ++x) {
        color.at(x, y, 0) = static_cast<uint8_t>(x * 255 / 639);
        color.at(x, y, 1) = static_cast<uint8_t>(y * 255 / 479);
        color.at(x, y, 2) = 128;
      }
    }
    CapturedFrame frame = RawFrame("k0", 7, depth, color);
    ASSERT_TRUE((*processor)->Process(frame).ok());
    EXPECT_FALSE(frame.depth_mm.has_value());
    EXPECT_FALSE(frame.color.has_value());
    const v1::DepthImage& d = frame.frame.depth();
    EXPECT_EQ(d.sensor_id(), "k0");
    EXPECT_EQ(d.frame_index(), 7);
    EXPECT_EQ(d.host_stamp_ns(), frame.frame.host_stamp_ns());
    EXPECT_EQ(d.device_stamp_ns(), frame.frame.device_stamp_ns());
    EXPECT_EQ(d.encoding(), encoding);
    EXPECT_EQ(d.width_px(), 640);
    auto decoded = DecodeDepth(d.data());
    ASSERT_TRUE(decoded.ok());
    EXPECT_TRUE(*decoded == depth) << "depth must be bit-exact";
    const v1::ColorImage& c = frame.frame.color();
    EXPECT_EQ(c.encoding(), "jpeg");
    EXPECT_EQ(c.quality(), 85);
    EXPECT_EQ(c.height_px(), 480);
    auto rgb = DecodeJpeg(c.data());
    ASSERT_TRUE(rgb.ok());
    double sum = 0;
    for (size_t i = 0; i < rgb->data.size(); ++i) sum += std::abs(rgb->data[i] - color.data[i]);
    EXPECT_LT(sum / rgb->data.size(), 2.0) << "mean JPEG error, 8-bit levels";
    EXPECT_FALSE(frame.frame.has_mask());
  }
}

TEST(FrameProcessor, RejectsFramesThatDoNotFit) {
  v1::SensorInfo info = InfoFor(KinectV1DefaultCalibration("k0", ""), "freenect");
  auto processor = FrameProcessor::Create(info, {});
  ASSERT_TRUE(processor.ok()) << processor.status();
  CapturedFrame wrong_size = RawFrame("k0", 0, DepthImageMm(320, 240), std::nullopt);
  EXPECT_EQ((*processor)->Process(wrong_size).code(), absl::StatusCode::kInvalidArgument);
  CapturedFrame wrong_id = RawFrame("k9", 0, DepthImageMm(640, 480), std::nullopt);
  EXPECT_EQ((*processor)->Process(wrong_id).code(), absl::StatusCode::kInvalidArgument);
  CapturedFrame no_depth;
  no_depth.frame.set_sensor_id("k0");
  EXPECT_EQ((*processor)->Process(no_depth).code(), absl::StatusCode::kInvalidArgument);
  ProcessingOptions bad;
  bad.depth_encoding = "png";
  EXPECT_EQ(FrameProcessor::Create(info, bad).status().code(), absl::StatusCode::kInvalidArgument);
  bad = {};
  bad.jpeg_quality = 0;
  EXPECT_EQ(FrameProcessor::Create(info, bad).status().code(), absl::StatusCode::kInvalidArgument);
}

// ---------------------------------------------------------- registration

TEST(FrameProcessor, RegistersKinectV1DepthToColour) {
  const v1::SensorCalibration calibration = KinectV1DefaultCalibration("k0", "");
  ProcessingOptions options;
  options.segmentation = Mode::kOff;
  auto processor = FrameProcessor::Create(InfoFor(calibration, "freenect"), options);
  ASSERT_TRUE(processor.ok()) << processor.status();
  // The output calibration: depth camera = colour camera, identity extrinsics.
  const v1::SensorCalibration& out = (*processor)->calibration();
  EXPECT_EQ(out.depth_intrinsics().width_px(), 640);
  EXPECT_DOUBLE_EQ(out.depth_intrinsics().fx_px(), calibration.color_intrinsics().fx_px());
  EXPECT_DOUBLE_EQ(out.depth_intrinsics().cy_px(), calibration.color_intrinsics().cy_px());
  EXPECT_DOUBLE_EQ(out.color_from_depth().rotation().w(), 1.0);
  EXPECT_DOUBLE_EQ(out.color_from_depth().translation_m().x(), 0.0);

  // A wall at 2.5 m with a square 1.5 m away.
  const CameraIntrinsics depth_k = *FromProto(calibration.depth_intrinsics());
  const CameraIntrinsics color_k = *FromProto(calibration.color_intrinsics());
  const Rigid3d color_from_depth = *FromProto(calibration.color_from_depth());
  DepthImageMm depth(640, 480, 2500);
  Eigen::Vector2d expected = Eigen::Vector2d::Zero();
  double expected_z_mm = 0;
  int n = 0;
  for (int y = 180; y < 260; ++y) {
    for (int x = 380; x < 460; ++x) {
      depth.at(x, y) = 1500;
      const Eigen::Vector3d p = color_from_depth * *depth_k.Unproject({x, y}, 1.5);
      expected += *color_k.Project(p);
      expected_z_mm += p.z() * 1000.0;
      ++n;
    }
  }
  expected /= n;
  expected_z_mm /= n;
  CapturedFrame frame = RawFrame("k0", 0, depth, std::nullopt);
  ASSERT_TRUE((*processor)->Process(frame).ok());
  auto registered = DecodeDepth(frame.frame.depth().data());
  ASSERT_TRUE(registered.ok());
  ASSERT_EQ(registered->width, 640);
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  double z_sum = 0;
  int m = 0;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      const uint16_t z = registered->at(x, y);
      if (z > 1300 && z < 1700) {
        centroid += Eigen::Vector2d(x, y);
        z_sum += z;
        ++m;
      }
    }
  }
  ASSERT_GT(m, 1000);
  centroid /= m;
  const double error_px = (centroid - expected).norm();
  std::printf(
      "registration: square centroid %.2f px from its projection through the calibration, "
      "depth %.1f mm vs %.1f mm\n",
      error_px, z_sum / m, expected_z_mm);
  EXPECT_LT(error_px, 1.0);
  EXPECT_NEAR(z_sum / m, expected_z_mm, 3.0);
  EXPECT_EQ((*processor)->stats().registered, 1);
}

TEST(FrameProcessor, RegistersAndSegmentsRawKinectV1Frames) {
  const v1::SensorCalibration calibration = KinectV1DefaultCalibration("k0", "");
  ProcessingOptions options;
  options.background_seconds = 0.1;
  auto processor = FrameProcessor::Create(InfoFor(calibration, "freenect"), options);
  ASSERT_TRUE(processor.ok()) << processor.status();
  // Four frames of an empty wall 3 m away, then a 0.6 x 0.6 m box 1.8 m away.
  const CameraIntrinsics depth_k = *FromProto(calibration.depth_intrinsics());
  double ms_sum = 0;
  int timed = 0;
  for (int i = 0; i < 10; ++i) {
    DepthImageMm depth(640, 480, 3000);
    if (i >= 4) {
      for (int y = 0; y < 480; ++y) {
        for (int x = 0; x < 640; ++x) {
          const Eigen::Vector3d p = *depth_k.Unproject({x, y}, 1.8);
          if (std::abs(p.x()) < 0.3 && std::abs(p.y()) < 0.3) depth.at(x, y) = 1800;
        }
      }
    }
    CapturedFrame frame = RawFrame("k0", i, depth, RgbImage(640, 480, 90));
    const int64_t begin = SteadyNowNs();
    ASSERT_TRUE((*processor)->Process(frame).ok());
    if (i >= 4) {
      ms_sum += (SteadyNowNs() - begin) * 1e-6;
      ++timed;
    }
    auto registered = DecodeDepth(frame.frame.depth().data());
    auto mask = DecodeMaskRle(frame.frame.mask().data());
    ASSERT_TRUE(registered.ok() && mask.ok());
    ASSERT_EQ(mask->width, registered->width);
    MaskImage box(registered->width, registered->height);
    for (size_t p = 0; p < box.data.size(); ++p) {
      box.data[p] = registered->data[p] > 0 && registered->data[p] < 2400;
    }
    const double iou = IoU(*mask, box);
    if (i < 4) {
      EXPECT_EQ(std::count(mask->data.begin(), mask->data.end(), 1), 0) << "frame " << i;
    } else {
      EXPECT_GE(iou, 0.98) << "frame " << i;
    }
  }
  std::printf("raw Kinect v1 frame (register 640x480 + segment + RVL + JPEG q90): %.1f ms\n",
              ms_sum / timed);
  EXPECT_EQ((*processor)->stats().segmented, 10);
}

// ---------------------------------------------------------- segmentation

constexpr int kBackgroundFrames = 30;

// The synthetic room (common/synth/scene.h) seen without the actor: each depth
// pixel's ray, through the take's calibration, is intersected with the room's
// axis-aligned floor and wall rectangles, then Kinect v2 noise is applied as
// the synthesizer does. The synthesizer renders the same geometry with
// OpenGL, so these frames are the empty room before the actor stepped in.
std::vector<DepthImageMm> RenderEmptyRoom(const v1::SensorCalibration& calibration, int frames) {
  const CameraIntrinsics k = *FromProto(calibration.depth_intrinsics());
  const Rigid3d world_from_depth = *FromProto(calibration.world_from_depth());
  struct Rect {
    Eigen::Vector3d normal, lo, hi;
  };
  std::vector<Rect> rects;
  for (const synth::RoomPart& part : synth::MakeRoom()) {
    const Eigen::Vector3f lo = part.mesh.positions_m.rowwise().minCoeff();
    const Eigen::Vector3f hi = part.mesh.positions_m.rowwise().maxCoeff();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    Eigen::Index axis;
    (hi - lo).minCoeff(&axis);  // The flat axis.
    normal[axis] = 1.0;
    rects.push_back({normal, lo.cast<double>(), hi.cast<double>()});
  }
  FloatImage ideal(k.width, k.height);
  const Eigen::Vector3d origin = world_from_depth.translation;
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const Eigen::Vector3d ray_in_depth = *k.Unproject({x, y}, 1.0);  // z = 1.
      const Eigen::Vector3d dir = world_from_depth.rotation * ray_in_depth;
      double best = std::numeric_limits<double>::infinity();
      for (const Rect& r : rects) {
        const double denom = r.normal.dot(dir);
        if (std::abs(denom) < 1e-12) continue;
        const double t = r.normal.dot(r.lo - origin) / denom;
        if (t <= 0 || t >= best) continue;
        const Eigen::Vector3d p = origin + t * dir;
        if (((p - r.lo).array() >= -1e-6).all() && ((r.hi - p).array() >= -1e-6).all()) best = t;
      }
      ideal.at(x, y) = std::isfinite(best) ? static_cast<float>(best) : 0.0f;
    }
  }
  std::vector<DepthImageMm> out;
  for (int i = 0; i < frames; ++i) {
    out.push_back(synth::ApplyKinectV2DepthNoise(ideal, k, synth::DepthNoiseOptions{}, 9000 + i));
  }
  return out;
}

struct SyntheticCapture {
  v1::SensorCalibration calibration;
  std::vector<DepthImageMm> background;
  std::vector<v1::DepthImage> depth;
  std::vector<v1::ActorMask> mask;
  std::vector<v1::GroundTruthJoints> joints;  // Parallel to depth.
};

const SyntheticCapture& Capture() {
  static const SyntheticCapture* capture = [] {
    auto* c = new SyntheticCapture;
    synth::SynthOptions options;
    // The sensors carry the jittered true skeleton (a device SDK stand-in).
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = "builtin:front-kick";
    options.num_sensors = 1;
    options.seconds = 0.6;
    options.color_width = 480;
    options.color_height = 270;
    options.ground_truth_mesh = false;
    const std::string path = testing::MakeTempDir("processing_take") + "/take.mcap";
    auto summary = synth::SynthesizeTake(options, path);
    if (!summary.ok()) {
      ADD_FAILURE() << summary.status();
      return c;
    }
    auto reader = TakeReader::Open(path);
    if (!reader.ok()) {
      ADD_FAILURE() << reader.status();
      return c;
    }
    c->calibration = (*reader)->sensors().begin()->second;
    const std::string id = c->calibration.sensor_id();
    c->depth = *(*reader)->ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
    c->mask = *(*reader)->ReadAll<v1::ActorMask>(SensorTopic(id, "mask"));
    c->joints = *(*reader)->ReadAll<v1::GroundTruthJoints>(std::string(kGroundTruthJointsTopic));
    c->background = RenderEmptyRoom(c->calibration, kBackgroundFrames);
    return c;
  }();
  return *capture;
}

// Frame `f` of the synthetic capture as `info`'s sensor delivers it: the
// take's depth, without mask or skeleton.
CapturedFrame CaptureFrame(const SyntheticCapture& capture, const v1::SensorInfo& info, size_t f,
                           int64_t index) {
  CapturedFrame frame;
  frame.frame.set_sensor_id(info.sensor_id());
  frame.frame.set_frame_index(index);
  frame.frame.set_host_stamp_ns(capture.depth[f].host_stamp_ns());
  *frame.frame.mutable_depth() = capture.depth[f];
  return frame;
}

TEST(FrameProcessor, SegmentsTheActorOfASyntheticTake) {
  const SyntheticCapture& capture = Capture();
  ASSERT_FALSE(capture.depth.empty());
  ASSERT_EQ(capture.depth.size(), capture.mask.size());
  v1::SensorInfo info = InfoFor(capture.calibration, "playback");
  info.set_provides_mask(false);
  auto processor = FrameProcessor::Create(info, ProcessingOptions{});
  ASSERT_TRUE(processor.ok()) << processor.status();

  // The empty room during the first second (background_seconds), then the
  // take (its masks removed).
  const int64_t period_ns = 33'333'333;
  const int64_t first_take_ns = capture.depth.front().host_stamp_ns();
  int64_t index = 0;
  for (int i = 0; i < kBackgroundFrames; ++i) {
    CapturedFrame frame;
    frame.frame.set_sensor_id(info.sensor_id());
    frame.frame.set_frame_index(index++);
    frame.frame.set_host_stamp_ns(first_take_ns - kNanosPerSecond + i * period_ns);
    v1::DepthImage* d = frame.frame.mutable_depth();
    d->set_encoding("rvl");
    d->set_data(*EncodeDepth(capture.background[i], {}));
    ASSERT_TRUE((*processor)->Process(frame).ok());
    auto mask = DecodeMaskRle(frame.frame.mask().data());
    ASSERT_TRUE(mask.ok());
    EXPECT_EQ(std::count(mask->data.begin(), mask->data.end(), 1), 0) << "background frame " << i;
  }
  double iou_sum = 0, iou_min = 1, ms_sum = 0;
  for (size_t f = 0; f < capture.depth.size(); ++f) {
    CapturedFrame frame = CaptureFrame(capture, info, f, index++);
    const int64_t begin = SteadyNowNs();
    ASSERT_TRUE((*processor)->Process(frame).ok());
    ms_sum += (SteadyNowNs() - begin) * 1e-6;
    const v1::ActorMask& m = frame.frame.mask();
    EXPECT_EQ(m.encoding(), "rle");
    EXPECT_EQ(m.width_px(), capture.depth[f].width_px());
    EXPECT_EQ(m.host_stamp_ns(), capture.depth[f].host_stamp_ns());
    auto ours = DecodeMaskRle(m.data());
    auto truth = DecodeMaskRle(capture.mask[f].data());
    ASSERT_TRUE(ours.ok() && truth.ok());
    const double iou = IoU(*ours, *truth);
    iou_sum += iou;
    iou_min = std::min(iou_min, iou);
  }
  const double n = static_cast<double>(capture.depth.size());
  const ProcessingStats stats = (*processor)->stats();
  std::printf(
      "segmentation: %zu frames, mask IoU vs ground truth mean %.3f min %.3f; "
      "%.1f ms per frame (decode + segment + encode mask); floor found %d\n",
      capture.depth.size(), iou_sum / n, iou_min, ms_sum / n, stats.floor_found);
  EXPECT_TRUE(stats.background_ready);
  EXPECT_TRUE(stats.floor_found);
  // Measured: mean 0.977, min 0.975 (front-kick, procedural body, 18 frames).
  EXPECT_GE(iou_min, 0.95);
  EXPECT_GE(iou_sum / n, 0.96);
}

TEST(ActorSegmenter, FindsTheFloorOfTheSyntheticRoom) {
  const SyntheticCapture& capture = Capture();
  ASSERT_FALSE(capture.background.empty());
  const CameraIntrinsics k = *FromProto(capture.calibration.depth_intrinsics());
  const Rigid3d world_from_depth = *FromProto(capture.calibration.world_from_depth());
  SegmenterOptions options;
  options.noise_model = capture.calibration.model();
  auto segmenter = ActorSegmenter::Create(k, world_from_depth, options);
  ASSERT_TRUE(segmenter.ok()) << segmenter.status();
  int64_t stamp = 0;
  for (const DepthImageMm& frame : capture.background) {
    ASSERT_TRUE(segmenter->Segment(frame, stamp).ok());
    stamp += 33'333'333;
  }
  ASSERT_TRUE(segmenter->Segment(capture.background.back(), SecondsToNs(1.1)).ok());
  ASSERT_TRUE(segmenter->background_ready());
  ASSERT_TRUE(segmenter->floor().has_value());
  // The floor is y = 0 in the world: its normal is world +Y and the depth
  // camera's height above it is world_from_depth's y.
  const Eigen::Vector3d normal_in_world = world_from_depth.rotation * segmenter->floor()->normal;
  const double tilt_deg = std::acos(std::clamp(normal_in_world.y(), -1.0, 1.0)) * 180.0 / M_PI;
  const double height_mm = segmenter->floor()->offset_m * 1000.0;  // n . 0 + d at the camera.
  std::printf("floor: normal %.2f deg from world up, camera %.1f mm above it (truth %.1f mm)\n",
              tilt_deg, height_mm, world_from_depth.translation.y() * 1000.0);
  EXPECT_LT(tilt_deg, 1.0);
  EXPECT_NEAR(height_mm, world_from_depth.translation.y() * 1000.0, 15.0);
}

TEST(ActorSegmenter, NoiseModelMatchesTheSynthesizer) {
  // The Kinect v2 sigma restated in the segmenter equals common/synth's model
  // at normal incidence.
  for (double z = 0.5; z <= 4.5; z += 0.5) {
    EXPECT_NEAR(ActorSegmenter::AxialSigmaMm("kinect_v2_synthetic", z),
                synth::KinectV2AxialSigmaMm(z, 0.0), 1e-9)
        << z;
  }
  EXPECT_NEAR(ActorSegmenter::AxialSigmaMm("kinect_v1", 2.0), 5.7, 0.01);
}

TEST(FrameProcessor, TracksSkeletonsWhereTheSourceGivesNone) {
  const SyntheticCapture& capture = Capture();
  ASSERT_FALSE(capture.depth.empty());
  ASSERT_EQ(capture.joints.size(), capture.depth.size());
  v1::SensorInfo info = InfoFor(capture.calibration, "playback");
  info.set_provides_skeleton(false);
  auto processor = FrameProcessor::Create(info, ProcessingOptions{});
  ASSERT_TRUE(processor.ok()) << processor.status();
  auto world_from_depth = FromProto(capture.calibration.world_from_depth());
  ASSERT_TRUE(world_from_depth.ok());
  // The take's own masks mark the person; the tracker runs on every frame.
  double torso_error_sum = 0.0;
  int torso_joints = 0, person_ids = 0;
  for (size_t f = 0; f < capture.depth.size(); ++f) {
    CapturedFrame frame = CaptureFrame(capture, info, f, static_cast<int64_t>(f));
    *frame.frame.mutable_mask() = capture.mask[f];
    ASSERT_TRUE((*processor)->Process(frame).ok());
    ASSERT_EQ(frame.frame.skeletons_size(), 1) << "frame " << f;
    const v1::Skeleton& skeleton = frame.frame.skeletons(0);
    EXPECT_EQ(skeleton.source(), kTrackerSource);
    EXPECT_EQ(skeleton.body_index(), 1);
    EXPECT_EQ(skeleton.host_stamp_ns(), capture.depth[f].host_stamp_ns());
    ASSERT_EQ(skeleton.joints_size(), body::kNumKinectV2Joints);
    person_ids += skeleton.person_id() == 1 ? 1 : 0;
    const v1::GroundTruthJoints& truth = capture.joints[f];
    for (int t = 0; t < truth.joint_names_size(); ++t) {
      if (truth.joint_names(t) != "SpineBase" && truth.joint_names(t) != "SpineMid" &&
          truth.joint_names(t) != "SpineShoulder") {
        continue;
      }
      for (const v1::Joint& joint : skeleton.joints()) {
        if (joint.name() != truth.joint_names(t)) continue;
        const Eigen::Vector3d tracked = *world_from_depth * FromProto(joint.position_in_depth_m());
        torso_error_sum += (tracked - FromProto(truth.positions_in_world_m(t))).norm();
        ++torso_joints;
      }
    }
  }
  // The torso of a person 2.5 m away is found within 4.5 cm on average
  // (measured: 23.6 mm), and
  // the person keeps one id.
  ASSERT_GT(torso_joints, 0);
  const double torso_mm = 1000.0 * torso_error_sum / torso_joints;
  std::printf("torso joints %d: mean error %.1f mm\n", torso_joints, torso_mm);
  EXPECT_LT(torso_mm, 45.0);
  EXPECT_EQ(person_ids, static_cast<int>(capture.depth.size()));
  const ProcessingStats stats = (*processor)->stats();
  EXPECT_EQ(stats.tracked, static_cast<int64_t>(capture.depth.size()));
  EXPECT_EQ(stats.tracking_errors, 0);
}

// A source with neither skeleton nor mask (a Kinect v1 without a background
// model): the tracker segments the people itself and that segmentation goes
// out as the frame's mask, body index = the skeleton's.
TEST(FrameProcessor, WithoutAMaskTheTrackersSegmentationBecomesTheMask) {
  const SyntheticCapture& capture = Capture();
  ASSERT_FALSE(capture.depth.empty());
  ASSERT_EQ(capture.depth.size(), capture.mask.size());
  v1::SensorInfo info = InfoFor(capture.calibration, "playback");
  info.set_provides_skeleton(false);
  ProcessingOptions options;
  options.segmentation = ProcessingOptions::Mode::kOff;
  auto processor = FrameProcessor::Create(info, options);
  ASSERT_TRUE(processor.ok()) << processor.status();
  int64_t both = 0, either = 0;
  for (size_t f = 0; f < capture.depth.size(); ++f) {
    CapturedFrame frame = CaptureFrame(capture, info, f, static_cast<int64_t>(f));
    ASSERT_TRUE((*processor)->Process(frame).ok());
    ASSERT_EQ(frame.frame.skeletons_size(), 1) << "frame " << f;
    ASSERT_TRUE(frame.frame.has_mask()) << "frame " << f;
    EXPECT_EQ(frame.frame.mask().host_stamp_ns(), capture.depth[f].host_stamp_ns());
    auto got = DecodeMask(frame.frame.mask().encoding(), frame.frame.mask().data());
    ASSERT_TRUE(got.ok()) << got.status();
    auto truth = DecodeMask(capture.mask[f].encoding(), capture.mask[f].data());
    ASSERT_TRUE(truth.ok()) << truth.status();
    ASSERT_EQ(got->data.size(), truth->data.size());
    const int body_index = frame.frame.skeletons(0).body_index();
    for (size_t i = 0; i < got->data.size(); ++i) {
      const bool a = got->data[i] == body_index, b = truth->data[i] != 0;
      both += a && b ? 1 : 0;
      either += a || b ? 1 : 0;
    }
  }
  // The person's pixels against the synthesiser's actor mask (measured:
  // IoU 0.951; the feet lose the pixels next to the floor).
  ASSERT_GT(either, 0);
  const double iou = static_cast<double>(both) / static_cast<double>(either);
  std::printf("tracker's own mask vs the true actor mask: IoU %.3f\n", iou);
  EXPECT_GT(iou, 0.85);
  EXPECT_EQ((*processor)->stats().tracker_masks, static_cast<int64_t>(capture.depth.size()));
}

TEST(FrameProcessor, TrackingKeepsADevicesSkeletonInAutoAndReplacesItWhenOn) {
  const SyntheticCapture& capture = Capture();
  ASSERT_FALSE(capture.depth.empty());
  for (const ProcessingOptions::Mode mode :
       {ProcessingOptions::Mode::kAuto, ProcessingOptions::Mode::kOn}) {
    v1::SensorInfo info = InfoFor(capture.calibration, "playback");
    info.set_provides_skeleton(true);
    ProcessingOptions options;
    options.tracking = mode;
    auto processor = FrameProcessor::Create(info, options);
    ASSERT_TRUE(processor.ok()) << processor.status();
    CapturedFrame frame;
    frame.frame.set_sensor_id(info.sensor_id());
    *frame.frame.mutable_depth() = capture.depth.back();
    *frame.frame.mutable_mask() = capture.mask.back();
    frame.frame.add_skeletons()->set_source("device");
    ASSERT_TRUE((*processor)->Process(frame).ok());
    ASSERT_EQ(frame.frame.skeletons_size(), 1);
    EXPECT_EQ(frame.frame.skeletons(0).source(),
              mode == ProcessingOptions::Mode::kOn ? kTrackerSource : "device");
  }
}

TEST(FrameProcessor, TrackingAFrameWithNobodyOrGarbageKeepsStreaming) {
  const SyntheticCapture& capture = Capture();
  ASSERT_FALSE(capture.background.empty());
  v1::SensorInfo info = InfoFor(capture.calibration, "playback");
  ProcessingOptions options;
  options.segmentation = ProcessingOptions::Mode::kOff;
  auto processor = FrameProcessor::Create(info, options);
  ASSERT_TRUE(processor.ok()) << processor.status();
  // The empty room: no skeleton.
  CapturedFrame empty;
  empty.frame.set_sensor_id(info.sensor_id());
  empty.frame.mutable_depth()->set_encoding("rvl");
  empty.frame.mutable_depth()->set_data(*EncodeDepth(capture.background[0], {}));
  ASSERT_TRUE((*processor)->Process(empty).ok());
  EXPECT_EQ(empty.frame.skeletons_size(), 0);
  // No depth at all, and depth of the wrong size: clear errors, no crash.
  CapturedFrame small;
  small.frame.set_sensor_id(info.sensor_id());
  small.frame.mutable_depth()->set_encoding("rvl");
  small.frame.mutable_depth()->set_data(*EncodeDepth(DepthImageMm(8, 8, 1500), {}));
  const absl::Status s = (*processor)->Process(small);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
  // A network that does not exist fails Create with the path.
  options.tracker.model_path = "/nonexistent/pose_net.onnx";
  auto missing = FrameProcessor::Create(info, options);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("/nonexistent/pose_net.onnx"), std::string::npos);
  // So does a forest, when the forest is asked for.
  options.tracker.method = tracking::TrackerMethod::kForest;
  options.tracker.forest_path = "/nonexistent/forest.rtf";
  auto missing_forest = FrameProcessor::Create(info, options);
  ASSERT_FALSE(missing_forest.ok());
  EXPECT_NE(missing_forest.status().message().find("/nonexistent/forest.rtf"), std::string::npos);
}

}  // namespace
}  // namespace reenact::capture
