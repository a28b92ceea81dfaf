// One take split across several workers, end to end over loopback: the real
// reenact-server with no workers of its own (--workers none), two real
// reenact-worker --server processes started from folders of their own, a
// synthetic 2-sensor take played in by the real reenactd. The same take is
// reconstructed by the body method twice: whole (one worker), and with
// `reenact jobs submit --segments 3` (prepare, three segments leased to both
// workers at once, stitch). Checked:
//   * the segmented result equals the whole one within the tolerances the
//     scale-out promises: against the ground truth, MPJPE and surface within
//     1 mm and PSNR90 within 0.2 dB of the whole result's (`reenact eval`);
//     the two fits' direct differences are reported (see below);
//   * `reenact jobs show --json` lists every part SUCCEEDED with the worker
//     that ran it, and the segments ran on both workers.
// A second test does the same with rigid-carved in two segments, which must
// give the whole job's reenactment (rigid_carved.h).
// The motion (CMU 131_03, a hop) and the body's shape (random) are not the
// demo's. PRE_TEST: synthesis and the novel view need an (offscreen) GL
// context.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/base/subprocess.h"
#include "common/io/body_reenactment.h"
#include "common/io/proto_convert.h"
#include "common/io/reenactment_convert.h"
#include "common/io/reenactment_file.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using testing::Bin;
using testing::CommandResult;
using testing::ReadText;
using testing::RunCommand;

class SegmentedJobEndToEnd : public ::testing::Test {
 protected:
  void SetUp() override {
    clip_ = reenact::testing::TestDataPath("mocap/cmu/131_03.bvh");
    if (!fs::exists(clip_)) GTEST_SKIP() << "no CMU clip at " << clip_;
    dir_ =
        (fs::temp_directory_path() / absl::StrCat("reenact_segmented_e2e_", ::getpid())).string();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    for (auto& worker : workers_) {
      (void)worker->Signal(SIGTERM);
      (void)worker->Wait(20);
    }
    if (server_ != nullptr) {
      (void)server_->Signal(SIGTERM);
      (void)server_->Wait(20);
    }
    if (!dir_.empty() && std::getenv("REENACT_KEEP_TEST_OUTPUT") == nullptr) {
      fs::remove_all(dir_);
    }
  }

  std::unique_ptr<Subprocess> Start(const std::string& name, const std::vector<std::string>& argv,
                                    const std::string& working_dir = "") {
    SubprocessOptions options;
    options.stdout_path = dir_ + "/" + name + ".out";
    options.stderr_path = dir_ + "/" + name + ".err";
    options.working_dir = working_dir;
    auto child = Subprocess::Start(argv, options);
    EXPECT_TRUE(child.ok()) << child.status();
    return child.ok() ? std::move(*child) : nullptr;
  }

  // The server's reenactment file of `id`.
  std::string ReenactmentFile(const std::string& id) const {
    for (const auto& entry : fs::recursive_directory_iterator(dir_ + "/data")) {
      if (entry.is_regular_file() && absl::StartsWith(entry.path().filename().string(), id) &&
          entry.path().extension() != ".glb") {
        return entry.path().string();
      }
    }
    return "";
  }

  nlohmann::json Eval(const std::string& reenactment_id) {
    CommandResult eval = RunCommand(dir_, "eval-" + reenactment_id,
                                    {Bin("reenact"), "eval", "--server", address_, "--reenactment",
                                     reenactment_id, "--take", dir_ + "/source.mcap", "--json"});
    EXPECT_EQ(eval.exit_code, 0) << eval.err;
    auto figures = nlohmann::json::parse(eval.out, nullptr, false);
    EXPECT_TRUE(figures.is_object()) << eval.out;
    return figures;
  }

