// The recording readers on the real Azure Kinect recording of the shared
// data, on TUM folders and OpenNI2 recordings written here, and on damaged or
// hostile input.
#include "common/io/recordings/recording.h"

#include <OpenNI.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"
#include "common/io/recordings/recording_import.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"

namespace reenact::recordings {
namespace {

namespace fs = std::filesystem;

const std::string kMkv = testing::TestDataPath("rgbd/azure-kinect-mkv/recording.mkv");

#define REQUIRE_MKV()                                                                       \
  do {                                                                                      \
    if (!fs::exists(kMkv)) {                                                                \
      GTEST_SKIP() << "\n*** SKIPPED: the real Azure Kinect recording " << kMkv             \
                   << " is missing; the shared data folder is not beside the checkout ***"; \
    }                                                                                       \
  } while (false)

cv::Mat ReadPng16(const std::string& path) { return cv::imread(path, cv::IMREAD_UNCHANGED); }

// Largest |a - b| over two depth images of equal size; -1 when sizes differ.
int MaxDifference(const DepthImageMm& a, const cv::Mat& b) {
  if (b.type() != CV_16UC1 || a.width != b.cols || a.height != b.rows) return -1;
  int worst = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      worst = std::max(worst, std::abs(int{a.at(x, y)} - int{b.at<uint16_t>(y, x)}));
    }
  }
  return worst;
}

TEST(AzureMkv, FirstDepthFrameEqualsTheRecordingsPixels) {
  REQUIRE_MKV();
  const cv::Mat truth =
      ReadPng16(testing::TestDataPath("rgbd/azure-kinect-mkv/derived/depth_640x576_mm.png"));
  ASSERT_EQ(truth.type(), CV_16UC1);
  auto reader = OpenRecording(kMkv, RecordingFormat::kAzureMkv);
  ASSERT_TRUE(reader.ok()) << reader.status();
  auto frame = (*reader)->Next();
  ASSERT_TRUE(frame.ok()) << frame.status();
  ASSERT_TRUE(frame->has_value());
  const RecordedFrame& f = **frame;
  EXPECT_EQ(f.depth_mm.width, 640);
  EXPECT_EQ(f.depth_mm.height, 576);
  const int difference = MaxDifference(f.depth_mm, truth);
  EXPECT_EQ(difference, 0) << "max |depth - derived/depth_640x576_mm.png| in mm";
  int64_t valid = 0;
  for (uint16_t v : f.depth_mm.data) valid += v != 0;
  EXPECT_GT(valid, 640 * 576 / 4);
  std::printf("first depth frame: max difference %d mm over %d px, %lld valid\n", difference,
              640 * 576, static_cast<long long>(valid));

  // Colour of the same capture: a JPEG that decodes to 1280x720.
  ASSERT_TRUE(f.has_color());
  auto rgb = DecodeJpeg(f.color_jpeg);
  ASSERT_TRUE(rgb.ok()) << rgb.status();
  EXPECT_EQ(rgb->width, 1280);
  EXPECT_EQ(rgb->height, 720);
  EXPECT_LE(std::abs(f.color_stamp_ns - f.stamp_ns), 17'000'000);

  // The rest of the frames read, stamps increasing.
  int64_t frames = 1, previous = f.stamp_ns;
  for (;;) {
    auto next = (*reader)->Next();
    ASSERT_TRUE(next.ok()) << next.status();
    if (!next->has_value()) break;
    EXPECT_GT((*next)->stamp_ns, previous);
    previous = (*next)->stamp_ns;
    ++frames;
  }
  EXPECT_GE(frames, 1);  // The shared recording holds one capture.
  std::printf("%lld depth frames\n", static_cast<long long>(frames));
}

