#include "capture_daemon/sensor_factory.h"

#include <fstream>
#include <set>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace reenact::capture
