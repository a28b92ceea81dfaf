// Writes the seed corpora of the fuzz targets: a few valid inputs per target,
// made with the project's own writers (McapWriter, the depth and mask
// encoders, WriteBvh, WriteReenactmentFile, FormatBoardSpec,
// FormatIntrinsicsJson) and cut from the real files of the shared test data
// where it has them (BVH, ASF/AMC and MakeHuman assets).
//
//   make_seeds OUT_DIR [DATA_DIR]
//
// writes OUT_DIR/<target>/<name>. Without DATA_DIR, or when a file is
// missing there, the seeds of real files are left out (and said so).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "common/base/files.h"
#include "common/base/image.h"
#include "common/base/status_macros.h"
#include "common/board/board_spec.h"
#include "common/board/intrinsics_file.h"
#include "common/body/makehuman_importer.h"
#include "common/body/motion.h"
#include "common/body/procedural_body.h"
#include "common/io/body_reenactment.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/mcap_reader.h"
#include "common/io/mcap_writer.h"
#include "common/io/reenactment_file.h"
#include "fuzz/fuzz_util.h"
#include "fuzz/makehuman_assets.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::fuzz {
namespace {

std::string out_dir;    // OUT_DIR.
std::string data_dir;   // DATA_DIR, or empty.
std::string work_dir;   // Scratch files of the writers.
int missing_files = 0;  // Real files not found.
bool failed = false;    // A writer failed.

void Seed(const std::string& target, const std::string& name, absl::string_view bytes) {
  WriteFile(out_dir + "/" + target + "/" + name, std::string_view(bytes.data(), bytes.size()));
}

// Reports a failed writer (the seed is left out; make_seeds then fails).
template <typename T>
bool Check(const absl::StatusOr<T>& value, const std::string& what) {
  if (value.ok()) return true;
  std::fprintf(stderr, "make_seeds: %s: %s\n", what.c_str(), value.status().ToString().c_str());
  failed = true;
  return false;
}
bool Check(const absl::Status& status, const std::string& what) {
  return Check(absl::StatusOr<int>(status.ok() ? absl::StatusOr<int>(0) : status), what);
}

// A real file of the shared data, or nullopt (counted) when it is missing.
std::optional<std::string> RealFile(const std::string& relative) {
  if (data_dir.empty()) return std::nullopt;
  absl::StatusOr<std::string> text = ReadFileToString(data_dir + "/" + relative);
  if (!text.ok()) {
    std::fprintf(stderr, "make_seeds: no %s/%s, its seeds are left out\n", data_dir.c_str(),
                 relative.c_str());
    ++missing_files;
    return std::nullopt;
  }
  return *text;
}

std::vector<absl::string_view> Lines(absl::string_view text) { return absl::StrSplit(text, '\n'); }

// ---- MCAP ----

// Sets every CRC of an MCAP file to 0 ("not computed"), so that mutations of
// its records are not all refused by a checksum.
std::string ZeroCrcs(const std::string& path) {
  absl::StatusOr<std::string> bytes = ReadFileToString(path);
  absl::StatusOr<std::unique_ptr<McapReader>> reader = McapReader::Open(path);
  if (!Check(bytes, path) || !Check(reader, path)) return "";
  std::string out = *bytes;
  // Chunk content: start, end, uncompressed size (3 x uint64), then the CRC.
  for (const McapChunkInfo& chunk : (*reader)->chunks()) {
    out.replace(chunk.chunk_offset + 9 + 24, 4, 4, '\0');
  }
  // Footer content: summary start, summary offset start, then the CRC.
  if ((*reader)->report().indexed) out.replace(out.size() - 8 - 29 + 9 + 16, 4, 4, '\0');
  return out;
}

// Copies the MCAP file `in` to `out` with chunks of `compression`.
absl::Status RewriteMcap(const std::string& in, const std::string& out,
                         const std::string& compression) {
  ASSIGN_OR_RETURN(std::unique_ptr<McapReader> reader, McapReader::Open(in));
  McapWriterOptions options;
  options.compression = compression;
  ASSIGN_OR_RETURN(std::unique_ptr<McapWriter> writer, McapWriter::Open(out, options));
  std::map<uint16_t, McapSchemaId> schemas;
  std::map<uint16_t, McapChannelId> channels;
  for (const auto& [id, schema] : reader->schemas()) {
    ASSIGN_OR_RETURN(schemas[id], writer->AddSchema(schema.name, schema.encoding, schema.data));
  }
  for (const auto& [id, channel] : reader->channels()) {
    ASSIGN_OR_RETURN(channels[id], writer->AddChannel(schemas[channel.schema_id], channel.topic,
                                                      channel.message_encoding, channel.metadata));
  }
  RETURN_IF_ERROR(reader->ForEachMessage([&](const McapChannel& c, const McapMessage& m) {
    return writer->WriteMessage(channels[c.id], m.log_time_ns, m.publish_time_ns, m.data);
  }));
  return writer->Close();
}

// A recording of two channels in small chunks, and its bytes.
std::string McapRecording(const std::string& compression, int messages) {
  const std::string path = work_dir + "/recording-" + compression + ".mcap";
  McapWriterOptions options;
  options.compression = compression;
  options.chunk_size_bytes = 256;
  absl::StatusOr<std::unique_ptr<McapWriter>> writer = McapWriter::Open(path, options);
  if (!Check(writer, path)) return "";
  McapWriter& w = **writer;
  absl::StatusOr<McapSchemaId> schema = w.AddSchema("reenact.v1.Test", "protobuf", "schema bytes");
  if (!Check(schema, "AddSchema")) return "";
  absl::StatusOr<McapChannelId> depth = w.AddChannel(*schema, "/k0/depth", "protobuf");
  absl::StatusOr<McapChannelId> note = w.AddChannel(0, "/notes", "json", {{"kind", "note"}});
  if (!Check(depth, "AddChannel") || !Check(note, "AddChannel")) return "";
  for (int i = 0; i < messages; ++i) {
    const uint64_t t = 1'000'000'000 + 33'333'333 * static_cast<uint64_t>(i);
    Check(w.WriteMessage(i % 3 == 2 ? *note : *depth, t, t + 5,
                         absl::StrCat("message ", i, std::string(20 + 7 * i, 'a' + i % 26))),
          "WriteMessage");
  }
  Check(w.Close(), "Close");
  absl::StatusOr<std::string> bytes = ReadFileToString(path);
  return Check(bytes, path) ? *bytes : "";
}

void McapSeeds() {
  const std::string zstd = McapRecording("zstd", 12);
  const std::string plain = McapRecording("", 12);
  Seed("fuzz_mcap_summary", "zstd.mcap", zstd);
  Seed("fuzz_mcap_summary", "plain.mcap", plain);
  Seed("fuzz_mcap_summary", "plain-no-crc.mcap", ZeroCrcs(work_dir + "/recording-.mcap"));
  Seed("fuzz_mcap_summary", "empty.mcap", McapRecording("", 0));
  // Files of a writer that died: cut inside the summary, inside a chunk, and
  // right after the Header.
  for (const auto& [name, bytes] : {std::pair{"zstd", zstd}, std::pair{"plain", plain}}) {
    for (const double fraction : {0.9, 0.55, 0.2}) {
      Seed("fuzz_mcap_recovery", absl::StrCat(name, "-cut-", fraction * 100, ".mcap"),
           bytes.substr(0, static_cast<size_t>(fraction * static_cast<double>(bytes.size()))));
    }
  }
  Seed("fuzz_mcap_recovery", "complete.mcap", plain);
}

// ---- Depth and masks ----

DepthImageMm TestDepth(int width, int height) {
  DepthImageMm depth(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      depth.at(x, y) = (x + y) % 5 == 0 ? 0 : static_cast<uint16_t>(1200 + 13 * x - 7 * y);
    }
  }
  return depth;
}