// The mode-specific intrinsics as the Azure Kinect SDK derives them from
// calibration.json (computed here from the JSON, independently of the
// reader's code path).
TEST(AzureMkv, IntrinsicsAndExtrinsicsMatchCalibrationJson) {
  REQUIRE_MKV();
  auto text = ReadFileToString(testing::TestDataPath("rgbd/azure-kinect-mkv/calibration.json"));
  ASSERT_TRUE(text.ok()) << text.status();
  const nlohmann::json j = nlohmann::json::parse(*text);
  nlohmann::json depth, color;
  for (const auto& camera : j["CalibrationInformation"]["Cameras"]) {
    if (camera["Location"] == "CALIBRATION_CameraLocationD0") depth = camera;
    if (camera["Location"] == "CALIBRATION_CameraLocationPV0") color = camera;
  }
  auto reader = OpenRecording(kMkv, RecordingFormat::kAzureMkv);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const RecordingInfo& info = (*reader)->info();
  ASSERT_TRUE(info.has_color);

  // Depth NFOV unbinned: 1024x1024 binned, crop (192, 180); colour 720p:
  // 1280x960 binned, crop (0, 120); then -0.5 to pixel centres.
  struct Expect {
    const nlohmann::json& camera;
    const LensModel& lens;
    double bw, bh, crop_x, crop_y;
  };
  double worst = 0.0;
  for (const Expect& e : {Expect{depth, info.depth_lens, 1024, 1024, 192, 180},
                          Expect{color, info.color_lens, 1280, 960, 0, 120}}) {
    const auto& p = e.camera["Intrinsics"]["ModelParameters"];
    const CameraIntrinsics& k = e.lens.pinhole;
    const double expected[] = {p[0].get<double>() * e.bw - e.crop_x - 0.5,
                               p[1].get<double>() * e.bh - e.crop_y - 0.5,
                               p[2].get<double>() * e.bw,
                               p[3].get<double>() * e.bh,
                               p[4],
                               p[5],
                               p[6],
                               p[7],
                               p[8],
                               p[9],
                               p[13],
                               p[12]};
    const double actual[] = {k.cx, k.cy,      k.fx,      k.fy,      k.k1, k.k2,
                             k.k3, e.lens.k4, e.lens.k5, e.lens.k6, k.p1, k.p2};
    for (int i = 0; i < 12; ++i) {
      EXPECT_DOUBLE_EQ(actual[i], expected[i]) << "parameter " << i;
      worst = std::max(worst, std::abs(actual[i] - expected[i]));
    }
  }
  std::printf("intrinsics: largest difference to calibration.json %g\n", worst);
  EXPECT_EQ(info.depth_lens.pinhole.width, 640);
  EXPECT_EQ(info.color_lens.pinhole.width, 1280);
  EXPECT_EQ(info.color_lens.pinhole.height, 720);

  // Extrinsics: the colour camera's Rt (depth is the reference), metres.
  const auto& r = color["Rt"]["Rotation"];
  const auto& t = color["Rt"]["Translation"];
  const Eigen::Matrix3d rotation = info.color_from_depth.rotation.toRotationMatrix();
  for (int i = 0; i < 9; ++i) {
    EXPECT_NEAR(rotation(i / 3, i % 3), r[i].get<double>(), 1e-6) << "rotation " << i;
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(info.color_from_depth.translation(i), t[i].get<double>());
  }
  EXPECT_NEAR(info.color_from_depth.translation.norm(), 0.032, 0.002);  // The 32 mm baseline.

  // The five-coefficient model stored in a take stays close to the rational
  // one over the image.
  double depth_fit = 0, color_fit = 0;
  const v1::SensorCalibration calibration = MakeCalibration(info, "k0", &depth_fit, &color_fit);
  std::printf("lens fit: depth %.3f px, colour %.3f px\n", depth_fit, color_fit);
  EXPECT_LT(depth_fit, 2.0);
  EXPECT_LT(color_fit, 2.0);
  EXPECT_DOUBLE_EQ(calibration.depth_intrinsics().fx_px(), info.depth_lens.pinhole.fx);
}

TEST(AzureMkv, ImportedTakeHoldsTheSamePixelsAndOpensInMcapCore) {
  REQUIRE_MKV();
  const std::string dir = testing::MakeTempDir("mkv_import");
  const std::string take_path = dir + "/take.mcap";
  auto reader = OpenRecording(kMkv, RecordingFormat::kAzureMkv);
  ASSERT_TRUE(reader.ok()) << reader.status();
  auto report = ImportRecording(**reader, take_path);
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->frames, report->frames_with_color);

  auto take = TakeReader::Open(take_path);
  ASSERT_TRUE(take.ok()) << take.status();
  ASSERT_EQ((*take)->sensors().count("k0"), 1u);
  EXPECT_EQ((*take)->frame_count(), report->frames);
  auto depths = (*take)->ReadAll<v1::DepthImage>(SensorTopic("k0", "depth"));
  ASSERT_TRUE(depths.ok()) << depths.status();
  ASSERT_FALSE(depths->empty());
  auto first = DecodeDepth(depths->front().data());
  ASSERT_TRUE(first.ok()) << first.status();
  const cv::Mat truth =
      ReadPng16(testing::TestDataPath("rgbd/azure-kinect-mkv/derived/depth_640x576_mm.png"));
  EXPECT_EQ(MaxDifference(*first, truth), 0);
  auto colors = (*take)->ReadAll<v1::ColorImage>(SensorTopic("k0", "color"));
  ASSERT_TRUE(colors.ok()) << colors.status();
  ASSERT_EQ(colors->size(), depths->size());
  EXPECT_EQ(colors->front().width_px(), 1280);
  EXPECT_TRUE(DecodeJpeg(colors->front().data()).ok());

  // An MCAP reader written independently of ours (tests/js, @mcap/core).
  const std::string js = std::string(REENACT_SOURCE_DIR) + "/tests/js";
  if (std::system("node --version > /dev/null 2>&1") != 0 ||
      !fs::exists(js + "/node_modules/@mcap/core")) {
    GTEST_SKIP() << "\n*** SKIPPED (the rest): node or " << js
                 << "/node_modules/@mcap/core is missing; run `npm ci --prefix tests/js` ***";
  }
  const std::string command = "node '" + js + "/check_take.mjs' '" + take_path + "' 2>&1";
  std::FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[4096];
  for (size_t n; (n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0;) output.append(buffer, n);
  const int status = ::pclose(pipe);
  const nlohmann::json result = nlohmann::json::parse(output, nullptr, false);
  ASSERT_FALSE(result.is_discarded()) << output;
  EXPECT_EQ(status, 0) << output;
  EXPECT_TRUE(result["problems"].empty()) << result["problems"].dump(2);
  EXPECT_EQ(result["counts"]["/sensor/k0/depth"].get<int64_t>(), report->frames);
  EXPECT_EQ(result["counts"]["/sensor/k0/color"].get<int64_t>(), report->frames);
}

