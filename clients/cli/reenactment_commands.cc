// `reenact reenactments ...` (the server's Reenactments service: list, show,
// delete, and follow a live job's preview) and `reenact export` (a
// reenactment, fetched or from a local file, as glTF, or a body-model
// reenactment's skeleton as BVH).
#include <cctype>
#include <ctime>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/commands.h"
#include "clients/cli/fit_diagnosis.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/remote_flags.h"
#include "clients/sdk/follow_stats.h"
#include "clients/sdk/reenactments_client.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/terminal_text.h"
#include "common/base/time.h"
#include "common/body/motion.h"
#include "common/io/body_reenactment_motion.h"
#include "common/io/gltf_export.h"
#include "common/io/jpeg.h"
#include "common/io/reenactment_convert.h"
#include "common/io/reenactment_file.h"

namespace reenact::cli {
namespace {

double DurationS(const v1::ReenactmentInfo& info) {
  return info.fps() > 0 && info.frame_count() > 0 ? (info.frame_count() - 1) / info.fps() : 0.0;
}

nlohmann::json SummaryJson(const v1::ReenactmentSummary& s) {
  const v1::ReenactmentInfo& info = s.info();
  nlohmann::json options = nlohmann::json::object();
  for (const auto& [key, value] : info.options()) options[key] = value;
  nlohmann::json figures = nlohmann::json::object();
  for (const auto& [key, value] : info.figures()) figures[key] = value;
  return {
      {"reenactment_id", info.reenactment_id()},
      {"take_id", info.take_id()},
      {"job_id", info.job_id()},
      {"method", info.method()},
      {"options", options},
      {"created_unix_ns", info.created_unix_ns()},
      {"generator", info.generator()},
      {"frame_count", info.frame_count()},
      {"fps", info.fps()},
      {"duration_s", DurationS(info)},
      {"part_names", std::vector<std::string>(info.part_names().begin(), info.part_names().end())},
      {"sensor_count", info.sensors_size()},
      {"figures", figures},
      {"fit", FitDiagnosisJson(info)},
      {"part_count", s.part_count()},
      {"keyframe_count", s.keyframe_count()},
      {"file_bytes", s.file_bytes()}};
}

// The id from `--reenactment ID` or the one positional argument.
absl::StatusOr<std::string> ReenactmentId(const Flags& flags, const std::string& command) {
  const std::vector<std::string>& positional = flags.positional();
  if (flags.Has("reenactment") && positional.empty()) return *flags.Get("reenactment");
  if (!flags.Has("reenactment") && positional.size() == 1) return positional[0];
  return absl::InvalidArgumentError(
      absl::StrCat(command, " needs exactly one reenactment id (ID or --reenactment ID)"));
}

// What `reenactments show` tells of a body-model reenactment's BodyMesh.
struct BodyFacts {
  std::string model_name;
  std::vector<std::pair<std::string, double>> shape;  // (direction name, coefficient).
  int64_t vertices = 0, triangles = 0, texture_vertices = 0;
  int atlas_width = 0, atlas_height = 0;  // 0 when the atlas is missing or undecodable.
  int64_t atlas_bytes = 0;
  // The per-frame appearance video (AppearanceVideo); 0 bytes: none.
  int64_t appearance_bytes = 0;
  int appearance_size_px = 0, appearance_frames = 0;
  std::string appearance_codec;
};

BodyFacts FactsOf(const v1::BodyMesh& mesh) {
  BodyFacts facts;
  facts.model_name = mesh.model_name();
  for (int k = 0; k < mesh.shape_size(); ++k) {
    facts.shape.emplace_back(k < mesh.shape_names_size() ? mesh.shape_names(k) : "", mesh.shape(k));
  }
  facts.vertices = static_cast<int64_t>(mesh.rest_positions_m_f32().size() / (3 * sizeof(float)));
  facts.triangles = mesh.triangle_indices_size() / 3;
  facts.texture_vertices = mesh.texture_vertex_source_size();
  facts.atlas_bytes = static_cast<int64_t>(mesh.atlas_jpeg().size());
  if (auto atlas = DecodeJpeg(mesh.atlas_jpeg()); atlas.ok()) {
    facts.atlas_width = atlas->width;
    facts.atlas_height = atlas->height;
  }
  facts.appearance_bytes = static_cast<int64_t>(mesh.appearance().mp4().size());
  facts.appearance_size_px = mesh.appearance().size_px();
  facts.appearance_frames = mesh.appearance().frame_count();
  facts.appearance_codec = mesh.appearance().codec();
  return facts;
}

nlohmann::json BodyJson(const BodyFacts& facts) {
  nlohmann::json shape = nlohmann::json::object();
  for (const auto& [name, value] : facts.shape) shape[name] = value;
  return {{"model_name", facts.model_name},
          {"shape", shape},
          {"vertices", facts.vertices},
          {"triangles", facts.triangles},
          {"texture_vertices", facts.texture_vertices},
          {"atlas_width", facts.atlas_width},
          {"atlas_height", facts.atlas_height},
          {"atlas_bytes", facts.atlas_bytes},
          {"appearance_bytes", facts.appearance_bytes},
          {"appearance_size_px", facts.appearance_size_px},
          {"appearance_frames", facts.appearance_frames},
          {"appearance_codec", facts.appearance_codec}};
}

// The summary; for a body-model reenactment (`body` set) its model, shape,
// mesh and atlas instead of the part and keyframe counts.
void PrintSummary(const v1::ReenactmentSummary& s, const BodyFacts* body, std::ostream& out) {
  const v1::ReenactmentInfo& info = s.info();
  out << "reenactment " << info.reenactment_id() << "\n"
      << "take        " << info.take_id() << "\n"
      << "job         " << info.job_id() << "\n"
      << "method      " << info.method() << "\n"
      << "created     " << UtcTime(info.created_unix_ns()) << "\n"
      << "frames      " << info.frame_count()
      << absl::StrFormat(" at %.2f fps (%.3f s)", info.fps(), DurationS(info)) << "\n";
  if (body != nullptr) {
    out << "body model  " << body->model_name << "\n"
        << "shape      ";
    for (const auto& [name, value] : body->shape) out << absl::StrFormat(" %s=%.3f", name, value);
    out << (body->shape.empty() ? " (none)\n" : "\n")
        << absl::StrFormat("mesh        %d vertices, %d triangles, %d texture vertices\n",
                           body->vertices, body->triangles, body->texture_vertices)
        << absl::StrFormat("atlas       %d x %d JPEG (%s)\n", body->atlas_width, body->atlas_height,
                           HumanBytes(body->atlas_bytes));
    if (body->appearance_bytes > 0) {
      out << absl::StrFormat("appearance  %d frames of %d x %d, %s video (%s)\n",
                             body->appearance_frames, body->appearance_size_px,
                             body->appearance_size_px, body->appearance_codec,
                             HumanBytes(body->appearance_bytes));
    } else {
      out << "appearance  the static atlas alone\n";
    }
  } else {
    out << "parts       " << s.part_count() << "\n"
        << "keyframes   " << s.keyframe_count() << " from " << info.sensors_size()
        << " sensor(s)\n";
  }
  out << "size        " << HumanBytes(s.file_bytes()) << "\n"
      << "generator   " << TerminalSafe(info.generator()) << "\n";
  for (const auto& [key, value] : info.options()) {
    out << "option      " << TerminalSafe(key) << " = " << TerminalSafe(value) << "\n";
  }
  for (const auto& [key, value] : info.figures()) {
    out << "figure      " << TerminalSafe(key) << " = " << value << "\n";
  }
  PrintFitDiagnosis(info, out);
}

// `reenact export --format glb`: the .glb of `data` at `path`.
int ExportGlb(const Reenactment& data, const Flags& flags, const std::string& path,
              std::ostream& out, std::ostream& err) {
  GltfExportOptions options;
  options.textures = !flags.Has("no-textures");
  GltfExportSummary summary;
  const absl::Status written = WriteReenactmentGlb(data, path, options, &summary);
  if (!written.ok()) return ReportRemoteError(written, err);
  if (flags.Has("json")) {
    out << nlohmann::json{{"out", path},
                          {"format", "glb"},
                          {"reenactment_id", data.info.reenactment_id},
                          {"nodes", summary.nodes},
                          {"meshes", summary.meshes},
                          {"textures", summary.textures},
                          {"joints", summary.joints},
                          {"frames_offsets_left_out", summary.frames_offsets_left_out},
                          {"animation_channels", summary.animation_channels},
                          {"keys", summary.keys},
                          {"duration_s", summary.duration_s},
                          {"stamps_fell_back", summary.stamps_fell_back},
                          {"bytes", summary.bytes}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  out << "wrote " << path << " (" << HumanBytes(summary.bytes) << "): " << summary.BriefReport()
      << "\n";
  return kExitOk;
}

// The length unit of a BVH export (--units): metres by default, which
// Blender's importer and three.js's BVHLoader take at their default scale;
// centimetres for tools that expect them (MotionBuilder, CMU-style files).
struct BvhUnits {
  std::string name;  // "m" or "cm".
  double metres_per_unit = 1.0;
};

absl::StatusOr<BvhUnits> BvhUnitsFromFlags(const Flags& flags) {
  const std::string units = flags.GetOr("units", "m");
  if (units == "m") return BvhUnits{"m", 1.0};
  if (units == "cm") return BvhUnits{"cm", 0.01};
  return absl::InvalidArgumentError(
      absl::StrCat("--units ", units,
                   " is not supported (m: metres, Blender's default scale; cm: centimetres)"));
}

// `reenact export --format bvh`: the fitted skeleton of a body-model
// reenactment (BodyReenactmentMotion) as BVH, in --units.
int ExportBvh(const Reenactment& data, const Flags& flags, const std::string& path,
              std::ostream& out, std::ostream& err) {
  const absl::StatusOr<BvhUnits> units = BvhUnitsFromFlags(flags);
  if (!units.ok()) return ReportError(units.status(), err);
  if (!data.is_body()) {
    return ReportError(
        absl::InvalidArgumentError(absl::StrCat(
            "--format bvh needs a body-model reenactment; ", data.info.reenactment_id,
            " (method \"", data.info.method, "\") is made of rigid parts: use --format glb")),
        err);
  }
  auto motion = BodyReenactmentMotion(data);
  if (!motion.ok()) return ReportRemoteError(motion.status(), err);
  body::BvhWriteOptions options;
  options.metres_per_unit = units->metres_per_unit;
  const absl::Status written = body::WriteBvh(*motion, path, options);
  if (!written.ok()) return ReportRemoteError(written, err);
  std::error_code ec;
  const auto bytes = static_cast<int64_t>(std::filesystem::file_size(path, ec));
  if (flags.Has("json")) {
    out << nlohmann::json{{"out", path},
                          {"format", "bvh"},
                          {"reenactment_id", data.info.reenactment_id},
                          {"joints", motion->joints().size()},
                          {"frames", motion->num_frames()},
                          {"fps", motion->fps()},
                          {"units", units->name},
                          {"bytes", ec ? -1 : bytes}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  out << "wrote " << path << " (" << HumanBytes(ec ? 0 : bytes)
      << "): bvh: " << motion->joints().size() << " Kinect v2 joints, " << motion->num_frames()
      << absl::StrFormat(" frames at %.2f fps, %s", motion->fps(),
                         units->name == "m" ? "metres" : "centimetres")
      << "\n";
  return kExitOk;
}

// `reenact export --format appearance`: a body reenactment's per-frame
// appearance video as it is stored (frame i is the atlas of instant i, in the
// glb's texture layout), for tools that take a movie as a texture.
int ExportAppearance(const Reenactment& data, const Flags& flags, const std::string& path,
                     std::ostream& out, std::ostream& err) {
  if (!data.is_body() || data.body->appearance_mp4.empty()) {
    return ReportError(absl::NotFoundError(absl::StrCat(
                           "reenactment ", data.info.reenactment_id, " has no appearance video (",
                           data.is_body() ? "its body job ran with appearance=false, or was split"
                                          : "it is made of rigid parts",
                           "): its texture is the static one in --format glb")),
                       err);
  }
  const BodyMesh& body = *data.body;
  if (absl::Status written = WriteFileAtomically(path, body.appearance_mp4); !written.ok()) {
    return ReportError(written, err);
  }
  const auto bytes = static_cast<int64_t>(body.appearance_mp4.size());
  const double seconds = data.info.fps > 0 ? body.appearance_frame_count / data.info.fps : 0.0;
  if (flags.Has("json")) {
    out << nlohmann::json{{"out", path},
                          {"format", "appearance"},
                          {"reenactment_id", data.info.reenactment_id},
                          {"frames", body.appearance_frame_count},
                          {"fps", data.info.fps},
                          {"size_px", body.appearance_size_px},
                          {"codec", body.appearance_codec},
                          {"bytes", bytes}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  out << "wrote " << path << " (" << HumanBytes(bytes) << "): appearance video, "
      << body.appearance_frame_count << " frames of " << body.appearance_size_px << "x"
      << body.appearance_size_px
      << absl::StrFormat(" at %.2f fps (%.0f kB per second), ", data.info.fps,
                         seconds > 0 ? bytes / seconds / 1000 : 0.0)
      << body.appearance_codec << "; frame i is the texture of the glb's frame i\n";
  return kExitOk;
}

std::string EndReasonName(v1::FollowEndReason reason) {
  std::string name = v1::FollowEndReason_Name(reason);
  constexpr std::string_view kPrefix = "FOLLOW_END_REASON_";
  if (name.rfind(kPrefix, 0) == 0) name = name.substr(kPrefix.size());
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

nlohmann::json DistributionJson(const client::Distribution& d) {
  return {{"count", d.count},
          {"p50_ms", d.p50_ms},
          {"p95_ms", d.p95_ms},
          {"max_ms", d.max_ms},
          {"mean_ms", d.mean_ms}};
}

// One line (text or JSON) per Follow event.
void PrintFollowEvent(const v1::FollowEvent& event, int64_t received_unix_ns, bool json,
                      std::ostream& out) {
  if (event.has_mesh()) {
    const v1::BodyMesh& mesh = event.mesh();
    const int64_t vertices = static_cast<int64_t>(mesh.rest_positions_m_f32().size() / 12);
    if (json) {
      out << nlohmann::json{{"event", "mesh"},
                            {"model_name", mesh.model_name()},
                            {"vertices", vertices},
                            {"triangles", mesh.triangle_indices_size() / 3},
                            {"shape",
                             std::vector<double>(mesh.shape().begin(), mesh.shape().end())}}
                 .dump();
    } else {
      out << absl::StrFormat("mesh   %s, %d vertices, %d triangles", mesh.model_name(), vertices,
                             mesh.triangle_indices_size() / 3);
    }
  } else if (event.has_frame()) {
    const v1::PartFrame& frame = event.frame();
    const double latency_ms = client::LatencyMs(event);
    const double receive_ms = client::ReceiveDelayMs(event, received_unix_ns);
    if (json) {
      out << nlohmann::json{{"event", "frame"},
                            {"frame_index", frame.frame_index()},
                            {"sequence", event.sequence()},
                            {"stamp_ns", frame.stamp_ns()},
                            {"latency_ms", latency_ms},
                            {"receive_ms", receive_ms},
                            {"fit_ms", event.fit_ms()},
                            {"frames_skipped", event.frames_skipped()},
                            {"joints", frame.joints_in_world_m_size()},
                            {"valid", frame.body().valid()}}
                 .dump();
    } else {
      out << absl::StrFormat(
          "frame %5d  set %6d  latency %6.1f ms  received %6.1f ms  fit %5.1f ms",
          frame.frame_index(), event.sequence(), latency_ms, receive_ms, event.fit_ms());
    }
  } else if (event.has_end()) {
    const v1::FollowEnd& end = event.end();
    if (json) {
      out << nlohmann::json{{"event", "end"},
                            {"reason", EndReasonName(end.reason())},
                            {"message", end.message()},
                            {"frames_received", end.frames_received()},
                            {"frames_followed", end.frames_followed()},
                            {"frames_skipped", end.frames_skipped()},
                            {"frames_unfitted", end.frames_unfitted()}}
                 .dump();
    } else {
      out << absl::StrFormat(
          "end    %s: %s (followed %d of %d frame sets, %d skipped, %d unfitted)",
          EndReasonName(end.reason()), end.message(), end.frames_followed(), end.frames_received(),
          end.frames_skipped(), end.frames_unfitted());
    }
  } else {
    return;
  }
  out << "\n" << std::flush;
}

void PrintFollowSummary(const client::FollowStats& stats, bool json, std::ostream& out) {
  const client::Distribution latency = stats.latency();
  const client::Distribution receive = stats.receive_delay();
  const client::Distribution fit = stats.fit();
  if (json) {
    out << nlohmann::json{{"summary",
                           {{"frames", stats.frames()},
                            {"latency", DistributionJson(latency)},
                            {"receive", DistributionJson(receive)},
                            {"fit", DistributionJson(fit)}}}}
               .dump()
        << "\n";
    return;
  }
  out << absl::StrFormat(
      "%d frames; latency (published - arrived) p50 %.1f ms, p95 %.1f ms, max %.1f ms; "
      "received - arrived p50 %.1f ms, p95 %.1f ms, max %.1f ms; fit p50 %.1f ms\n",
      stats.frames(), latency.p50_ms, latency.p95_ms, latency.max_ms, receive.p50_ms,
      receive.p95_ms, receive.max_ms, fit.p50_ms);
}

}  // namespace

int RunReenactmentsList(const std::vector<std::string>& args, std::ostream& out,
                        std::ostream& err) {
  auto flags = Flags::Parse(
      args, {"server", "timeout", "tls-ca", "token-file", "take", "page-size"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("reenactments list takes no arguments"), err);
  }
  auto page_size = flags->GetInt("page-size", 0);
  if (!page_size.ok()) return ReportError(page_size.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto listed = client::ReenactmentsClient(*connection).List(flags->GetOr("take", ""), *page_size);
  if (!listed.ok()) return ReportRemoteError(listed.status(), err);
  if (flags->Has("json")) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& s : *listed) j.push_back(SummaryJson(s));
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  out << absl::StrFormat("%-28s %-36s %-16s %7s %9s %9s %10s  %s\n", "REENACTMENT", "TAKE",
                         "METHOD", "FRAMES", "SECONDS", "KEYFRAMES", "SIZE", "CREATED (UTC)");
  for (const auto& s : *listed) {
    out << absl::StrFormat("%-28s %-36s %-16s %7d %9.2f %9d %10s  %s\n", s.info().reenactment_id(),
                           s.info().take_id(), s.info().method(), s.info().frame_count(),
                           DurationS(s.info()), s.keyframe_count(), HumanBytes(s.file_bytes()),
                           UtcTime(s.info().created_unix_ns()));
  }
  if (listed->empty()) out << "(no reenactments)\n";
  return kExitOk;
}

int RunReenactmentsShow(const std::vector<std::string>& args, std::ostream& out,
                        std::ostream& err) {
  auto flags =
      Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "reenactment"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto id = ReenactmentId(*flags, "reenactments show");
  if (!id.ok()) return ReportError(id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const client::ReenactmentsClient client(*connection);
  auto summary = client.Get(*id);
  if (!summary.ok()) return ReportRemoteError(summary.status(), err);
  std::optional<BodyFacts> body;
  if (summary->part_count() == 0) {  // Body-model reenactments have no parts.
    auto mesh = client.FetchBodyMesh(*id);
    if (mesh.ok()) {
      body = FactsOf(*mesh);
    } else if (mesh.status().code() != absl::StatusCode::kFailedPrecondition) {
      return ReportRemoteError(mesh.status(), err);
    }
  }
  if (flags->Has("json")) {
    nlohmann::json j = SummaryJson(*summary);
    if (body.has_value()) j["body"] = BodyJson(*body);
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  PrintSummary(*summary, body.has_value() ? &*body : nullptr, out);
  return kExitOk;
}

int RunReenactmentsDelete(const std::vector<std::string>& args, std::ostream& out,
                          std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "reenactment"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto id = ReenactmentId(*flags, "reenactments delete");
  if (!id.ok()) return ReportError(id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const absl::Status deleted = client::ReenactmentsClient(*connection).Delete(*id);
  if (!deleted.ok()) return ReportRemoteError(deleted, err);
  out << "deleted " << *id << "\n";
  return kExitOk;
}

int RunReenactmentsFollow(const std::vector<std::string>& args, std::ostream& out,
                          std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "job"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto job = flags->Required("job");
  if (!job.ok()) return ReportError(job.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("reenactments follow takes --job ID only"), err);
  }
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const bool json = flags->Has("json");
  client::FollowStats stats;
  auto end =
      client::ReenactmentsClient(*connection).Follow(*job, [&](const v1::FollowEvent& event) {
        const int64_t received_unix_ns = WallNowNs();
        stats.Add(event, received_unix_ns);
        PrintFollowEvent(event, received_unix_ns, json, out);
        return true;
      });
  PrintFollowSummary(stats, json, out);
  if (!end.ok()) return ReportRemoteError(end.status(), err);
  return kExitOk;
}

int RunExport(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(
      args,
      {"server", "timeout", "tls-ca", "token-file", "reenactment", "in", "format", "out", "units"},
      {"no-textures", "quiet", "json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto out_path = flags->Required("out");
  if (!out_path.ok()) return ReportError(out_path.status(), err);
  const std::string format = flags->GetOr("format", "glb");
  if (flags->Has("units") && format != "bvh") {
    return ReportError(absl::InvalidArgumentError("--units applies to --format bvh alone"), err);
  }
  if (format == "bvh") {
    // Before the fetch: a bad unit costs no download.
    if (const auto units = BvhUnitsFromFlags(*flags); !units.ok()) {
      return ReportError(units.status(), err);
    }
  }
  if (format != "glb" && format != "bvh" && format != "appearance") {
    return ReportError(absl::InvalidArgumentError(absl::StrCat(
                           "--format ", format,
                           " is not supported (glb: glTF 2.0 binary; bvh: the fitted skeleton "
                           "of a body-model reenactment; appearance: its per-frame texture "
                           "video, MP4)")),
                       err);
  }
  if (!flags->positional().empty() || flags->Has("in") == flags->Has("reenactment") ||
      (flags->Has("in") && flags->Has("server"))) {
    return ReportError(absl::InvalidArgumentError(
                           "export needs either --server HOST:PORT --reenactment ID or --in "
                           "FILE.reen"),
                       err);
  }
  absl::StatusOr<Reenactment> data;
  if (flags->Has("in")) {
    data = ReadReenactment(*flags->Get("in"), /*skip_keyframes=*/true);
    if (!data.ok()) return ReportRemoteError(data.status(), err);
  } else {
    auto connection = ConnectionFromFlags(*flags);
    if (!connection.ok()) return ReportError(connection.status(), err);
    // The baked textures are in the part meshes; keyframes are not needed.
    ProgressBar bar(err, !flags->Has("quiet") && !flags->Has("json"));
    data = client::ReenactmentsClient(*connection)
               .Fetch(*flags->Get("reenactment"), /*skip_keyframes=*/true, bar.AsCallback());
    bar.Finish();
    if (!data.ok()) return ReportRemoteError(data.status(), err);
  }
  if (format == "bvh") return ExportBvh(*data, *flags, *out_path, out, err);
  if (format == "appearance") return ExportAppearance(*data, *flags, *out_path, out, err);
  return ExportGlb(*data, *flags, *out_path, out, err);
}

}  // namespace reenact::cli