MaskImage TestMask(int width, int height) {
  MaskImage mask(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      mask.at(x, y) = x > width / 4 && x < 3 * width / 4 ? static_cast<uint8_t>(1 + y / 8) : 0;
    }
  }
  return mask;
}

void CodecSeeds() {
  for (const auto& [w, h] : {std::pair{8, 6}, std::pair{32, 24}, std::pair{1, 1}}) {
    const DepthImageMm depth = TestDepth(w, h);
    for (const bool zstd : {false, true}) {
      absl::StatusOr<std::string> encoded = EncodeDepth(depth, DepthCodecOptions{.zstd = zstd});
      if (!Check(encoded, "EncodeDepth")) continue;
      Seed("fuzz_depth_codec", absl::StrCat(w, "x", h, zstd ? "-zstd" : "", ".rvld"), *encoded);
    }
    // The bare RVL stream after a two-byte pixel count.
    std::string rvl(2, '\0');
    rvl[0] = static_cast<char>(depth.data.size() & 0xFF);
    rvl[1] = static_cast<char>(depth.data.size() >> 8);
    Seed("fuzz_depth_codec", absl::StrCat(w, "x", h, ".rvl"), rvl + RvlCompress(depth.data));

    const MaskImage mask = TestMask(w, h);
    Seed("fuzz_mask_rle", absl::StrCat(w, "x", h, ".rle"), EncodeMaskRle(mask));
    DepthImageMm as_depth(w, h);
    std::copy(mask.data.begin(), mask.data.end(), as_depth.data.begin());
    absl::StatusOr<std::string> rvl_mask = EncodeDepth(as_depth, DepthCodecOptions{.zstd = false});
    if (Check(rvl_mask, "EncodeDepth")) {
      Seed("fuzz_mask_rle", absl::StrCat(w, "x", h, "-mask.rvld"), *rvl_mask);
    }
  }
  Seed("fuzz_mask_rle", "empty.rle", EncodeMaskRle(MaskImage()));
}