  // Synthesises `seconds` of the clip (2 sensors, 15 fps, `width` x
  // `height` colour, a random body), starts the server with no workers of
  // its own and two workers from folders of their own, plays the take in
  // with reenactd and returns its id (empty after a failure or a skip).
  std::string StartWithTake(double seconds, int width, int height) {
    synth::SynthOptions options;
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = clip_;
    options.body = "procedural";
    options.shape = "random:23";
    options.num_sensors = 2;
    options.seconds = seconds;
    options.fps = 15.0;
    options.color_width = width;
    options.color_height = height;
    auto summary = synth::SynthesizeTake(options, dir_ + "/source.mcap");
    if (!summary.ok() && summary.status().code() == absl::StatusCode::kUnavailable) {
      skipped_ = std::string(summary.status().message());
      return "";
    }
    EXPECT_TRUE(summary.ok()) << summary.status();
    if (!summary.ok()) return "";
    server_ =
        Start("server", {Bin("reenact-server"), "--data", dir_ + "/data", "--listen", "127.0.0.1:0",
                         "--port-file", dir_ + "/server.port", "--workers", "none"});
    if (server_ == nullptr) return "";
    for (int i = 0; i < 2400 && address_.empty(); ++i) {  // Up to 2 min under load.
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      const std::string text = ReadText(dir_ + "/server.port");
      if (const auto nl = text.find('\n'); nl != std::string::npos) address_ = text.substr(0, nl);
    }
    EXPECT_FALSE(address_.empty()) << ReadText(dir_ + "/server.err");
    if (address_.empty()) return "";
    for (const char* name : {"worker-a", "worker-b"}) {
      const std::string home = dir_ + "/" + name;
      fs::create_directories(home + "/scratch");
      workers_.push_back(Start(name,
                               {Bin("reenact-worker"), "--server", address_, "--loop", "--name",
                                name, "--scratch", home + "/scratch"},
                               home));
      if (workers_.back() == nullptr) return "";
    }
    const CommandResult daemon = RunCommand(
        dir_, "reenactd",
        {Bin("reenactd"), "--server", address_, "--source", "playback:" + dir_ + "/source.mcap",
         "--fast", "--once", "--take-name", "segmented", "--spool", dir_ + "/spool"});
    EXPECT_EQ(daemon.exit_code, 0) << daemon.err;
    if (daemon.exit_code != 0) return "";
    const CommandResult list = RunCommand(
        dir_, "takes-list", {Bin("reenact"), "takes", "list", "--server", address_, "--json"});
    EXPECT_EQ(list.exit_code, 0) << list.err;
    const auto takes = nlohmann::json::parse(list.out, nullptr, false);
    EXPECT_TRUE(takes.is_array() && takes.size() == 1u) << list.out;
    if (!takes.is_array() || takes.size() != 1u) return "";
    return takes[0]["take_id"].get<std::string>();
  }