TEST(AzureMkv, TruncatedOrForeignFilesAreErrors) {
  REQUIRE_MKV();
  const std::string dir = testing::MakeTempDir("mkv_bad");
  auto bytes = ReadFileToString(kMkv);
  ASSERT_TRUE(bytes.ok());
  // Cuts before the end of the depth block (the recording holds one
  // capture): the import fails, naming the file, and leaves no take.
  for (const size_t keep : {size_t{200}, size_t{4096}, bytes->size() / 3, bytes->size() / 2}) {
    const std::string path = dir + "/cut_" + std::to_string(keep) + ".mkv";
    ASSERT_TRUE(WriteFileAtomically(path, bytes->substr(0, keep)).ok());
    absl::Status status;
    auto reader = OpenRecording(path, RecordingFormat::kAzureMkv);
    if (reader.ok()) {
      status = ImportRecording(**reader, dir + "/cut.mcap").status();
    } else {
      status = reader.status();
    }
    EXPECT_FALSE(status.ok()) << "cut at " << keep;
    EXPECT_NE(status.message().find(path), std::string::npos) << status;
    EXPECT_FALSE(fs::exists(dir + "/cut.mcap"));
    std::printf("cut at %zu bytes: %s\n", keep, status.ToString().c_str());
  }
  const std::string junk = dir + "/junk.mkv";
  ASSERT_TRUE(WriteFileAtomically(junk, std::string(5000, 'x')).ok());
  auto reader = OpenRecording(junk, RecordingFormat::kAzureMkv);
  ASSERT_FALSE(reader.ok());
  EXPECT_NE(reader.status().message().find("junk.mkv"), std::string::npos) << reader.status();
  EXPECT_EQ(OpenRecording(dir + "/none.mkv", RecordingFormat::kAzureMkv).status().code(),
            absl::StatusCode::kNotFound);
}

// ------------------------------------------------------------------- TUM

struct TumFixture {
  std::string dir;
  std::vector<DepthImageMm> depth_mm;  // What each depth PNG holds, in mm.
  std::vector<cv::Vec3b> color;        // The uniform colour of each rgb PNG.
};

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// Four depth frames at 30 Hz from t0 = 1305031102.175304; colour images
// 10 ms after depth frames 0, 1 and 3 (frame 2's colour is 35 ms late: no
// partner within 20 ms), plus one stray colour image.
TumFixture WriteTum(const std::string& name) {
  TumFixture f;
  f.dir = testing::MakeTempDir(name);
  fs::create_directories(f.dir + "/depth");
  fs::create_directories(f.dir + "/rgb");
  std::string depth_txt = "# depth maps\n# file: 'synthetic'\n# timestamp filename\n";
  std::string rgb_txt = "# color images\n# timestamp filename\n";
  const char* depth_stamps[] = {"1305031102.175304", "1305031102.208637", "1305031102.241970",
                                "1305031102.275304"};
  const char* rgb_stamps[] = {"1305031102.185304", "1305031102.218637", "1305031102.276970",
                              "1305031102.285304", "1305031102.900000"};
  for (int i = 0; i < 4; ++i) {
    DepthImageMm mm(64, 48);
    cv::Mat png(48, 64, CV_16UC1);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) {
        // Millimetres 0 (no value), and 500..5563 varying per pixel and frame.
        const uint16_t v = (x + y) % 7 == 0 ? 0 : static_cast<uint16_t>(500 + 37 * x + 41 * y + i);
        mm.at(x, y) = v;
        png.at<uint16_t>(y, x) = static_cast<uint16_t>(v * 5);  // 5000 units per metre.
      }
    }
    f.depth_mm.push_back(mm);
    const std::string file = "depth/" + std::string(depth_stamps[i]) + ".png";
    cv::imwrite(f.dir + "/" + file, png);
    depth_txt += std::string(depth_stamps[i]) + " " + file + "\n";
  }
  for (int i = 0; i < 5; ++i) {
    const cv::Vec3b bgr(static_cast<uint8_t>(40 * i), 100, static_cast<uint8_t>(250 - 40 * i));
    f.color.push_back(bgr);
    cv::Mat image(48, 64, CV_8UC3, cv::Scalar(bgr[0], bgr[1], bgr[2]));
    const std::string file = "rgb/" + std::string(rgb_stamps[i]) + ".png";
    cv::imwrite(f.dir + "/" + file, image);
    rgb_txt += std::string(rgb_stamps[i]) + " " + file + "\n";
  }
  WriteText(f.dir + "/depth.txt", depth_txt);
  WriteText(f.dir + "/rgb.txt", rgb_txt);
  return f;
}