// ---- Frame sets ----

void FrameSetSeeds() {
  absl::StatusOr<std::string> jpeg = EncodeJpeg(RgbImage(32, 24, 90), 80);
  if (!Check(jpeg, "EncodeJpeg")) return;
  v1::FrameSet set;
  set.set_sequence(7);
  set.set_stamp_ns(1'200'000'000);
  set.set_skew_ns(1000);
  int i = 0;
  for (const std::string id : {"k0", "k1", "free"}) {
    const int w = id == "free" ? 16 : 32, h = id == "free" ? 8 : 24;
    v1::Frame* f = set.add_frames();
    f->set_sensor_id(id);
    f->set_device_stamp_ns(233'333'331 + i);
    f->set_host_stamp_ns(1'200'000'000 + 1000 * i);
    f->set_frame_index(6);
    const auto header = [&](auto* m) {
      m->set_sensor_id(f->sensor_id());
      m->set_device_stamp_ns(f->device_stamp_ns());
      m->set_host_stamp_ns(f->host_stamp_ns());
      m->set_frame_index(f->frame_index());
    };
    const bool zstd = i % 2 == 1;
    v1::DepthImage* depth = f->mutable_depth();
    header(depth);
    depth->set_width_px(w);
    depth->set_height_px(h);
    depth->set_encoding(zstd ? "rvl+zstd" : "rvl");
    absl::StatusOr<std::string> encoded = EncodeDepth(TestDepth(w, h), {.zstd = zstd});
    if (!Check(encoded, "EncodeDepth")) return;
    depth->set_data(*encoded);
    if (id != "free") {
      v1::ColorImage* color = f->mutable_color();
      header(color);
      color->set_width_px(w);
      color->set_height_px(h);
      color->set_encoding("jpeg");
      color->set_quality(80);
      color->set_data(*jpeg);
    }
    v1::ActorMask* mask = f->mutable_mask();
    header(mask);
    mask->set_width_px(w);
    mask->set_height_px(h);
    mask->set_encoding("rle");
    mask->set_data(EncodeMaskRle(TestMask(w, h)));
    v1::Skeleton* skeleton = f->add_skeletons();
    header(skeleton);
    for (int j = 0; j < 3; ++j) {
      v1::Joint* joint = skeleton->add_joints();
      joint->set_name(absl::StrCat("joint", j));
      joint->mutable_position_in_depth_m()->set_x(0.1 * j);
      joint->mutable_position_in_depth_m()->set_y(-0.2 * j);
      joint->mutable_position_in_depth_m()->set_z(2.0);
      joint->set_confidence(0.9f);
    }
    ++i;
  }
  Seed("fuzz_frame_set_validation", "three-sensors.pb", set.SerializeAsString());
  v1::FrameSet one = set;
  one.mutable_frames()->DeleteSubrange(1, 2);
  one.add_missing_sensor_ids("k1");
  Seed("fuzz_frame_set_validation", "one-frame-k1-missing.pb", one.SerializeAsString());
}

// ---- Motion files ----

// The first `frames` frames (or fewer) of a BVH file's text, "Frames:"
// rewritten.
std::string CutBvh(absl::string_view text, int frames) {
  enum { kHierarchy, kMotionHeader, kFrames } part = kHierarchy;
  std::string hierarchy, frame_time, frame_lines;
  int kept = 0;
  for (absl::string_view line : Lines(text)) {
    if (part == kHierarchy) {
      absl::StrAppend(&hierarchy, line, "\n");
      if (absl::StartsWith(line, "MOTION")) part = kMotionHeader;
    } else if (part == kMotionHeader) {
      if (absl::StartsWith(line, "Frame Time:")) {
        frame_time = std::string(line);
        part = kFrames;
      }
    } else if (kept < frames && !line.empty()) {
      absl::StrAppend(&frame_lines, line, "\n");
      ++kept;
    }
  }
  return absl::StrCat(hierarchy, "Frames: ", kept, "\n", frame_time, "\n", frame_lines);
}

// The header, skeleton and first `frames` frames of an AMC file's text.
std::string CutAmc(absl::string_view text, int frames) {
  std::string out;
  int seen = 0;
  for (absl::string_view line : Lines(text)) {
    int number = 0;
    if (absl::SimpleAtoi(line, &number) && ++seen > frames) break;
    absl::StrAppend(&out, line, "\n");
  }
  return out;
}

void MotionSeeds() {
  for (const std::string name : {"mocap/cmu/01_01.bvh", "mocap/cmu/131_01.bvh",
                                 "mocap/cmu-train/02_01.bvh", "body/makehuman/poses/tpose.bvh"}) {
    const std::optional<std::string> text = RealFile(name);
    if (!text) continue;
    const std::string cut = CutBvh(*text, 3);
    const std::string base = std::filesystem::path(name).stem().string();
    Seed("fuzz_bvh", base + "-3-frames.bvh", cut);
    // The same motion through the project's writer.
    const std::string in = WriteScratchFile("cut.bvh", cut);
    const std::string out = ScratchDir() + "/written.bvh";
    absl::StatusOr<body::Motion> motion = body::ReadBvh(in);
    if (!Check(motion, name) || !Check(body::WriteBvh(*motion, out), "WriteBvh")) continue;
    absl::StatusOr<std::string> written = ReadFileToString(out);
    if (Check(written, out)) Seed("fuzz_bvh", base + "-written.bvh", *written);
  }
  for (const auto& [asf_name, amc_name] :
       {std::pair{"07-walk", "07_05-walk"}, std::pair{"09-run", "09_06-run"},
        std::pair{"131-dance", "131_04-dance"}}) {
    const std::optional<std::string> asf = RealFile(absl::StrCat("mocap/cmu/", asf_name, ".asf"));
    const std::optional<std::string> amc = RealFile(absl::StrCat("mocap/cmu/", amc_name, ".amc"));
    if (!asf || !amc) continue;
    Seed("fuzz_asf_amc", absl::StrCat(amc_name, "-3-frames"),
         *asf + std::string(1, '\0') + CutAmc(*amc, 3));
  }
}

// ---- MakeHuman ----

// A cut of a real base.obj: its first `faces` faces of group "body", their
// vertices and uvs renumbered in order of use.
std::string CutObj(absl::string_view text, size_t faces) {
  std::vector<absl::string_view> v, vt;
  std::vector<std::vector<std::pair<int, int>>> body;
  bool in_body = false;
  for (absl::string_view line : Lines(text)) {
    if (absl::StartsWith(line, "v ")) v.push_back(line);
    if (absl::StartsWith(line, "vt ")) vt.push_back(line);
    if (absl::StartsWith(line, "g ")) in_body = line == "g body" || line == "g body\r";
    if (!in_body || !absl::StartsWith(line, "f ") || body.size() >= faces) continue;
    std::vector<std::pair<int, int>> face;
    for (absl::string_view corner : absl::StrSplit(line.substr(2), ' ', absl::SkipEmpty())) {
      std::vector<absl::string_view> parts = absl::StrSplit(corner, '/');
      int vi = 0, ti = 0;
      if (!absl::SimpleAtoi(parts[0], &vi) || parts.size() < 2 ||
          !absl::SimpleAtoi(parts[1], &ti)) {
        return "";
      }
      face.emplace_back(vi, ti);
    }
    body.push_back(std::move(face));
  }
  std::map<int, int> v_map, vt_map;
  std::string vs, vts, fs = "g body\n";
  for (const auto& face : body) {
    fs += "f";
    for (const auto& [vi, ti] : face) {
      if (vi < 1 || vi > static_cast<int>(v.size()) || ti < 1 || ti > static_cast<int>(vt.size())) {
        return "";
      }
      auto [vit, v_new] = v_map.emplace(vi, static_cast<int>(v_map.size()) + 1);
      if (v_new) absl::StrAppend(&vs, v[vi - 1], "\n");
      auto [tit, t_new] = vt_map.emplace(ti, static_cast<int>(vt_map.size()) + 1);
      if (t_new) absl::StrAppend(&vts, vt[ti - 1], "\n");
      absl::StrAppend(&fs, " ", vit->second, "/", tit->second);
    }
    fs += "\n";
  }
  return "# cut of the MakeHuman base mesh\n" + vs + vts + fs;
}

// A real JSON file whose vertex indices are taken modulo the synthetic
// mesh's vertex count, so that it fits that mesh.
std::string RemapVertices(absl::string_view text, bool weights) {
  nlohmann::json json =
      nlohmann::json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded()) return "";
  if (!weights && json.contains("joints")) {
    for (auto& [name, group] : json["joints"].items()) {
      for (auto& v : group) v = v.get<int>() % kMakeHumanBodyVertices;
    }
  }
  if (weights && json.contains("weights")) {
    for (auto& [bone, pairs] : json["weights"].items()) {
      nlohmann::json kept = nlohmann::json::array();
      for (size_t i = 0; i < pairs.size() && i < 4; ++i) {
        kept.push_back({pairs[i][0].get<int>() % kMakeHumanBodyVertices, pairs[i][1]});
      }
      pairs = kept;
    }
  }
  return json.dump(1) + "\n";
}

void MakeHumanSeeds() {
  const MakeHumanFiles small = SmallMakeHumanFiles();
  const std::string nul(1, '\0');
  Seed("fuzz_makehuman_obj", "synthetic", small.obj + nul + small.target);
  Seed("fuzz_makehuman_obj", "synthetic-obj-only", small.obj);
  Seed("fuzz_makehuman_json", "synthetic", small.skeleton + nul + small.weights);
  Seed("fuzz_makehuman_json", "synthetic-skeleton-only", small.skeleton);
  const std::optional<std::string> obj = RealFile("body/makehuman/3dobjs/base.obj");
  const std::optional<std::string> target =
      RealFile("body/makehuman/targets/macrodetails/caucasian-male-young.target");
  if (obj && target) {
    std::string target_cut;
    int kept = 0;
    for (absl::string_view line : Lines(*target)) {
      int vertex = 0;
      std::vector<absl::string_view> words = absl::StrSplit(line, ' ', absl::SkipEmpty());
      if (!words.empty() && absl::SimpleAtoi(words[0], &vertex)) {
        if (++kept > 40) break;
        words[0] = "";
        absl::StrAppend(&target_cut, vertex % kMakeHumanBodyVertices, absl::StrJoin(words, " "),
                        "\n");
      } else {
        absl::StrAppend(&target_cut, line, "\n");
      }
    }
    Seed("fuzz_makehuman_obj", "base-cut", CutObj(*obj, 60) + nul + target_cut);
  }
  const std::optional<std::string> skeleton = RealFile("body/makehuman/rigs/default.mhskel");
  const std::optional<std::string> weights = RealFile("body/makehuman/rigs/default_weights.mhw");
  if (skeleton && weights) {
    Seed("fuzz_makehuman_json", "default-remapped",
         RemapVertices(*skeleton, false) + nul + RemapVertices(*weights, true));
  }
}

// ---- Reenactment files ----

v1::PartMesh Triangle(int part, const std::string& name) {
  v1::PartMesh mesh;
  mesh.set_part(part);
  mesh.set_name(name);
  mesh.set_positions_in_part_m_f32(PackFloats({0, 0, 0, 0.1f, 0, 0, 0, 0.2f, 0, 0, 0, 0.05f}));
  mesh.set_normals_in_part_f32(PackFloats({0, 0, 1, 0, 0, 1, 0, 0, 1, 1, 0, 0}));
  mesh.set_uvs_f32(PackFloats({0, 0, 1, 0, 0, 1, 1, 1}));
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) mesh.add_triangle_indices(i);
  mesh.set_reference_length_m(0.2f);
  return mesh;
}

