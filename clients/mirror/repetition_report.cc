#include "clients/mirror/repetition_report.h"

#include <filesystem>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact::mirror {
namespace {

using Json = nlohmann::json;

Json OptionalNumber(const std::optional<double>& value) {
  return value ? Json(*value) : Json(nullptr);
}

std::string CsvNumber(const std::optional<double>& value) {
  return value ? absl::StrFormat("%.3f", *value) : std::string();
}

std::string CsvRow(const ComparedFrame& frame) {
  std::string row =
      absl::StrFormat("%.4f,%d,%d", frame.time_s, frame.teacher_frame, frame.learner_stamp_ns);
  for (const std::optional<double>& error_deg : frame.comparison.part_error_deg) {
    absl::StrAppend(&row, ",", CsvNumber(error_deg));
  }
  absl::StrAppend(&row, ",", CsvNumber(frame.comparison.mean_error_deg), "\n");
  return row;
}

Json PartsJson(const PerPart<double>& part_mean_error_deg) {
  Json parts = Json::object();
  for (int p = 0; p < kNumBodyParts; ++p) {
    parts[std::string(BodyPartName(BodyPartAt(p)))] = OptionalNumber(part_mean_error_deg[p]);
  }
  return parts;
}

}  // namespace

void SummarizeErrors(RepetitionReport& report) {
  std::array<double, kNumBodyParts> part_sum{};
  std::array<int, kNumBodyParts> part_count{};
  double mean_sum = 0.0;
  int mean_count = 0;
  for (const ComparedFrame& frame : report.frames) {
    for (int p = 0; p < kNumBodyParts; ++p) {
      if (!frame.comparison.part_error_deg[p]) continue;
      part_sum[p] += *frame.comparison.part_error_deg[p];
      ++part_count[p];
    }
    if (!frame.comparison.mean_error_deg) continue;
    mean_sum += *frame.comparison.mean_error_deg;
    ++mean_count;
  }
  for (int p = 0; p < kNumBodyParts; ++p) {
    report.part_mean_error_deg[p] =
        part_count[p] > 0 ? std::optional<double>(part_sum[p] / part_count[p]) : std::nullopt;
  }
  report.mean_error_deg =
      mean_count > 0 ? std::optional<double>(mean_sum / mean_count) : std::nullopt;
  int compared = 0;
  for (const int n : part_count) compared += n;
  report.coverage = report.frames.empty()
                        ? 0.0
                        : static_cast<double>(compared) /
                              (static_cast<double>(report.frames.size()) * kNumBodyParts);
}

std::string RepetitionCsv(const RepetitionReport& report) {
  std::string csv = "time_s,teacher_frame,learner_stamp_ns";
  for (int p = 0; p < kNumBodyParts; ++p)
    absl::StrAppend(&csv, ",", std::string(BodyPartName(BodyPartAt(p))));
  absl::StrAppend(&csv, ",mean_error_deg\n");
  for (const ComparedFrame& frame : report.frames) absl::StrAppend(&csv, CsvRow(frame));
  return csv;
}

std::string RepetitionJson(const RepetitionReport& report) {
  const std::string stem = RepetitionFileStem(report.repetition);
  Json json = {
      {"repetition", report.repetition},
      {"mean_error_deg", OptionalNumber(report.mean_error_deg)},
      {"coverage", report.coverage},
      {"parts", PartsJson(report.part_mean_error_deg)},
      {"learner_facing_yaw_deg", OptionalNumber(report.learner_facing_yaw_deg)},
      {"view_yaw_deg", report.view_yaw_deg},
      {"teacher_turn_yaw_deg", report.teacher_turn_yaw_deg},
      {"teacher_facing_yaw_world_deg", report.teacher_facing_yaw_world_deg},
      {"challenge", report.challenge},
      {"dtw", report.used_dtw},
      {"playback_speed", report.playback_speed},
      {"start_stamp_ns", report.start_stamp_ns},
      {"end_stamp_ns", report.end_stamp_ns},
      {"duration_s", (report.end_stamp_ns - report.start_stamp_ns) * 1e-9},
      {"num_learner_frames", report.num_learner_frames},
      {"frames_without_learner", report.frames_without_learner},
      {"frames_with_several_people", report.frames_with_several_people},
      {"teacher_frames_without_skeleton", report.teacher_frames_without_skeleton},
      {"num_teacher_frames", report.num_teacher_frames},
      {"complete", report.complete},
      {"teacher_frames_played", report.teacher_frames_played},
      {"num_compared_frames", static_cast<int>(report.frames.size())},
      {"input_problems", InputProblems(report)},
      {"files", {{"csv", stem + ".csv"}, {"png", stem + ".png"}}},
  };
  if (report.grade) {
    json["grade"] = Json::parse(GradeJson(*report.grade));
    json["files"]["heatmap"] = stem + "-heatmap.png";
    json["files"]["worst_moments"] = stem + "-worst.png";
  }
  return json.dump(2) + "\n";
}

std::vector<std::string> InputProblems(const RepetitionReport& report) {
  std::vector<std::string> problems;
  const int received = report.num_learner_frames + report.frames_without_learner;
  if (report.frames_without_learner > 0) {
    problems.push_back(absl::StrFormat(
        "the learner was not seen in %d of %d frames (out of view, or no depth from the sensor): "
        "those frames are not graded",
        report.frames_without_learner, received));
  }
  if (report.frames_with_several_people > 0) {
    problems.push_back(absl::StrFormat(
        "%d of %d frames had more than one person in view: the one with the most joints tracked "
        "was graded",
        report.frames_with_several_people, received));
  }
  if (report.teacher_frames_without_skeleton > 0) {
    problems.push_back(absl::StrFormat(
        "the teacher has no skeleton in %d of %d frames: nothing is graded against them",
        report.teacher_frames_without_skeleton, report.teacher_frames_played));
  }
  return problems;
}

std::string RepetitionFileStem(int repetition) { return absl::StrFormat("rep-%03d", repetition); }

absl::StatusOr<RepetitionFiles> WriteRepetitionReport(const RepetitionReport& report,
                                                      const std::string& report_dir) {
  RETURN_IF_ERROR(CreateDirectories(report_dir));
  const std::filesystem::path stem =
      std::filesystem::path(report_dir) / RepetitionFileStem(report.repetition);
  RepetitionFiles files{stem.string() + ".csv", stem.string() + ".json", stem.string() + ".png", "",
                        ""};
  ASSIGN_OR_RETURN(const std::string png, RepetitionPlotPng(report));
  // The JSON goes last: a reader that sees it finds the others in place.
  RETURN_IF_ERROR(WriteFileAtomically(files.csv_path, RepetitionCsv(report)));
  RETURN_IF_ERROR(WriteFileAtomically(files.png_path, png));
  if (report.grade) {
    files.heatmap_path = stem.string() + "-heatmap.png";
    files.worst_path = stem.string() + "-worst.png";
    ASSIGN_OR_RETURN(const std::string heat, GradeHeatMapPng(*report.grade));
    RETURN_IF_ERROR(WriteFileAtomically(files.heatmap_path, heat));
    if (report.teacher_frames) {
      ASSIGN_OR_RETURN(
          const std::string worst,
          WorstMomentsPng(*report.grade, *report.teacher_frames, report.learner_frames));
      RETURN_IF_ERROR(WriteFileAtomically(files.worst_path, worst));
    } else {
      files.worst_path.clear();
    }
  }
  RETURN_IF_ERROR(WriteFileAtomically(files.json_path, RepetitionJson(report)));
  return files;
}

}  // namespace reenact::mirror