TEST(Tum, DepthToTheMillimetreAndColourByNearestStamp) {
  const TumFixture f = WriteTum("tum_ok");
  EXPECT_EQ(DetectFormat(f.dir).value_or(RecordingFormat::kOni), RecordingFormat::kTum);
  auto reader = OpenRecording(f.dir, RecordingFormat::kTum);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const RecordingInfo& info = (*reader)->info();
  EXPECT_EQ(info.frame_count, 4);
  // Default intrinsics scaled from 640x480 to 64x48.
  EXPECT_EQ(info.depth_lens.pinhole.width, 64);
  EXPECT_DOUBLE_EQ(info.depth_lens.pinhole.fx, 52.5);
  EXPECT_DOUBLE_EQ(info.depth_lens.pinhole.cx, (319.5 + 0.5) / 10 - 0.5);
  EXPECT_TRUE(info.color_from_depth.translation.isZero());
  // Expected partners: depth 0 -> rgb 0 (10 ms), 1 -> 1 (10 ms), 2 -> none
  // (rgb 2 is 35 ms away but is 1.7 ms from depth 3, which takes it), 3 -> 2.
  const int partner[] = {0, 1, -1, 2};
  const int64_t t0 = 1305031102175304000;
  int worst = 0;
  for (int i = 0; i < 4; ++i) {
    auto frame = (*reader)->Next();
    ASSERT_TRUE(frame.ok()) << frame.status();
    ASSERT_TRUE(frame->has_value());
    const RecordedFrame& r = **frame;
    EXPECT_EQ(r.index, i);
    const cv::Mat truth(48, 64, CV_16UC1, const_cast<uint16_t*>(f.depth_mm[i].data.data()));
    const int difference = MaxDifference(r.depth_mm, truth);
    worst = std::max(worst, difference);
    EXPECT_EQ(difference, 0) << "frame " << i;
    EXPECT_EQ(r.has_color(), partner[i] >= 0) << "frame " << i;
    if (partner[i] >= 0) {
      ASSERT_TRUE(r.color_rgb.has_value());
      const cv::Vec3b bgr = f.color[partner[i]];
      EXPECT_EQ(r.color_rgb->at(5, 5, 0), bgr[2]) << "frame " << i;
      EXPECT_EQ(r.color_rgb->at(5, 5, 2), bgr[0]) << "frame " << i;
    }
  }
  auto frame = (*reader)->Next();
  ASSERT_TRUE(frame.ok());
  EXPECT_FALSE(frame->has_value());
  std::printf("TUM depth: max difference %d mm; first stamp %lld ns\n", worst,
              static_cast<long long>(t0));

  // Imported: the take holds the same millimetres and the association.
  auto again = OpenRecording(f.dir, RecordingFormat::kTum);
  ASSERT_TRUE(again.ok());
  const std::string take_path = f.dir + "/take.mcap";
  auto report = ImportRecording(**again, take_path);
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->frames, 4);
  EXPECT_EQ(report->frames_with_color, 3);
  EXPECT_EQ(report->first_stamp_ns, t0);
  auto take = TakeReader::Open(take_path);
  ASSERT_TRUE(take.ok()) << take.status();
  auto depths = (*take)->ReadAll<v1::DepthImage>(SensorTopic("k0", "depth"));
  ASSERT_TRUE(depths.ok());
  ASSERT_EQ(depths->size(), 4u);
  for (int i = 0; i < 4; ++i) {
    auto decoded = DecodeDepth((*depths)[i].data());
    ASSERT_TRUE(decoded.ok());
    EXPECT_EQ(*decoded, f.depth_mm[i]) << "frame " << i;
    EXPECT_EQ((*depths)[i].device_stamp_ns(), t0 + i * 33'333'000 + (i == 3 ? 1'000 : 0))
        << "frame " << i;
  }
  const v1::SensorCalibration& c = (*take)->sensors().at("k0");
  EXPECT_DOUBLE_EQ(c.depth_intrinsics().fx_px(), 52.5);
  EXPECT_DOUBLE_EQ(c.depth_scale_m_per_unit(), 0.001);
}

TEST(Tum, IntrinsicsFileOverridesTheDefault) {
  const TumFixture f = WriteTum("tum_intrinsics");
  WriteText(f.dir + "/calib.txt",
            "# fx fy cx cy d0 d1 d2 d3 d4\n51.73 51.65 31.86 25.53 "
            "0.2624 -0.9531 -0.0054 0.0026 1.1633\n");
  RecordingOptions options;
  options.intrinsics_path = f.dir + "/calib.txt";
  auto reader = OpenRecording(f.dir, RecordingFormat::kTum, options);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const CameraIntrinsics& k = (*reader)->info().depth_lens.pinhole;
  EXPECT_DOUBLE_EQ(k.fx, 51.73);
  EXPECT_DOUBLE_EQ(k.k1, 0.2624);
  EXPECT_DOUBLE_EQ(k.p1, -0.0054);
  EXPECT_DOUBLE_EQ(k.k3, 1.1633);
}

TEST(Tum, BadFoldersAreClearErrors) {
  {
    const TumFixture f = WriteTum("tum_missing");
    fs::remove(f.dir + "/depth/1305031102.241970.png");
    auto reader = OpenRecording(f.dir, RecordingFormat::kTum);
    ASSERT_FALSE(reader.ok());
    EXPECT_EQ(reader.status().code(), absl::StatusCode::kNotFound);
    EXPECT_NE(reader.status().message().find("depth.txt line 6"), std::string::npos)
        << reader.status();
    EXPECT_NE(reader.status().message().find("1305031102.241970.png does not exist"),
              std::string::npos)
        << reader.status();
  }
  {
    const TumFixture f = WriteTum("tum_malformed");
    WriteText(f.dir + "/rgb.txt",
              "# ok\n1305031102.185304 rgb/1305031102.185304.png\nnot-a-stamp "
              "rgb/x.png\n");
    auto reader = OpenRecording(f.dir, RecordingFormat::kTum);
    ASSERT_FALSE(reader.ok());
    EXPECT_EQ(reader.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(reader.status().message().find("rgb.txt line 3"), std::string::npos)
        << reader.status();
  }
  {
    const TumFixture f = WriteTum("tum_escape");
    WriteText(f.dir + "/depth.txt", "1305031102.175304 ../../etc/passwd\n");
    auto reader = OpenRecording(f.dir, RecordingFormat::kTum);
    ASSERT_FALSE(reader.ok());
    EXPECT_NE(reader.status().message().find("not a path inside the folder"), std::string::npos);
  }
  {
    // A PNG whose header claims 100000 x 100000 pixels: refused before
    // anything that size is allocated.
    const TumFixture f = WriteTum("tum_hostile");
    auto bytes = ReadFileToString(f.dir + "/depth/1305031102.208637.png");
    ASSERT_TRUE(bytes.ok());
    std::string hostile = *bytes;
    const unsigned char size[8] = {0, 1, 0x86, 0xa0, 0, 1, 0x86, 0xa0};
    hostile.replace(16, 8, reinterpret_cast<const char*>(size), 8);
    ASSERT_TRUE(WriteFileAtomically(f.dir + "/depth/1305031102.208637.png", hostile).ok());
    // And a truncated one.
    ASSERT_TRUE(WriteFileAtomically(f.dir + "/depth/1305031102.241970.png",
                                    bytes->substr(0, bytes->size() / 2))
                    .ok());
    auto reader = OpenRecording(f.dir, RecordingFormat::kTum);
    ASSERT_TRUE(reader.ok()) << reader.status();
    ASSERT_TRUE((*reader)->Next().ok());
    auto second = (*reader)->Next();
    ASSERT_FALSE(second.ok());
    EXPECT_EQ(second.status().code(), absl::StatusCode::kDataLoss);
    EXPECT_NE(second.status().message().find("100000x100000"), std::string::npos)
        << second.status();
    auto third = (*reader)->Next();
    ASSERT_FALSE(third.ok());
    EXPECT_EQ(third.status().code(), absl::StatusCode::kDataLoss) << third.status();
    // The import of such a folder fails and leaves no take.
    auto again = OpenRecording(f.dir, RecordingFormat::kTum);
    ASSERT_TRUE(again.ok());
    EXPECT_FALSE(ImportRecording(**again, f.dir + "/take.mcap").ok());
    EXPECT_FALSE(fs::exists(f.dir + "/take.mcap"));
  }
  EXPECT_EQ(DetectFormat("/nonexistent/folder").status().code(), absl::StatusCode::kNotFound);
}

// ---------------------------------------------------------------- OpenNI2

// In a child process (the Dummy driver's frame thread may crash once its
// streams are stopped, so the fixture is made where that cannot take the
// test down): records `frames` depth (and colour) frames of OpenNI2's
// "Dummy" device into `path` with openni::Recorder, and writes the depth
// frames it delivered to `path`.raw (width, height, then uint16 values per
// frame). The child exits without closing the device.
absl::StatusOr<std::vector<DepthImageMm>> RecordDummy(const std::string& path, int frames) {
  const pid_t pid = ::fork();
  if (pid < 0) return absl::UnavailableError("fork failed");
  if (pid == 0) {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) ::_exit(3);
    openni::Device device;
    if (device.open("Dummy") != openni::STATUS_OK) ::_exit(4);
    openni::VideoStream depth, color;
    if (depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) ::_exit(5);
    const bool has_color = color.create(device, openni::SENSOR_COLOR) == openni::STATUS_OK;
    openni::Recorder recorder;
    if (recorder.create(path.c_str()) != openni::STATUS_OK ||
        recorder.attach(depth, false) != openni::STATUS_OK ||
        (has_color && recorder.attach(color, true) != openni::STATUS_OK)) {
      ::_exit(6);
    }
    depth.start();
    if (has_color) color.start();
    recorder.start();
    std::ofstream raw(path + ".raw", std::ios::binary);
    openni::VideoStream* streams[1] = {&depth};
    for (int i = 0; i < frames; ++i) {
      int ready = -1;
      openni::VideoFrameRef frame;
      if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, 2000) != openni::STATUS_OK ||
          depth.readFrame(&frame) != openni::STATUS_OK) {
        ::_exit(7);
      }
      const int32_t size[2] = {frame.getWidth(), frame.getHeight()};
      raw.write(reinterpret_cast<const char*>(size), sizeof(size));
      const auto* base = static_cast<const char*>(frame.getData());
      for (int y = 0; y < size[1]; ++y) {
        raw.write(base + static_cast<size_t>(y) * frame.getStrideInBytes(),
                  sizeof(uint16_t) * size[0]);
      }
    }
    raw.close();
    recorder.stop();
    recorder.destroy();
    ::_exit(raw ? 0 : 8);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return absl::UnavailableError(
        absl::StrCat("recording from OpenNI2's Dummy device failed (child ",
                     WIFEXITED(status) ? absl::StrCat("exit code ", WEXITSTATUS(status))
                                       : absl::StrCat("signal ", WTERMSIG(status)),
                     "; 4: no Dummy device)"));
  }
  auto raw = ReadFileToString(path + ".raw");
  if (!raw.ok()) return raw.status();
  std::vector<DepthImageMm> delivered;
  size_t at = 0;
  while (at + 8 <= raw->size()) {
    int32_t size[2];
    std::memcpy(size, raw->data() + at, sizeof(size));
    at += sizeof(size);
    const size_t bytes = sizeof(uint16_t) * static_cast<size_t>(size[0]) * size[1];
    if (size[0] <= 0 || size[1] <= 0 || at + bytes > raw->size()) break;
    DepthImageMm mm(size[0], size[1]);
    std::memcpy(mm.data.data(), raw->data() + at, bytes);
    at += bytes;
    delivered.push_back(std::move(mm));
  }
  if (delivered.empty()) return absl::UnavailableError("the Dummy device delivered no frame");
  return delivered;
}