ReenactmentData RigidReenactment(const std::string& texture) {
  ReenactmentData data;
  data.info.set_reenactment_id("r-20260101-120000-seed");
  data.info.set_take_id("t-20260101-110000-seed");
  data.info.set_method("rigid-carved");
  data.info.set_created_unix_ns(1767268800000000000);
  data.info.set_frame_count(3);
  data.info.set_fps(30.0);
  v1::SensorCalibration* sensor = data.info.add_sensors();
  sensor->set_sensor_id("k0");
  sensor->mutable_color_intrinsics()->set_width_px(8);
  sensor->mutable_color_intrinsics()->set_height_px(8);
  for (int p = 0; p < 2; ++p) {
    const std::string name = p == 0 ? "head" : "chest";
    data.info.add_part_names(name);
    data.parts.push_back(Triangle(p, name));
    data.parts.back().set_baked_texture_jpeg(texture);
  }
  for (int f = 0; f < 3; ++f) {
    v1::PartFrame frame;
    frame.set_frame_index(f);
    frame.set_stamp_ns(5'000'000'000 + 33'333'333 * f);
    for (int p = 0; p < 2; ++p) {
      v1::PartPose* pose = frame.add_parts();
      pose->mutable_world_from_part()->mutable_rotation()->set_w(1.0);
      pose->mutable_world_from_part()->mutable_translation_m()->set_x(0.05 * f);
      pose->set_scale(1.0f);
      pose->set_valid(true);
    }
    data.frames.push_back(std::move(frame));
  }
  v1::TextureKeyframe keyframe;
  keyframe.set_frame_index(1);
  keyframe.set_sensor_id("k0");
  keyframe.set_stamp_ns(data.frames[1].stamp_ns());
  keyframe.set_color_jpeg(texture);
  for (int p = 0; p < 2; ++p) keyframe.add_vertex_visible_bits(std::string(1, '\x05'));
  data.keyframes.push_back(std::move(keyframe));
  return data;
}

// A body-model reenactment of the synthetic MakeHuman body (48 vertices), or
// of a coarse procedural body when that does not import.
absl::StatusOr<ReenactmentData> BodyReenactment() {
  const std::string assets = work_dir + "/makehuman";
  WriteMakeHumanFiles(assets, SmallMakeHumanFiles());
  absl::StatusOr<body::BodyModel> model = body::ImportMakeHuman(assets);
  if (!model.ok()) {
    std::fprintf(stderr,
                 "make_seeds: the synthetic MakeHuman body does not import (%s); "
                 "using a procedural body\n",
                 model.status().ToString().c_str());
    body::ProceduralBodyOptions options;
    options.grid_spacing_m = 0.03;
    options.smoothing_iterations = 1;
    options.population_size = 20;
    options.num_shape_components = 8;
    options.num_held_out = 0;
    ASSIGN_OR_RETURN(model, body::BuildProceduralBody(options));
  }
  ReenactmentData data;
  data.info.set_reenactment_id("r-20260101-120000-body");
  data.info.set_take_id("t-20260101-110000-body");
  data.info.set_method("body");
  data.info.set_created_unix_ns(1767268800000000000);
  data.info.set_frame_count(2);
  data.info.set_fps(30.0);
  ASSIGN_OR_RETURN(v1::BodyMesh mesh,
                   MakeBodyMesh(*model, Eigen::VectorXd::Zero(model->num_shape_components()), ""));
  data.body.push_back(std::move(mesh));
  for (int f = 0; f < 2; ++f) {
    body::BodyPose pose;
    pose.local_rotation[static_cast<int>(body::KinectV2Joint::kElbowRight)] =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.4 * f, Eigen::Vector3d::UnitX()));
    pose.root_translation_m = Eigen::Vector3d(0.05 * f, 0.0, 0.0);
    v1::PartFrame frame;
    frame.set_frame_index(f);
    frame.set_stamp_ns(1'000'000'000 + 33'333'333 * f);
    *frame.mutable_body() = BodyPoseToProto(pose);
    if (f == 1) {
      // 2 mm: 40 steps of 0.05 mm.
      SetBodyPoseOffsets(VertexOffsets50um::Constant(3, model->num_vertices(), 40),
                         frame.mutable_body());
    }
    data.frames.push_back(std::move(frame));
  }
  return data;
}

