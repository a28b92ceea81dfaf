// Interoperability of reenactments: the .glb export must pass the Khronos
// glTF-Validator (tests/js/check_gltf.mjs, npm gltf-validator) with zero
// errors, the BVH export must read in three.js's BVHLoader with continuous
// channels and no zero-length bone (tests/js/check_bvh.mjs, npm three), and
// reenactment files must open in an independent MCAP reader
// (tests/js/check_take.mjs, @mcap/core).
//
// Setup (once per checkout; deploy/setup-debian.sh does it for CI):
//   npm ci --prefix tests/js   or   npm install --prefix tests/js
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <sys/wait.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/body/motion.h"
#include "common/io/body_reenactment_motion.h"
#include "common/io/gltf_export.h"
#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

using testing::MakeTestReenactment;
using testing::TestReenactmentOptions;

const std::string kJsDir = std::string(REENACT_SOURCE_DIR) + "/tests/js";

// Skips the test (loudly) when node or the npm package `package` is missing.
#define REQUIRE_NODE_PACKAGE(package)                                                     \
  do {                                                                                    \
    if (std::system("node --version > /dev/null 2>&1") != 0) {                            \
      GTEST_SKIP() << "\n*** SKIPPED: node is not installed; the independent " << package \
                   << " check did not run. ***";                                          \
    }                                                                                     \
    if (!std::filesystem::exists(kJsDir + "/node_modules/" + package)) {                  \
      GTEST_SKIP() << "\n*** SKIPPED: " << kJsDir << "/node_modules/" << package          \
                   << " is missing; run `npm ci --prefix tests/js` (or "                  \
                      "`npm install --prefix tests/js`). ***";                            \
    }                                                                                     \
  } while (false)