TEST(Oni, RecordingOfTheDummyDevice) {
  const std::string dir = testing::MakeTempDir("oni");
  const std::string path = dir + "/dummy.oni";
  auto delivered = RecordDummy(path, 10);
  if (!delivered.ok()) {
    GTEST_SKIP() << "\n*** SKIPPED: no OpenNI2 device to record a .oni fixture from ("
                 << delivered.status() << ") ***";
  }
  ASSERT_TRUE(fs::exists(path));
  EXPECT_EQ(DetectFormat(path).value_or(RecordingFormat::kTum), RecordingFormat::kOni);
  RecordingOptions options;
  options.oni_frame_timeout_s = 2.0;
  auto reader = OpenRecording(path, RecordingFormat::kOni, options);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const RecordingInfo& info = (*reader)->info();
  EXPECT_EQ(info.depth_lens.pinhole.width, delivered->front().width);
  EXPECT_EQ(info.depth_lens.pinhole.height, delivered->front().height);
  EXPECT_GE(info.frame_count, 1);
  EXPECT_LE(info.frame_count, 10);
  std::printf("recorded %zu Dummy frames of %dx%d; the file lists %lld depth frames\n",
              delivered->size(), delivered->front().width, delivered->front().height,
              static_cast<long long>(info.frame_count));
  auto frame = (*reader)->Next();
  if (!frame.ok() && frame.status().code() == absl::StatusCode::kDeadlineExceeded) {
    GTEST_SKIP() << "\n*** SKIPPED (frames): this OpenNI2 build's file player opens the "
                    "recording (sizes and frame count checked) but delivers no frame: "
                 << frame.status() << " ***";
  }
  ASSERT_TRUE(frame.ok()) << frame.status();
  ASSERT_TRUE(frame->has_value());
  EXPECT_EQ((*frame)->depth_mm.width, delivered->front().width);
  bool matches_one = false;
  for (const DepthImageMm& d : *delivered) matches_one |= d == (*frame)->depth_mm;
  EXPECT_TRUE(matches_one) << "the played depth equals none of the recorded frames";
}

