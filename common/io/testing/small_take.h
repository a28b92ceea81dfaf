// Test-only: builds a small synthetic take with every channel filled, and
// keeps what was written so tests can compare a reader's output with it.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/take.h"

namespace reenact::testing {

// Every message written to a take, serialized, by topic, in write order.
struct WrittenTake {
  v1::TakeInfo info;
  std::map<std::string, std::vector<std::string>> messages_by_topic;
  int frames = 0;
  int64_t period_ns = 0;
};

inline v1::SensorCalibration TestCalibration(const std::string& id, double x_m) {
  v1::SensorCalibration c;
  c.set_sensor_id(id);
  c.set_model("kinect_v2_synthetic");
  auto* depth = c.mutable_depth_intrinsics();
  depth->set_width_px(16);
  depth->set_height_px(12);
  depth->set_fx_px(365.0);
  depth->set_fy_px(365.0);
  depth->set_cx_px(7.5);
  depth->set_cy_px(5.5);
  *c.mutable_color_intrinsics() = *depth;
  c.mutable_color_from_depth()->mutable_rotation()->set_w(1.0);
  c.mutable_world_from_depth()->mutable_rotation()->set_w(1.0);
  c.mutable_world_from_depth()->mutable_translation_m()->set_x(x_m);
  c.set_depth_scale_m_per_unit(0.001);
  c.set_nominal_fps(30.0);
  return c;
}

// Writes a take of `sensor_count` sensors x `frames` frames with every sensor
// and ground-truth channel to `path`.
inline WrittenTake WriteTestTake(const std::string& path, int sensor_count, int frames,
                                 const TakeWriterOptions& options = {}) {
  WrittenTake out;
  out.frames = frames;
  out.period_ns = 33'333'333;
  const int64_t start_ns = 5'000'000'000;
  out.info.set_name("test-take");
  out.info.set_generator("testing/small_take");
  out.info.set_sensor_count(sensor_count);
  out.info.set_fps(30.0);
  out.info.set_start_stamp_ns(start_ns);
  out.info.set_synthetic(true);
  auto writer = TakeWriter::Open(path, out.info, options);
  EXPECT_TRUE(writer.ok()) << writer.status();
  if (!writer.ok()) return out;
  TakeWriter& w = **writer;
  auto record = [&out](std::string_view topic, const google::protobuf::Message& m) {
    out.messages_by_topic[std::string(topic)].push_back(m.SerializeAsString());
  };
  record(kTakeInfoTopic, out.info);
  std::vector<std::string> ids;
  for (int s = 0; s < sensor_count; ++s) {
    ids.push_back("k" + std::to_string(s));
    const v1::SensorCalibration c = TestCalibration(ids.back(), 1.5 * s);
    EXPECT_TRUE(w.AddSensor(c).ok());
    record(SensorTopic(ids.back(), "calibration"), c);
  }
  v1::GroundTruthTopology topology;
  topology.set_model_name("test-model");
  topology.set_vertex_count(3);
  for (uint32_t i : {0u, 1u, 2u}) topology.add_triangle_indices(i);
  EXPECT_TRUE(w.WriteGroundTruthTopology(topology).ok());
  record(kGroundTruthTopologyTopic, topology);
  for (int f = 0; f < frames; ++f) {
    const int64_t stamp_ns = start_ns + f * out.period_ns;
    for (const std::string& id : ids) {
      RgbImage rgb(16, 12, static_cast<uint8_t>(10 * f));
      v1::ColorImage color;
      color.set_sensor_id(id);
      color.set_device_stamp_ns(f * out.period_ns);
      color.set_host_stamp_ns(stamp_ns);
      color.set_frame_index(f);
      color.set_width_px(16);
      color.set_height_px(12);
      color.set_encoding("jpeg");
      color.set_quality(90);
      color.set_data(*EncodeJpeg(rgb, 90));
      EXPECT_TRUE(w.WriteColor(color).ok());
      record(SensorTopic(id, "color"), color);
      v1::DepthImage depth;
      depth.set_sensor_id(id);
      depth.set_device_stamp_ns(f * out.period_ns);
      depth.set_host_stamp_ns(stamp_ns);
      depth.set_frame_index(f);
      depth.set_width_px(16);
      depth.set_height_px(12);
      depth.set_encoding("rvl");
      depth.set_data(std::string(100 + f, static_cast<char>(f)));
      EXPECT_TRUE(w.WriteDepth(depth).ok());
      record(SensorTopic(id, "depth"), depth);
      depth.set_data(std::string(90 + f, static_cast<char>(f + 1)));
      EXPECT_TRUE(w.WriteGroundTruthDepth(depth).ok());
      record(GroundTruthDepthTopic(id), depth);
      MaskImage mask_image(16, 12);
      mask_image.at(f % 16, 3) = 1;
      v1::ActorMask mask;
      mask.set_sensor_id(id);
      mask.set_host_stamp_ns(stamp_ns);
      mask.set_frame_index(f);
      mask.set_width_px(16);
      mask.set_height_px(12);
      mask.set_encoding("rle");
      mask.set_data(EncodeMaskRle(mask_image));
      EXPECT_TRUE(w.WriteMask(mask).ok());
      record(SensorTopic(id, "mask"), mask);
      v1::Skeleton skeleton;
      skeleton.set_sensor_id(id);
      skeleton.set_host_stamp_ns(stamp_ns);
      skeleton.set_frame_index(f);
      skeleton.set_body_index(1);
      skeleton.set_source("synthetic-sensor-skeleton (stand-in for a vendor SDK tracker)");
      for (int j = 0; j < 25; ++j) {
        v1::Joint* joint = skeleton.add_joints();
        joint->set_name("Joint" + std::to_string(j));
        joint->mutable_position_in_depth_m()->set_z(2.0 + 0.01 * j + 0.001 * f);
        joint->set_tracking_state(v1::TRACKING_STATE_TRACKED);
      }
      EXPECT_TRUE(w.WriteSkeleton(skeleton).ok());
      record(SensorTopic(id, "skeleton"), skeleton);
    }
    v1::GroundTruthJoints joints;
    joints.set_frame_index(f);
    joints.set_stamp_ns(stamp_ns);
    joints.add_joint_names("SpineBase");
    joints.add_positions_in_world_m()->set_y(1.0 + 0.01 * f);
    EXPECT_TRUE(w.WriteGroundTruthJoints(joints).ok());
    record(kGroundTruthJointsTopic, joints);
    v1::GroundTruthBody body;
    body.set_frame_index(f);
    body.set_stamp_ns(stamp_ns);
    body.set_model_name("test-model");
    for (int j = 0; j < 25; ++j) body.add_local_rotations()->set_w(1.0);
    body.mutable_root_translation_in_world_m()->set_y(0.9);
    body.add_shape_coefficients(0.1f * f);
    EXPECT_TRUE(w.WriteGroundTruthBody(body).ok());
    record(kGroundTruthBodyTopic, body);
    v1::GroundTruthMesh mesh;
    mesh.set_frame_index(f);
    mesh.set_stamp_ns(stamp_ns);
    mesh.set_vertex_count(3);
    mesh.set_positions_in_world_m_f32(std::string(36, static_cast<char>(f)));
    EXPECT_TRUE(w.WriteGroundTruthMesh(mesh).ok());
    record(kGroundTruthMeshTopic, mesh);
  }
  EXPECT_TRUE(w.Close().ok());
  return out;
}

}  // namespace reenact::testing
