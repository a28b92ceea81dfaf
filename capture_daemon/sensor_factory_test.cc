#include "capture_daemon/sensor_factory.h"

#include <filesystem>
#include <fstream>
#include <set>

#include <gtest/gtest.h>

#include "capture_daemon/sensors/source_backends.h"
#include "common/io/testing/small_take.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

TEST(ParseSourceSpecs, SplitsListsAndDefaults) {
  auto specs = ParseSourceSpecs({"playback:a.mcap,freenect", "openni2", "freenect2:123"});
  ASSERT_TRUE(specs.ok()) << specs.status();
  ASSERT_EQ(specs->size(), 4u);
  EXPECT_EQ((*specs)[0].ToString(), "playback:a.mcap");
  EXPECT_EQ((*specs)[1].ToString(), "freenect:all");
  EXPECT_EQ((*specs)[2].ToString(), "openni2:any");
  EXPECT_EQ((*specs)[3].ToString(), "freenect2:123");
}

TEST(ParseSourceSpecs, RejectsBadSpecs) {
  EXPECT_TRUE(absl::IsInvalidArgument(ParseSourceSpecs({"playback:"}).status()));
  EXPECT_TRUE(absl::IsInvalidArgument(ParseSourceSpecs({"webcam:0"}).status()));
  EXPECT_TRUE(absl::IsInvalidArgument(ParseSourceSpecs({}).status()));
  const absl::Status s = ParseSourceSpecs({"kinect:0"}).status();
  EXPECT_NE(s.message().find("kinect:0"), std::string::npos) << s;
  // The error lists every backend of the table.
  for (const SourceBackend& backend : SourceBackends()) {
    EXPECT_NE(s.message().find(backend.syntax), std::string::npos) << backend.name << ": " << s;
  }
  // A spec that never went through the parser is refused, not opened by
  // some other backend.
  const absl::Status unknown = OpenSources({{"webcam", "0"}}, {}).status();
  EXPECT_TRUE(absl::IsInvalidArgument(unknown)) << unknown;
  EXPECT_NE(unknown.message().find("unknown backend"), std::string::npos) << unknown;
}

TEST(OpenSources, PlaybackIdsStayUniqueAcrossSources) {
  const std::string dir = reenact::testing::MakeTempDir("factory");
  const std::string take = dir + "/take.mcap";
  reenact::testing::WriteTestTake(take, 2, 3);
  auto specs = ParseSourceSpecs({"playback:" + take, "playback:" + take});
  ASSERT_TRUE(specs.ok());
  auto sensors = OpenSources(*specs, {});
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  ASSERT_EQ(sensors->size(), 4u);
  std::set<std::string> ids;
  for (const auto& sensor : *sensors) {
    const v1::SensorInfo info = sensor->info();
    ids.insert(info.sensor_id());
    EXPECT_EQ(info.backend(), "playback");
    EXPECT_EQ(info.calibration().sensor_id(), info.sensor_id());
    EXPECT_TRUE(info.provides_mask());
    EXPECT_TRUE(info.provides_skeleton());
    EXPECT_EQ(info.depth_width_px(), 16);
  }
  EXPECT_EQ(ids, (std::set<std::string>{"k0", "k1", "p1-0", "p1-1"}));
}

TEST(OpenSources, ErrorsNameTheSource) {
  auto missing = OpenSources({{"playback", "/no/such/take.mcap"}}, {});
  EXPECT_TRUE(absl::IsNotFound(missing.status())) << missing.status();
  EXPECT_NE(missing.status().message().find("playback:/no/such/take.mcap"), std::string::npos);
  const std::string dir = reenact::testing::MakeTempDir("factory_bad");
  const std::string junk = dir + "/junk.mcap";
  std::ofstream(junk) << "not a take";
  EXPECT_TRUE(absl::IsInvalidArgument(OpenSources({{"playback", junk}}, {}).status()));
}

TEST(ParseSourceSpecs, RecordingsNeedAPath) {
  auto specs = ParseSourceSpecs({"azure-mkv:a.mkv,tum:dir", "oni:b.oni"});
  ASSERT_TRUE(specs.ok()) << specs.status();
  ASSERT_EQ(specs->size(), 3u);
  EXPECT_EQ((*specs)[1].ToString(), "tum:dir");
  for (const char* bad : {"azure-mkv", "tum:", "oni"}) {
    const absl::Status s = ParseSourceSpecs({bad}).status();
    EXPECT_TRUE(absl::IsInvalidArgument(s)) << bad;
    EXPECT_NE(s.message().find("needs a"), std::string::npos) << s;
  }
}

TEST(OpenSources, TumRecordingsTakeKinectIdsPastThoseTaken) {
  const std::string dir = reenact::testing::MakeTempDir("factory_tum");
  const std::string take = dir + "/take.mcap";
  reenact::testing::WriteTestTake(take, 2, 3);
  // A TUM folder of one frame.
  std::filesystem::create_directories(dir + "/tum");
  // A 1x1 16-bit grey PNG holding 7500 (1500 mm at 5000 units per metre).
  const unsigned char png[] = {
      0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48,
      0x44, 0x52, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x10, 0x00, 0x00, 0x00,
      0x00, 0x6a, 0xee, 0x47, 0x16, 0x00, 0x00, 0x00, 0x0b, 0x49, 0x44, 0x41, 0x54, 0x78,
      0x9c, 0x63, 0x90, 0xf5, 0x01, 0x00, 0x00, 0x89, 0x00, 0x6a, 0x07, 0xa8, 0x82, 0x91,
      0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
  std::ofstream(dir + "/tum/d.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(png), sizeof(png));
  std::ofstream(dir + "/tum/depth.txt") << "1.0 d.png\n";
  auto sensors = OpenSources({{"playback", take}, {"tum", dir + "/tum"}}, {});
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  ASSERT_EQ(sensors->size(), 3u);
  const v1::SensorInfo info = (*sensors)[2]->info();
  EXPECT_EQ(info.sensor_id(), "k2");
  EXPECT_EQ(info.backend(), "tum");
  EXPECT_EQ(info.depth_width_px(), 1);
  auto missing = OpenSources({{"azure-mkv", "/no/such.mkv"}}, {});
  EXPECT_TRUE(absl::IsNotFound(missing.status())) << missing.status();
  EXPECT_NE(missing.status().message().find("azure-mkv:/no/such.mkv"), std::string::npos);
}

}  // namespace
}  // namespace reenact::capture
