#include "clients/mirror/repetition_report.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/base/files.h"
#include "common/testing/test_data.h"

namespace reenact::mirror {
namespace {

RepetitionReport SmallReport() {
  RepetitionReport report;
  report.repetition = 7;
  report.num_teacher_frames = 3;
  report.num_learner_frames = 3;
  report.end_stamp_ns = 66'666'666;
  for (int f = 0; f < 3; ++f) {
    ComparedFrame frame{f / 30.0, f, f * 33'333'333, {}};
    frame.comparison.part_error_deg[Index(BodyPart::kRightLowerArm)] = 10.0 * (f + 1);
    frame.comparison.part_error_deg[Index(BodyPart::kHead)] = 2.0;
    frame.comparison.mean_error_deg = (10.0 * (f + 1) + 2.0) / 2.0;
    frame.comparison.num_parts_compared = 2;
    report.frames.push_back(frame);
  }
  SummarizeErrors(report);
  return report;
}

TEST(SummarizeErrors, MeansPerPartAndOverFrames) {
  const RepetitionReport report = SmallReport();
  EXPECT_DOUBLE_EQ(*report.part_mean_error_deg[Index(BodyPart::kRightLowerArm)], 20.0);
  EXPECT_DOUBLE_EQ(*report.part_mean_error_deg[Index(BodyPart::kHead)], 2.0);
  EXPECT_FALSE(report.part_mean_error_deg[Index(BodyPart::kTorso)]);
  EXPECT_DOUBLE_EQ(*report.mean_error_deg, 11.0);
}

TEST(WriteRepetitionReport, WritesCsvJsonAndPng) {
  const std::string dir = reenact::testing::MakeTempDir("mirror_report") + "/reports";
  absl::StatusOr<RepetitionFiles> files = WriteRepetitionReport(SmallReport(), dir);
  ASSERT_TRUE(files.ok()) << files.status();
  EXPECT_EQ(std::filesystem::path(files->json_path).filename(), "rep-007.json");
  const std::string csv = *ReadFileToString(files->csv_path);
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "time_s,teacher_frame,learner_stamp_ns,head,left_shoulder,right_shoulder,"
            "left_upper_arm,right_upper_arm,left_lower_arm,right_lower_arm,torso,abdomen,"
            "left_upper_leg,right_upper_leg,left_lower_leg,right_lower_leg,mean_error_deg");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 4);
  const nlohmann::json json = nlohmann::json::parse(*ReadFileToString(files->json_path));
  EXPECT_DOUBLE_EQ(json["mean_error_deg"].get<double>(), 11.0);
  EXPECT_DOUBLE_EQ(json["parts"]["right_lower_arm"].get<double>(), 20.0);
  EXPECT_TRUE(json["parts"]["torso"].is_null());
  EXPECT_EQ(json["num_compared_frames"].get<int>(), 3);
  const std::string png = *ReadFileToString(files->png_path);
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    EXPECT_NE(entry.path().extension(), ".tmp") << entry.path();
  }
}

TEST(WriteRepetitionReport, UnwritableFolderIsAnError) {
  const std::string dir = reenact::testing::MakeTempDir("mirror_report_bad");
  const std::string file = dir + "/a_file";
  std::ofstream(file) << "x";
  const absl::StatusOr<RepetitionFiles> files =
      WriteRepetitionReport(SmallReport(), file + "/reports");
  EXPECT_FALSE(files.ok());
  std::cout << "report into a folder under a file: " << files.status() << "\n";
}

TEST(RepetitionPlotPng, DrawsAnEmptyRepetition) {
  RepetitionReport empty;
  empty.repetition = 1;
  absl::StatusOr<std::string> png = RepetitionPlotPng(empty);
  ASSERT_TRUE(png.ok());
  EXPECT_GT(png->size(), 1000u);
}

}  // namespace
}  // namespace reenact::mirror