  // `reenact jobs submit ... --wait --json` of `method` on `take_id`.
  nlohmann::json Submit(const std::string& name, const std::string& take_id,
                        const std::string& method, const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {Bin("reenact"), "jobs",   "submit",  "--server",
                                     address_,       "--take", take_id,   "--method",
                                     method,         "--wait", "--quiet", "--json"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    const CommandResult result = RunCommand(dir_, name, argv, 1200);
    EXPECT_EQ(result.exit_code, 0) << result.err << ReadText(dir_ + "/server.err");
    auto json = nlohmann::json::parse(result.out, nullptr, false);
    EXPECT_TRUE(json.is_object() && json.contains("reenactment")) << result.out;
    return json;
  }

  // `reenact jobs show JOB --json`.
  nlohmann::json Show(const std::string& job_id) {
    const CommandResult show =
        RunCommand(dir_, "show-" + job_id,
                   {Bin("reenact"), "jobs", "show", job_id, "--server", address_, "--json"});
    EXPECT_EQ(show.exit_code, 0) << show.err;
    auto job = nlohmann::json::parse(show.out, nullptr, false);
    EXPECT_TRUE(job.is_object()) << show.out;
    return job;
  }

  // The workers the segments of a split job ran on; every part succeeded.
  std::set<std::string> SegmentWorkers(const nlohmann::json& job) {
    std::set<std::string> workers;
    for (const auto& part : job["parts"]) {
      EXPECT_EQ(part["state"], "succeeded") << part.dump();
      if (part["attempt_history"].empty()) continue;
      const std::string worker = part["attempt_history"].back()["worker"].get<std::string>();
      EXPECT_TRUE(worker == "worker-a" || worker == "worker-b") << worker;
      if (absl::StartsWith(part["name"].get<std::string>(), "segment-")) {
        workers.insert(worker);
        EXPECT_GT(part["file_bytes"].get<int64_t>(), 0) << part.dump();
      }
    }
    return workers;
  }

  std::string clip_;
  std::string dir_;
  std::string skipped_;  // Why StartWithTake skipped.
  std::string address_;
  std::unique_ptr<Subprocess> server_;
  std::vector<std::unique_ptr<Subprocess>> workers_;
};

TEST_F(SegmentedJobEndToEnd, ThreeSegmentsOnTwoWorkersEqualTheWholeJob) {
  const std::string take_id = StartWithTake(6.0, 960, 540);
  if (!skipped_.empty()) GTEST_SKIP() << skipped_;
  ASSERT_FALSE(take_id.empty());

  auto submit = [&](const std::string& name, const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {"--option", "atlas_px=512"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return Submit(name, take_id, "body", argv);
  };
  // A split job's stitch decodes no colour, so it carries the static atlas
  // alone; the whole job is compared without its per-frame appearance.
  const nlohmann::json whole = submit("submit-whole", {"--option", "appearance=false"});
  const nlohmann::json segmented = submit("submit-segmented", {"--segments", "3"});
  ASSERT_TRUE(whole.contains("reenactment") && segmented.contains("reenactment"));

  // Where every part ran.
  const std::string job_id = segmented["job"]["job_id"].get<std::string>();
  const nlohmann::json job = Show(job_id);
  ASSERT_TRUE(job.is_object());
  EXPECT_EQ(job["state"], "succeeded");
  EXPECT_EQ(job["segments"], 3);
  ASSERT_EQ(job["parts"].size(), 5u) << job.dump();
  EXPECT_EQ(SegmentWorkers(job).size(), 2u)
      << "the segments should run on both workers: " << job.dump();

  // What the server streamed: the whole job the take as stored; each phase
  // of the segmented one the take without image bytes, then the images it
  // decodes (prepare every depth, a segment its own frames, the stitch
  // none), and its part inputs.
  const nlohmann::json whole_job = Show(whole["job"]["job_id"].get<std::string>());
  ASSERT_TRUE(whole_job.is_object() && !whole_job["attempt_history"].empty()) << whole_job.dump();
  const int64_t whole_read = whole_job["attempt_history"].back()["read_bytes"].get<int64_t>();
  // Per part: the take bytes streamed (its read less its part inputs).
  std::map<std::string, int64_t> part_bytes;
  for (const auto& part : job["parts"]) {
    part_bytes[part["name"].get<std::string>()] = part.value("file_bytes", int64_t{0});
  }
  std::map<std::string, int64_t> take_read;
  int64_t segmented_take_read = 0;
  int64_t segmented_read = 0;
  for (const auto& part : job["parts"]) {
    const std::string name = part["name"].get<std::string>();
    const int64_t read = part["attempt_history"].back()["read_bytes"].get<int64_t>();
    int64_t inputs = 0;
    if (name != "prepare") inputs += part_bytes["prepare"];
    if (name == "stitch") {
      for (const char* s : {"segment-1", "segment-2", "segment-3"}) inputs += part_bytes[s];
    }
    take_read[name] = read - inputs;
    segmented_take_read += read - inputs;
    segmented_read += read;
  }
  std::printf(
      "[ segments ] take bytes streamed: whole job %.2f MB; segmented %.2f MB (prepare %.2f, "
      "segments %.2f / %.2f / %.2f, stitch %.2f MB), plus %.2f MB of part files\n",
      1e-6 * whole_read, 1e-6 * segmented_take_read, 1e-6 * take_read["prepare"],
      1e-6 * take_read["segment-1"], 1e-6 * take_read["segment-2"], 1e-6 * take_read["segment-3"],
      1e-6 * take_read["stitch"], 1e-6 * (segmented_read - segmented_take_read));
  EXPECT_GT(whole_read, 0);
  for (const auto& [name, read] : take_read) EXPECT_GT(read, 0) << name;
  for (const char* segment : {"segment-1", "segment-2", "segment-3"}) {
    EXPECT_LT(take_read[segment], whole_read * 3 / 4) << segment << " streamed the whole take";
  }
  // 6 s: 40 of the 90 instants lie near the 5 shape targets.
  EXPECT_LT(take_read["prepare"], whole_read / 3) << "prepare decodes the depth near its targets";
  EXPECT_LT(take_read["stitch"], whole_read / 10) << "the stitch decodes no image";
  EXPECT_LT(segmented_take_read, 3 * whole_read / 2);

  // The two reenactments, frame by frame.
  const auto a = ReadReenactmentFile(ReenactmentFile(whole["reenactment"].get<std::string>()));
  const auto b = ReadReenactmentFile(ReenactmentFile(segmented["reenactment"].get<std::string>()));
  ASSERT_TRUE(a.ok()) << a.status();
  ASSERT_TRUE(b.ok()) << b.status();
  ASSERT_TRUE(a->is_body() && b->is_body());
  ASSERT_EQ(a->frames.size(), b->frames.size());
  auto mesh = DecodeBodyMesh(a->body.front());
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  double joint_sum_mm = 0.0, vertex_sum_mm = 0.0;
  int joints = 0;
  for (size_t i = 0; i < a->frames.size(); ++i) {
    const v1::PartFrame& fa = a->frames[i];
    const v1::PartFrame& fb = b->frames[i];
    ASSERT_EQ(fa.joints_in_world_m_size(), fb.joints_in_world_m_size());
    for (int j = 0; j < fa.joints_in_world_m_size(); ++j) {
      joint_sum_mm +=
          1000.0 * (FromProto(fa.joints_in_world_m(j)) - FromProto(fb.joints_in_world_m(j))).norm();
      ++joints;
    }
    auto pa = PoseBodyMesh(*mesh, fa.body());
    auto pb = PoseBodyMesh(*mesh, fb.body());
    ASSERT_TRUE(pa.ok() && pb.ok());
    vertex_sum_mm += 1000.0 * (pa->vertices_m - pb->vertices_m).colwise().norm().mean();
  }
  const double joint_mm = joint_sum_mm / std::max(1, joints);
  const double vertex_mm = vertex_sum_mm / std::max<size_t>(1, a->frames.size());

  // Both against the ground truth.
  const nlohmann::json fw = Eval(whole["reenactment"].get<std::string>());
  const nlohmann::json fs_ = Eval(segmented["reenactment"].get<std::string>());
  ASSERT_TRUE(fw.is_object() && fs_.is_object());
  const double d_mpjpe = std::abs(fw["mpjpe_mm"].get<double>() - fs_["mpjpe_mm"].get<double>());
  const double d_surface =
      std::abs(fw["surface_mm"].get<double>() - fs_["surface_mm"].get<double>());
  const double d_psnr = std::abs(fw["psnr_db_90"].get<double>() - fs_["psnr_db_90"].get<double>());
  std::printf(
      "[ segments ] body, %zu frames, 3 segments on 2 workers vs whole: joints differ by %.3f "
      "mm, posed vertices by %.3f mm; against the truth: MPJPE %.2f vs %.2f mm, surface %.2f vs "
      "%.2f mm, PSNR90 %.2f vs %.2f dB (tolerances 1 mm, 1 mm, 0.2 dB)\n",
      a->frames.size(), joint_mm, vertex_mm, fs_["mpjpe_mm"].get<double>(),
      fw["mpjpe_mm"].get<double>(), fs_["surface_mm"].get<double>(), fw["surface_mm"].get<double>(),
      fs_["psnr_db_90"].get<double>(), fw["psnr_db_90"].get<double>());
  // The promise is about accuracy: against the truth, the segmented result
  // is as good as the whole one. The two need not be the same fit: a
  // sequential fit depends on its path (each frame starts from the one
  // before, Eq. 4.6), and a segment that starts one second early may settle
  // a limb's twist differently from the whole run for a while (measured on
  // this take: up to 9.6 mm of surface for 45 frames after the second
  // segment's start, with the segmented run the nearer to the truth). So
  // the direct differences get a looser bound.
  EXPECT_LE(joint_mm, 3.0);
  EXPECT_LE(vertex_mm, 6.0);
  EXPECT_LE(d_mpjpe, 1.0);
  EXPECT_LE(d_surface, 1.0);
  EXPECT_LE(d_psnr, 0.2);
}

// rigid-carved splits only its texturing (rigid_carved.h): the prepare
// phase registers, fuses and meshes the whole take, each segment makes its
// instants' keyframes, the stitch bakes. The two jobs' reenactments must be
// the same but for the timing figures, on a take the method was not tuned
// on, and so must their figures against the ground truth.
TEST_F(SegmentedJobEndToEnd, RigidCarvedInTwoSegmentsEqualsTheWholeJob) {
  const std::string take_id = StartWithTake(3.0, 960, 540);
  if (!skipped_.empty()) GTEST_SKIP() << skipped_;
  ASSERT_FALSE(take_id.empty());
  const std::vector<std::string> options = {"--option", "texture_size_px=256"};
  const nlohmann::json whole = Submit("submit-whole", take_id, "rigid-carved", options);
  std::vector<std::string> split_options = options;
  split_options.insert(split_options.end(), {"--segments", "2"});
  const nlohmann::json segmented =
      Submit("submit-segmented", take_id, "rigid-carved", split_options);
  ASSERT_TRUE(whole.contains("reenactment") && segmented.contains("reenactment"));

  const nlohmann::json job = Show(segmented["job"]["job_id"].get<std::string>());
  ASSERT_TRUE(job.is_object());
  EXPECT_EQ(job["state"], "succeeded");
  EXPECT_EQ(job["segments"], 2);
  ASSERT_EQ(job["parts"].size(), 4u) << job.dump();
  EXPECT_EQ(SegmentWorkers(job).size(), 2u)
      << "the segments should run on both workers: " << job.dump();
  const nlohmann::json whole_job = Show(whole["job"]["job_id"].get<std::string>());
  ASSERT_TRUE(whole_job.is_object() && !whole_job["attempt_history"].empty()) << whole_job.dump();
  const int64_t whole_read = whole_job["attempt_history"].back()["read_bytes"].get<int64_t>();
  std::map<std::string, int64_t> read;
  std::map<std::string, int64_t> file_bytes;
  for (const auto& part : job["parts"]) {
    const std::string name = part["name"].get<std::string>();
    read[name] = part["attempt_history"].back()["read_bytes"].get<int64_t>();
    file_bytes[name] = part.value("file_bytes", int64_t{0});
  }
  std::printf(
      "[ segments ] rigid-carved: whole job streamed %.2f MB; split job: prepare %.2f MB, "
      "segments %.2f / %.2f MB (with the %.2f MB prepared part), stitch %.2f MB; parts %.2f / "
      "%.2f / %.2f MB\n",
      1e-6 * whole_read, 1e-6 * read["prepare"], 1e-6 * read["segment-1"], 1e-6 * read["segment-2"],
      1e-6 * file_bytes["prepare"], 1e-6 * read["stitch"], 1e-6 * file_bytes["prepare"],
      1e-6 * file_bytes["segment-1"], 1e-6 * file_bytes["segment-2"]);
  for (const char* segment : {"segment-1", "segment-2"}) {
    EXPECT_LT(read[segment] - file_bytes["prepare"], whole_read * 3 / 4)
        << segment << " streamed the whole take";
  }
  EXPECT_LT(
      read["stitch"] - file_bytes["prepare"] - file_bytes["segment-1"] - file_bytes["segment-2"],
      whole_read / 10)
      << "the stitch decodes no image";

  // The two reenactments: the same meshes, textures, poses and keyframes.
  auto a = ReadReenactment(ReenactmentFile(whole["reenactment"].get<std::string>()));
  auto b = ReadReenactment(ReenactmentFile(segmented["reenactment"].get<std::string>()));
  ASSERT_TRUE(a.ok()) << a.status();
  ASSERT_TRUE(b.ok()) << b.status();
  ASSERT_EQ(a->parts.size(), b->parts.size());
  for (size_t p = 0; p < a->parts.size(); ++p) {
    EXPECT_EQ(a->parts[p].positions_in_part_m, b->parts[p].positions_in_part_m) << p;
    EXPECT_EQ(a->parts[p].baked_texture_jpeg, b->parts[p].baked_texture_jpeg) << p;
  }
  ASSERT_EQ(a->frames.size(), b->frames.size());
  for (size_t i = 0; i < a->frames.size(); ++i) {
    for (size_t p = 0; p < a->frames[i].parts.size(); ++p) {
      EXPECT_TRUE(a->frames[i].parts[p].world_from_part.isApprox(
          b->frames[i].parts[p].world_from_part, 1e-12))
          << i << " " << p;
    }
  }
  ASSERT_EQ(a->keyframes.size(), b->keyframes.size());
  for (size_t k = 0; k < a->keyframes.size(); ++k) {
    EXPECT_EQ(a->keyframes[k].color_jpeg, b->keyframes[k].color_jpeg) << k;
    EXPECT_EQ(a->keyframes[k].vertex_visible_bits, b->keyframes[k].vertex_visible_bits) << k;
  }

  const nlohmann::json fw = Eval(whole["reenactment"].get<std::string>());
  const nlohmann::json fs_ = Eval(segmented["reenactment"].get<std::string>());
  ASSERT_TRUE(fw.is_object() && fs_.is_object());
  std::printf(
      "[ segments ] rigid-carved, %zu frames, 2 segments on 2 workers vs whole, against the "
      "truth: MPJPE %.2f vs %.2f mm, surface %.2f vs %.2f mm, PSNR90 %.2f vs %.2f dB\n",
      a->frames.size(), fs_["mpjpe_mm"].get<double>(), fw["mpjpe_mm"].get<double>(),
      fs_["surface_mm"].get<double>(), fw["surface_mm"].get<double>(),
      fs_["psnr_db_90"].get<double>(), fw["psnr_db_90"].get<double>());
  EXPECT_LE(std::abs(fw["mpjpe_mm"].get<double>() - fs_["mpjpe_mm"].get<double>()), 1.0);
  EXPECT_LE(std::abs(fw["surface_mm"].get<double>() - fs_["surface_mm"].get<double>()), 1.0);
  EXPECT_LE(std::abs(fw["psnr_db_90"].get<double>() - fs_["psnr_db_90"].get<double>()), 0.2);
}

}  // namespace
}  // namespace reenact