// Runs `node tests/js/<script> <args...>` and parses the JSON it prints.
nlohmann::json RunNode(const std::string& script, const std::vector<std::string>& args,
                       int* exit_code) {
  std::string command = "node '" + kJsDir + "/" + script + "'";
  for (const std::string& arg : args) command += " '" + arg + "'";
  command += " 2>&1";
  std::FILE* pipe = ::popen(command.c_str(), "r");
  EXPECT_NE(pipe, nullptr) << command;
  if (pipe == nullptr) return {};
  std::string output;
  char buffer[4096];
  for (size_t n; (n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0;) output.append(buffer, n);
  const int status = ::pclose(pipe);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  const nlohmann::json result = nlohmann::json::parse(output, nullptr, false);
  EXPECT_FALSE(result.is_discarded()) << script << " printed no JSON:\n" << output;
  return result;
}

nlohmann::json RunNode(const std::string& script, const std::string& path, int* exit_code) {
  return RunNode(script, std::vector<std::string>{path}, exit_code);
}

// Exports `data` to `path` and validates it; returns the validator's report.
nlohmann::json ExportAndValidate(const ReenactmentData& data, const std::string& path,
                                 const GltfExportOptions& options = {}) {
  const absl::Status written = WriteReenactmentGlb(testing::ToPlain(data), path, options);
  EXPECT_TRUE(written.ok()) << written;
  int exit_code = -1;
  nlohmann::json report = RunNode("check_gltf.mjs", path, &exit_code);
  EXPECT_EQ(exit_code, report.value("num_errors", -1) == 0 ? 0 : 1) << report.dump(2);
  return report;
}

TEST(GltfValidator, TexturedExportHasNoErrorsOrWarnings) {
  REQUIRE_NODE_PACKAGE("gltf-validator");
  const std::string dir = testing::MakeTempDir("gltf_validator");
  TestReenactmentOptions options;
  options.parts = 15;
  options.frames = 90;
  options.texture_px = 64;
  const nlohmann::json report =
      ExportAndValidate(MakeTestReenactment(options), dir + "/textured.glb");
  ASSERT_TRUE(report.contains("num_errors")) << report.dump(2);
  EXPECT_EQ(report["num_errors"].get<int>(), 0) << report["issues"].dump(2);
  EXPECT_EQ(report["num_warnings"].get<int>(), 0) << report["issues"].dump(2);
  EXPECT_EQ(report["mime_type"], "model/gltf-binary");
  EXPECT_EQ(report["info"]["animationCount"].get<int>(), 1);
  EXPECT_EQ(report["info"]["materialCount"].get<int>(), 15);
  EXPECT_EQ(report["info"]["drawCallCount"].get<int>(), 15);
  EXPECT_TRUE(report["info"]["hasTextures"].get<bool>());
}

TEST(GltfValidator, HiddenPartsPlainMaterialsAndMeshlessPartsHaveNoErrors) {
  REQUIRE_NODE_PACKAGE("gltf-validator");
  const std::string dir = testing::MakeTempDir("gltf_validator_edge");
  TestReenactmentOptions options;
  options.frames = 20;
  options.part1_invalid_before = 20;  // Never posed.
  ReenactmentData data = MakeTestReenactment(options);
  for (int f = 5; f < 9; ++f) data.frames[f].mutable_parts(2)->set_valid(false);
  data.parts[0].clear_triangle_indices();  // A node without a mesh.
  const nlohmann::json steps = ExportAndValidate(data, dir + "/steps.glb");
  EXPECT_EQ(steps.value("num_errors", -1), 0) << steps.dump(2);

  GltfExportOptions plain;
  plain.textures = false;
  plain.unlit = false;
  const nlohmann::json untextured = ExportAndValidate(data, dir + "/plain.glb", plain);
  EXPECT_EQ(untextured.value("num_errors", -1), 0) << untextured.dump(2);

  // One frame: a zero-length animation.
  options.frames = 1;
  options.keyframes = 1;
  options.part1_invalid_before = 0;
  const nlohmann::json single = ExportAndValidate(MakeTestReenactment(options), dir + "/one.glb");
  EXPECT_EQ(single.value("num_errors", -1), 0) << single.dump(2);
}

TEST(GltfValidator, SkinnedBodyExportHasNoErrorsOrWarnings) {
  REQUIRE_NODE_PACKAGE("gltf-validator");
  const std::string dir = testing::MakeTempDir("gltf_validator_body");
  const nlohmann::json report =
      ExportAndValidate(testing::MakeTestBodyReenactment(30), dir + "/body.glb");
  ASSERT_TRUE(report.contains("num_errors")) << report.dump(2);
  EXPECT_EQ(report["num_errors"].get<int>(), 0) << report["issues"].dump(2);
  EXPECT_EQ(report["num_warnings"].get<int>(), 0) << report["issues"].dump(2);
  EXPECT_EQ(report["info"]["animationCount"].get<int>(), 1);
  EXPECT_TRUE(report["info"]["hasSkins"].get<bool>());
  EXPECT_EQ(report["info"]["drawCallCount"].get<int>(), 1);
  EXPECT_EQ(report["info"]["maxInfluences"].get<int>(), 4);
  EXPECT_TRUE(report["info"]["hasTextures"].get<bool>());
  std::printf("body .glb: %lld bytes, %d infos, %d hints\n",
              static_cast<long long>(std::filesystem::file_size(dir + "/body.glb")),
              report["num_infos"].get<int>(), report["num_hints"].get<int>());

  // Without textures, and a single frame.
  GltfExportOptions plain;
  plain.textures = false;
  const nlohmann::json untextured =
      ExportAndValidate(testing::MakeTestBodyReenactment(1), dir + "/plain.glb", plain);
  EXPECT_EQ(untextured.value("num_errors", -1), 0) << untextured.dump(2);
  EXPECT_EQ(untextured.value("num_warnings", -1), 0) << untextured.dump(2);
}

// The checker itself must be able to fail: a broken export is reported.
TEST(GltfValidator, ReportsErrorsInADamagedFile) {
  REQUIRE_NODE_PACKAGE("gltf-validator");
  const std::string dir = testing::MakeTempDir("gltf_validator_bad");
  const std::string path = dir + "/bad.glb";
  ASSERT_TRUE(WriteReenactmentGlb(testing::ToPlain(MakeTestReenactment()), path).ok());
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  // Same length, so the GLB container stays intact: an unknown
  // interpolation and an unknown attribute semantic.
  const std::vector<std::pair<std::string, std::string>> edits = {{"\"LINEAR\"", "\"LINEAX\""},
                                                                  {"\"NORMAL\"", "\"NORMAX\""}};
  for (const auto& [from, to] : edits) {
    const size_t at = bytes->find(from);
    ASSERT_NE(at, std::string::npos) << from;
    bytes->replace(at, from.size(), to);
  }
  ASSERT_TRUE(WriteFileAtomically(path, *bytes).ok());
  int exit_code = -1;
  const nlohmann::json report = RunNode("check_gltf.mjs", path, &exit_code);
  EXPECT_EQ(exit_code, 1);
  EXPECT_GE(report.value("num_errors", 0), 1) << report.dump(2);
}

// The fitted skeleton as BVH, read by three.js's BVHLoader (check_bvh.mjs):
// every joint, an End Site on each of the 7 leaves instead of a zero-length
// bone, channels continuous from frame to frame (no jump between equivalent
// Euler angles, so a linear blend between frames turns the short way), and
// a person's height at the reader's default scale in metres, the same
// figure read as centimetres.
TEST(BvhLoader, BodySkeletonIsContinuousWithEndSitesInMetresOrCentimetres) {
  REQUIRE_NODE_PACKAGE("three");
  const std::string dir = testing::MakeTempDir("bvh_loader");
  // A performer who spins once and a quarter (15 degrees a frame) while every
  // joint turns steadily about its own axis: rotations that cross every
  // Euler branch cut.
  ReenactmentData data = testing::MakeTestBodyReenactment(30);
  for (int f = 0; f < 30; ++f) {
    v1::BodyPose* message = data.frames[f].mutable_body();
    auto pose = BodyPoseFromProto(*message);
    ASSERT_TRUE(pose.ok()) << pose.status();
    pose->local_rotation[0] = Eigen::AngleAxisd(f * 15.0 * M_PI / 180.0, Eigen::Vector3d::UnitY());
    for (int j = 1; j < body::kNumKinectV2Joints; ++j) {
      pose->local_rotation[j] = Eigen::AngleAxisd(
          0.12 * f, Eigen::Vector3d(std::sin(j), std::cos(2.0 * j), 0.5).normalized());
    }
    *message = BodyPoseToProto(*pose);
  }
  const absl::StatusOr<body::Motion> motion = BodyReenactmentMotion(testing::ToPlain(data));
  ASSERT_TRUE(motion.ok()) << motion.status();
  double height_m[2] = {0.0, 0.0};
  int k = 0;
  for (const auto& [unit, metres_per_unit] :
       std::vector<std::pair<std::string, double>>{{"m", 1.0}, {"cm", 0.01}}) {
    const std::string path = dir + "/body_" + unit + ".bvh";
    body::BvhWriteOptions options;
    options.metres_per_unit = metres_per_unit;
    ASSERT_TRUE(body::WriteBvh(*motion, path, options).ok());
    int exit_code = -1;
    const nlohmann::json report = RunNode(
        "check_bvh.mjs", {path, "--metres-per-unit", absl::StrCat(metres_per_unit)}, &exit_code);
    ASSERT_TRUE(report.contains("bones")) << report.dump(2);
    EXPECT_EQ(exit_code, 0) << report.dump(2);
    EXPECT_EQ(report["bones"].get<int>(), body::kNumKinectV2Joints);
    EXPECT_EQ(report["end_sites"].get<int>(), 7);
    EXPECT_EQ(report["frames"].get<int>(), 30);
    EXPECT_TRUE(report["zero_length_bones"].empty()) << report["zero_length_bones"].dump();
    EXPECT_LE(report["excess_jump_deg"].get<double>(), 1.0);
    EXPECT_LE(report["max_blend_error_deg"].get<double>(), 5.0);
    height_m[k++] = report["height_m"].get<double>();
    std::printf(
        "BVH in %s, read by BVHLoader: %.3f m tall, excess jump %.3f deg, blend error %.2f deg, "
        "%d channel changes over 90 deg\n",
        unit.c_str(), report["height_m"].get<double>(), report["excess_jump_deg"].get<double>(),
        report["max_blend_error_deg"].get<double>(), report["channel_jumps_over_90"].get<int>());
  }
  // Frame 0 is the rest pose: the test body's stature.
  EXPECT_GT(height_m[0], 1.5);
  EXPECT_LT(height_m[0], 2.0);
  EXPECT_NEAR(height_m[1], height_m[0], 1e-3);

  // The checker can fail: one channel turned by a whole turn in one frame
  // (the same rotation, a jump a player would blend through).
  auto text = ReadFileToString(dir + "/body_m.bvh");
  ASSERT_TRUE(text.ok());
  const size_t motion_at = text->find("Frame Time:");
  ASSERT_NE(motion_at, std::string::npos);
  size_t line = motion_at;
  for (int skip = 0; skip < 11; ++skip) line = text->find('\n', line) + 1;
  // The fourth number of frame 10: the root's first rotation channel.
  size_t at = line;
  for (int skip = 0; skip < 3; ++skip) at = text->find(' ', at) + 1;
  const size_t end = text->find(' ', at);
  const double value = std::stod(text->substr(at, end - at));
  text->replace(at, end - at, absl::StrCat(value + 360.0));
  ASSERT_TRUE(WriteFileAtomically(dir + "/jump.bvh", *text).ok());
  int exit_code = -1;
  const nlohmann::json jump = RunNode("check_bvh.mjs", {dir + "/jump.bvh"}, &exit_code);
  EXPECT_EQ(exit_code, 1) << jump.dump(2);
  EXPECT_NEAR(jump.value("excess_jump_deg", 0.0), 360.0, 1.0) << jump.dump(2);
}

// Writes `data` to `path` and reads it with @mcap/core (check_take.mjs):
// exit status 0 and no problems; returns the report.
nlohmann::json WriteAndReadWithMcapCore(const ReenactmentData& data, const std::string& path) {
  EXPECT_TRUE(WriteReenactmentFile(data, path).ok());
  int exit_code = -1;
  nlohmann::json result = RunNode("check_take.mjs", path, &exit_code);
  EXPECT_EQ(exit_code, 0) << result.dump(2);
  EXPECT_TRUE(result.value("problems", nlohmann::json::array()).empty()) << result.dump(2);
  return result;
}

TEST(ReenactmentMcapInterop, IndependentReaderSeesEveryChannel) {
  REQUIRE_NODE_PACKAGE("@mcap/core");
  const std::string path = testing::MakeTempDir("reen_interop") + "/r.reen";
  TestReenactmentOptions options;
  options.frames = 30;
  options.keyframes = 4;
  const nlohmann::json result = WriteAndReadWithMcapCore(MakeTestReenactment(options), path);
  ASSERT_TRUE(result.contains("counts")) << result.dump(2);
  EXPECT_EQ(result["counts"][std::string(kReenactmentInfoTopic)].get<int>(), 1);
  EXPECT_EQ(result["counts"][std::string(kReenactmentPartMeshTopic)].get<int>(), 3);
  EXPECT_EQ(result["counts"][std::string(kReenactmentFrameTopic)].get<int>(), 30);
  EXPECT_EQ(result["counts"][std::string(kReenactmentKeyframeTopic)].get<int>(), 4);
  for (const auto& channel : result["channels"]) {
    EXPECT_EQ(channel["schema_encoding"], "protobuf");
    EXPECT_GT(channel["schema_bytes"].get<int>(), 0);
  }
}

TEST(ReenactmentMcapInterop, IndependentReaderSeesTheBodyMesh) {
  REQUIRE_NODE_PACKAGE("@mcap/core");
  const std::string path = testing::MakeTempDir("reen_interop_body") + "/body.reen";
  const nlohmann::json result =
      WriteAndReadWithMcapCore(testing::MakeTestBodyReenactment(12), path);
  ASSERT_TRUE(result.contains("counts")) << result.dump(2);
  EXPECT_EQ(result["counts"][std::string(kReenactmentInfoTopic)].get<int>(), 1);
  EXPECT_EQ(result["counts"][std::string(kReenactmentBodyMeshTopic)].get<int>(), 1);
  EXPECT_EQ(result["counts"][std::string(kReenactmentFrameTopic)].get<int>(), 12);
  EXPECT_FALSE(result["counts"].contains(std::string(kReenactmentPartMeshTopic)));
}

}  // namespace
}  // namespace reenact