TEST(Oni, ForeignFileIsAnError) {
  const std::string dir = testing::MakeTempDir("oni_bad");
  ASSERT_TRUE(WriteFileAtomically(dir + "/junk.oni", std::string(3000, 'z')).ok());
  auto reader = OpenRecording(dir + "/junk.oni", RecordingFormat::kOni);
  ASSERT_FALSE(reader.ok());
  EXPECT_NE(reader.status().message().find("junk.oni"), std::string::npos) << reader.status();
}

// A real Kinect v2 depth sequence of ../shared/data/rgbd-seq: a folder of
// 16-bit PNGs in millimetres with its lens in meta.json, read as a
// depth-only recording with the depth as stored and the lens of meta.json;
// at the pixels of the Kinect SDK's joints the depth lies just in front of
// the joints, as the data's README says.
TEST(DepthFolder, ARealKinectV2SequenceWithTheLensOfItsMeta) {
  const std::string dir = testing::TestDataPath("rgbd-seq/utd-kinect2-a01-s1-t1");
  REENACT_REQUIRE_TEST_FILE(dir + "/meta.json");
  EXPECT_EQ(DetectFormat(dir).value_or(RecordingFormat::kTum), RecordingFormat::kDepthFolder);
  auto reader = OpenRecording(dir, RecordingFormat::kDepthFolder);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const RecordingInfo& info = (*reader)->info();
  auto meta_text = ReadFileToString(dir + "/meta.json");
  ASSERT_TRUE(meta_text.ok());
  const nlohmann::json meta = nlohmann::json::parse(*meta_text);
  EXPECT_EQ(info.frame_count, static_cast<int64_t>(meta["frames"].size()));
  EXPECT_FALSE(info.has_color);
  EXPECT_DOUBLE_EQ(info.nominal_fps, 30.0);
  EXPECT_EQ(info.depth_lens.pinhole.width, 512);
  EXPECT_EQ(info.depth_lens.pinhole.height, 424);
  EXPECT_DOUBLE_EQ(info.depth_lens.pinhole.fx, meta["intrinsics"][0].get<double>());
  EXPECT_DOUBLE_EQ(info.depth_lens.pinhole.cy, meta["intrinsics"][3].get<double>());
  std::vector<double> gaps_m;
  int64_t frames = 0;
  int worst = 0;
  while (true) {
    auto frame = (*reader)->Next();
    ASSERT_TRUE(frame.ok()) << frame.status();
    if (!frame->has_value()) break;
    const RecordedFrame& f = **frame;
    EXPECT_EQ(f.stamp_ns, static_cast<int64_t>(std::llround(frames * 1e9 / 30.0)));
    EXPECT_FALSE(f.has_color());
    const nlohmann::json& entry = meta["frames"][frames];
    worst = std::max(
        worst, MaxDifference(f.depth_mm, ReadPng16(dir + "/" + entry["depth"].get<std::string>())));
    for (const auto& [name, px] : entry["joints_px"].items()) {
      const int u = static_cast<int>(std::lround(px[0].get<double>()));
      const int v = static_cast<int>(std::lround(px[1].get<double>()));
      if (u < 0 || v < 0 || u >= f.depth_mm.width || v >= f.depth_mm.height) continue;
      const uint16_t mm = f.depth_mm.at(u, v);
      if (mm == 0) continue;
      gaps_m.push_back(mm * 1e-3 - entry["joints_m"][name][2].get<double>());
    }
    ++frames;
  }
  EXPECT_EQ(frames, info.frame_count);
  EXPECT_EQ(worst, 0) << "max |depth - the PNG| in mm";
  ASSERT_GT(gaps_m.size(), 100u);
  std::sort(gaps_m.begin(), gaps_m.end());
  const double median = gaps_m[gaps_m.size() / 2];
  std::printf(
      "rgbd-seq a01 s1: %lld frames, depth minus the SDK joint's z at its pixel: median "
      "%.3f m over %zu joints\n",
      static_cast<long long>(frames), median, gaps_m.size());
  // Joints lie inside the body: the surface 2-17 cm in front of them.
  EXPECT_LT(median, 0.0);
  EXPECT_GT(median, -0.15);
}