void ReenactmentSeeds() {
  absl::StatusOr<std::string> texture = EncodeJpeg(RgbImage(8, 8, 128), 70);
  if (!Check(texture, "EncodeJpeg")) return;
  absl::StatusOr<ReenactmentData> body = BodyReenactment();
  if (!Check(body, "body reenactment")) return;
  for (const auto& [name, data] :
       {std::pair{"rigid", RigidReenactment(*texture)}, std::pair{"body", *body}}) {
    const std::string path = absl::StrCat(work_dir, "/", name, ".mcap");
    if (!Check(WriteReenactmentFile(data, path), "WriteReenactmentFile")) continue;
    absl::StatusOr<std::string> bytes = ReadFileToString(path);
    if (Check(bytes, path)) Seed("fuzz_reenactment_file", absl::StrCat(name, ".mcap"), *bytes);
    // Uncompressed chunks without CRCs: mutations reach the messages.
    const std::string plain = absl::StrCat(work_dir, "/", name, "-plain.mcap");
    if (Check(RewriteMcap(path, plain, ""), "RewriteMcap")) {
      Seed("fuzz_reenactment_file", absl::StrCat(name, "-plain-no-crc.mcap"), ZeroCrcs(plain));
    }
  }
}

// ---- Board spec and intrinsics ----

