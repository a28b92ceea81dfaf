// Test-only: small hand-made takes for the server's tests. Frame sets carry
// real encodings (RVL depth that decodes, JPEG colour, RLE mask, a
// skeleton) at 32x24 px so that streams of many sets stay fast.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/base/image.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/take.h"
#include "reenact/v1/frame.pb.h"
#include "reenact/v1/ingest_service.pb.h"

#include <gtest/gtest.h>

namespace reenact::server::testing {

inline constexpr int kWidthPx = 32;
inline constexpr int kHeightPx = 24;
inline constexpr int64_t kPeriodNs = 33'333'333;
inline constexpr int64_t kStartNs = 1'000'000'000;

inline v1::SensorCalibration TestSensor(const std::string& id) {
  v1::SensorCalibration c;
  c.set_sensor_id(id);
  c.set_model("kinect_v2_synthetic");
  for (v1::CameraIntrinsics* in : {c.mutable_depth_intrinsics(), c.mutable_color_intrinsics()}) {
    in->set_width_px(kWidthPx);
    in->set_height_px(kHeightPx);
    in->set_fx_px(30.0);
    in->set_fy_px(30.0);
    in->set_cx_px(15.5);
    in->set_cy_px(11.5);
  }
  c.mutable_world_from_depth()->mutable_rotation()->set_w(1.0);
  c.mutable_color_from_depth()->mutable_rotation()->set_w(1.0);
  c.set_depth_scale_m_per_unit(0.001);
  c.set_nominal_fps(30.0);
  return c;
}

inline std::vector<std::string> SensorIds(int count) {
  std::vector<std::string> ids;
  ids.reserve(count);
  for (int i = 0; i < count; ++i) ids.push_back("k" + std::to_string(i));
  return ids;
}

inline v1::OpenTake MakeOpenTake(const std::string& take_id, const std::string& daemon_id,
                                 int sensor_count) {
  v1::OpenTake open;
  open.set_take_id(take_id);
  open.set_daemon_id(daemon_id);
  v1::TakeInfo* info = open.mutable_info();
  info->set_name("test-" + take_id);
  info->set_generator("server test");
  info->set_sensor_count(sensor_count);
  info->set_fps(30.0);
  info->set_start_stamp_ns(kStartNs);
  for (const std::string& id : SensorIds(sensor_count)) *open.add_sensors() = TestSensor(id);
  return open;
}

// Depth that differs per sequence and sensor, with a hole.
inline DepthImageMm TestDepth(uint64_t sequence, int sensor) {
  DepthImageMm depth(kWidthPx, kHeightPx);
  for (int y = 0; y < kHeightPx; ++y) {
    for (int x = 0; x < kWidthPx; ++x) {
      depth.at(x, y) =
          (x < 3 && y < 3)
              ? 0
              : static_cast<uint16_t>(1500 + 7 * sequence + 100 * sensor + 3 * x + 5 * y);
    }
  }
  return depth;
}

// Frame set `sequence` with one frame per id in `sensor_ids`; sensor i
// encodes depth as "rvl" when i is even, "rvl+zstd" when odd.
inline v1::FrameSet MakeFrameSet(uint64_t sequence, const std::vector<std::string>& sensor_ids) {
  static const std::string jpeg = *EncodeJpeg(RgbImage(kWidthPx, kHeightPx, 90), 80);
  v1::FrameSet set;
  set.set_sequence(sequence);
  const int64_t stamp_ns = kStartNs + static_cast<int64_t>(sequence - 1) * kPeriodNs;
  set.set_stamp_ns(stamp_ns);
  for (size_t i = 0; i < sensor_ids.size(); ++i) {
    v1::Frame* f = set.add_frames();
    f->set_sensor_id(sensor_ids[i]);
    f->set_device_stamp_ns(static_cast<int64_t>(sequence) * kPeriodNs);
    f->set_host_stamp_ns(stamp_ns + static_cast<int64_t>(i) * 1000);
    f->set_frame_index(static_cast<int64_t>(sequence) - 1);
    auto header = [&](auto* m) {
      m->set_sensor_id(f->sensor_id());
      m->set_device_stamp_ns(f->device_stamp_ns());
      m->set_host_stamp_ns(f->host_stamp_ns());
      m->set_frame_index(f->frame_index());
    };
    v1::DepthImage* depth = f->mutable_depth();
    header(depth);
    depth->set_width_px(kWidthPx);
    depth->set_height_px(kHeightPx);
    const bool zstd = i % 2 == 1;
    depth->set_encoding(zstd ? "rvl+zstd" : "rvl");
    depth->set_data(
        *EncodeDepth(TestDepth(sequence, static_cast<int>(i)), DepthCodecOptions{.zstd = zstd}));
    v1::ColorImage* color = f->mutable_color();
    header(color);
    color->set_width_px(kWidthPx);
    color->set_height_px(kHeightPx);
    color->set_encoding("jpeg");
    color->set_quality(80);
    color->set_data(jpeg);
    v1::ActorMask* mask = f->mutable_mask();
    header(mask);
    mask->set_width_px(kWidthPx);
    mask->set_height_px(kHeightPx);
    mask->set_encoding("rle");
    MaskImage mask_image(kWidthPx, kHeightPx);
    mask_image.at(static_cast<int>(sequence % kWidthPx), 5) = 1;
    mask->set_data(EncodeMaskRle(mask_image));
    v1::Skeleton* skeleton = f->add_skeletons();
    header(skeleton);
    skeleton->set_body_index(1);
    v1::Joint* joint = skeleton->add_joints();
    joint->set_name("SpineBase");
    joint->mutable_position_in_depth_m()->set_z(2.0 + 0.001 * static_cast<double>(sequence));
    joint->set_tracking_state(v1::TRACKING_STATE_TRACKED);
  }
  set.set_skew_ns(sensor_ids.size() > 1 ? static_cast<int64_t>(sensor_ids.size() - 1) * 1000 : 0);
  return set;
}

// Checks that the take file at `path` holds frame sets 1..`last` of
// MakeFrameSet(.., ids) exactly once: FrameSetRecords 1..last in order, and
// per sensor the depth, colour, mask and skeleton messages byte for byte.
inline void ExpectStoredFrameSets(const std::string& path, const std::vector<std::string>& ids,
                                  uint64_t last) {
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_TRUE((*reader)->report().complete) << (*reader)->report().Summary();
  auto records = (*reader)->ReadAll<v1::FrameSetRecord>(kIngestFrameSetTopic);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), last);
  for (uint64_t s = 1; s <= last; ++s) {
    EXPECT_EQ((*records)[s - 1].sequence(), s);
    EXPECT_EQ((*records)[s - 1].sensor_ids_size(), static_cast<int>(ids.size()));
  }
  for (size_t i = 0; i < ids.size(); ++i) {
    auto depth = (*reader)->ReadAll<v1::DepthImage>(SensorTopic(ids[i], "depth"));
    auto color = (*reader)->ReadAll<v1::ColorImage>(SensorTopic(ids[i], "color"));
    auto mask = (*reader)->ReadAll<v1::ActorMask>(SensorTopic(ids[i], "mask"));
    auto skeleton = (*reader)->ReadAll<v1::Skeleton>(SensorTopic(ids[i], "skeleton"));
    ASSERT_TRUE(depth.ok() && color.ok() && mask.ok() && skeleton.ok());
    ASSERT_EQ(depth->size(), last) << ids[i];
    ASSERT_EQ(color->size(), last) << ids[i];
    ASSERT_EQ(mask->size(), last) << ids[i];
    ASSERT_EQ(skeleton->size(), last) << ids[i];
    for (uint64_t s = 1; s <= last; ++s) {
      const v1::Frame sent = MakeFrameSet(s, ids).frames(static_cast<int>(i));
      EXPECT_EQ((*depth)[s - 1].data(), sent.depth().data()) << ids[i] << " set " << s;
      EXPECT_EQ((*depth)[s - 1].SerializeAsString(), sent.depth().SerializeAsString());
      EXPECT_EQ((*color)[s - 1].SerializeAsString(), sent.color().SerializeAsString());
      EXPECT_EQ((*mask)[s - 1].SerializeAsString(), sent.mask().SerializeAsString());
      EXPECT_EQ((*skeleton)[s - 1].SerializeAsString(), sent.skeletons(0).SerializeAsString());
    }
  }
}

}  // namespace reenact::server::testing