// A folder of PNGs written here: frames ordered by the number in their
// names, depth in another unit, the lens from a file, the frame rate given;
// and what is refused.
TEST(DepthFolder, OrderUnitsLensAndBadFolders) {
  const std::string dir = testing::MakeTempDir("depth_png");
  // 10000 units per metre; frame k holds 1000 + k mm, written out of order.
  for (int k : {10, 2, 1}) {
    cv::Mat png(4, 6, CV_16UC1, cv::Scalar((1000 + k) * 10 + 4));
    png.at<uint16_t>(0, 0) = 0;
    cv::imwrite(absl::StrCat(dir, "/f", k, ".png"), png);
  }
  WriteText(dir + "/lens.txt", "# fx fy cx cy\n5.5 5.25 2.5 1.5\n");
  RecordingOptions options;
  options.depth_units_per_m = 10000;
  options.fps = 10;
  options.intrinsics_path = dir + "/lens.txt";
  EXPECT_EQ(DetectFormat(dir).value_or(RecordingFormat::kTum), RecordingFormat::kDepthFolder);
  auto reader = OpenRecording(dir, RecordingFormat::kDepthFolder, options);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_DOUBLE_EQ((*reader)->info().depth_lens.pinhole.fy, 5.25);
  EXPECT_EQ((*reader)->info().depth_lens.pinhole.width, 6);
  std::vector<int> mm;
  std::vector<int64_t> stamps;
  while (true) {
    auto frame = (*reader)->Next();
    ASSERT_TRUE(frame.ok()) << frame.status();
    if (!frame->has_value()) break;
    EXPECT_EQ((*frame)->depth_mm.at(0, 0), 0) << "no value stays no value";
    mm.push_back((*frame)->depth_mm.at(3, 2));
    stamps.push_back((*frame)->stamp_ns);
  }
  EXPECT_EQ(mm, (std::vector<int>{1001, 1002, 1010}));  // 10014 units: 1001.4 mm.
  EXPECT_EQ(stamps, (std::vector<int64_t>{0, 100'000'000, 200'000'000}));

  // The lens as JSON, as rgbd-seq's meta.json states it.
  WriteText(dir + "/lens.json", R"({"intrinsics": [5.5, 5.25, 2.5, 1.5]})");
  options.intrinsics_path = dir + "/lens.json";
  EXPECT_TRUE(OpenRecording(dir, RecordingFormat::kDepthFolder, options).ok());

  // No lens: refused, asking for one.
  auto no_lens = OpenRecording(dir, RecordingFormat::kDepthFolder);
  ASSERT_FALSE(no_lens.ok());
  EXPECT_EQ(no_lens.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(no_lens.status().message().find("--intrinsics"), std::string::npos) << no_lens.status();
  // A lens file of three numbers, a bad unit.
  WriteText(dir + "/short.txt", "5 5 2\n");
  options.intrinsics_path = dir + "/short.txt";
  EXPECT_EQ(OpenRecording(dir, RecordingFormat::kDepthFolder, options).status().code(),
            absl::StatusCode::kInvalidArgument);
  options.intrinsics_path = dir + "/lens.txt";
  options.depth_units_per_m = -5;
  EXPECT_EQ(OpenRecording(dir, RecordingFormat::kDepthFolder, options).status().code(),
            absl::StatusCode::kInvalidArgument);
  options.depth_units_per_m = 0;

  // A frame of another size and a truncated frame: DataLoss naming the file.
  cv::imwrite(dir + "/f11.png", cv::Mat(5, 6, CV_16UC1, cv::Scalar(1000)));
  auto bytes = ReadFileToString(dir + "/f2.png");
  ASSERT_TRUE(bytes.ok());
  ASSERT_TRUE(WriteFileAtomically(dir + "/f12.png", bytes->substr(0, bytes->size() / 2)).ok());
  auto damaged = OpenRecording(dir, RecordingFormat::kDepthFolder, options);
  ASSERT_TRUE(damaged.ok()) << damaged.status();
  std::vector<std::string> errors;
  for (int i = 0; i < 6; ++i) {
    auto frame = (*damaged)->Next();
    if (!frame.ok()) {
      EXPECT_EQ(frame.status().code(), absl::StatusCode::kDataLoss);
      errors.emplace_back(frame.status().message());
    }
  }
  ASSERT_EQ(errors.size(), 2u);
  EXPECT_NE(errors[0].find("f11.png: 6x5 px"), std::string::npos) << errors[0];
  EXPECT_NE(errors[1].find("f12.png"), std::string::npos) << errors[1];

  // An empty frames/ folder.
  const std::string empty = testing::MakeTempDir("depth_png_empty");
  fs::create_directories(empty + "/frames");
  EXPECT_EQ(DetectFormat(empty).value_or(RecordingFormat::kTum), RecordingFormat::kDepthFolder);
  auto nothing = OpenRecording(empty, RecordingFormat::kDepthFolder, options);
  ASSERT_FALSE(nothing.ok());
  EXPECT_NE(nothing.status().message().find("holds no *.png"), std::string::npos)
      << nothing.status();
}

TEST(Formats, NamesAndDetection) {
  EXPECT_EQ(ParseFormat("azure-mkv").value_or(RecordingFormat::kTum), RecordingFormat::kAzureMkv);
  EXPECT_EQ(ParseFormat("bag").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ParseFormat("depth-png").value_or(RecordingFormat::kTum),
            RecordingFormat::kDepthFolder);
  EXPECT_EQ(FormatName(RecordingFormat::kDepthFolder), "depth-png");
  const std::string dir = testing::MakeTempDir("formats");
  WriteText(dir + "/a.MKV", "x");
  WriteText(dir + "/b.txt", "x");
  EXPECT_EQ(DetectFormat(dir + "/a.MKV").value_or(RecordingFormat::kTum),
            RecordingFormat::kAzureMkv);
  EXPECT_EQ(DetectFormat(dir + "/b.txt").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(DetectFormat(dir).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::recordings