void BoardSeeds() {
  Seed("fuzz_board_spec", "default", board::kDefaultBoardSpecText);
  board::BoardSpec spec;
  spec.dictionary = "DICT_APRILTAG_36h11";
  spec.columns = 5;
  spec.rows = 7;
  spec.marker_side_m = 0.0405;
  spec.marker_gap_m = 0.0081;
  spec.first_marker_id = 12;
  Seed("fuzz_board_spec", "apriltag", board::FormatBoardSpec(spec));
  Seed("fuzz_board_spec", "mixed-case", "ArUco:dict_6x6_250:4X3:60.5:12.25:0");

  CameraIntrinsics kinect;  // The PCL frame's camera (shared data README).
  kinect.width = 640;
  kinect.height = 480;
  kinect.fx = kinect.fy = 525.0;
  kinect.cx = 319.5;
  kinect.cy = 239.5;
  Seed("fuzz_intrinsics_file", "pcl-kinect.json", board::FormatIntrinsicsJson(kinect));
  absl::StatusOr<CameraIntrinsics> phone = board::IntrinsicsFromFieldOfView(1280, 720, 65.0);
  if (Check(phone, "IntrinsicsFromFieldOfView")) {
    phone->k1 = 0.08;
    phone->k2 = -0.21;
    phone->p1 = 0.001;
    Seed("fuzz_intrinsics_file", "phone.json", board::FormatIntrinsicsJson(*phone));
  }
  Seed("fuzz_intrinsics_file", "fov.json",
       R"({"width": 1920, "height": 1080, "horizontal_fov_deg": 70})");
  Seed("fuzz_intrinsics_file", "distortion-array.json",
       R"({"width": 640, "height": 360, "fx": 481.94, "fy": 481.94, "cx": 315.16, )"
       R"("cy": 174.97, "distortion": [0.1, -0.05, 0.001, 0.002, 0.01]})");
}

// What the tablet app sends: targets of the API and the app, and the Range
// headers of a resumed glTF download.
void WebRequestSeeds() {
  Seed("fuzz_web_request", "list.txt", "/api/v1/reenactments?page_size=20&page_token=abc%3D\n");
  Seed("fuzz_web_request", "glb-range.txt",
       "/api/v1/reenactments/r-20261124-213130-2a6f/model.glb\nbytes=1000-");
  Seed("fuzz_web_request", "suffix.txt", "/api/v1/reenactments/r-1/model.glb\nbytes=-500");
  Seed("fuzz_web_request", "follow.txt", "/api/v1/jobs/j-1/follow?access_token=abc+def\n");
  Seed("fuzz_web_request", "deep-link.txt",
       "/?reenactment=r-1&t=1.5&paused=1&yaw=-90&mirror=1\nbytes=0-0,5-9");
  // Not UTF-8, escaped and raw: the error answers quote them.
  Seed("fuzz_web_request", "not-utf8.txt", "/%ff?page_size=%ff&live=%c0%ae\n");
  Seed("fuzz_web_request", "raw-byte.txt", "/api/v1/reenactments/\xff\xfe/model.glb\nbytes=0-");
}

}  // namespace
}  // namespace reenact::fuzz

int main(int argc, char** argv) {
  using namespace reenact::fuzz;  // NOLINT: a small program.
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: %s OUT_DIR [DATA_DIR]\n", argv[0]);
    return 2;
  }
  out_dir = argv[1];
  if (argc == 3) data_dir = argv[2];
  if (!data_dir.empty() && !std::filesystem::is_directory(data_dir)) {
    std::fprintf(stderr, "make_seeds: no test data folder %s; seeds of real files left out\n",
                 data_dir.c_str());
    data_dir.clear();
  }
  work_dir = ScratchDir() + "/writers";
  std::filesystem::create_directories(work_dir);
  McapSeeds();
  CodecSeeds();
  FrameSetSeeds();
  MotionSeeds();
  MakeHumanSeeds();
  ReenactmentSeeds();
  BoardSeeds();
  WebRequestSeeds();
  if (missing_files > 0) {
    std::fprintf(stderr, "make_seeds: %d real files missing\n", missing_files);
  }
  return failed ? 1 : 0;
}
