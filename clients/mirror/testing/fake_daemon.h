// Test support: a capture daemon's CaptureControl service that lists one
// sensor of a recorded take and streams its frames as LiveFrameSets, served
// on a loopback port the system picks.
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>

#include "common/io/take.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::mirror::testing {

class FakeDaemon final : public v1::CaptureControl::Service {
 public:
  // Streams sensor k0 of `take_path`, one set every 1/pace_fps seconds (0:
  // as fast as the client reads).
  FakeDaemon(const std::string& take_path, double pace_fps)
      : take_(TakeReader::Open(take_path).value()), pace_fps_(pace_fps) {}

  grpc::Status ListSensors(grpc::ServerContext*, const v1::ListSensorsRequest*,
                           v1::ListSensorsResponse* response) override {
    v1::SensorInfo* info = response->add_sensors();
    info->set_sensor_id("k0");
    info->set_state(v1::SENSOR_STATE_STREAMING);
    info->set_provides_skeleton(true);
    info->set_nominal_fps(30.0);
    *info->mutable_calibration() = take_->sensors().at("k0");
    return grpc::Status::OK;
  }

  grpc::Status StreamFrames(grpc::ServerContext* context, const v1::StreamFramesRequest* request,
                            grpc::ServerWriter<v1::LiveFrameSet>* writer) override {
    last_request_ = *request;
    std::map<int64_t, v1::LiveFrameSet> sets;
    absl::Status read = take_->ForEach<v1::ColorImage>(
        SensorTopic("k0", "color"), [&](const v1::ColorImage& image) {
          v1::LiveFrameSet& set = sets[image.frame_index()];
          set.set_stamp_ns(image.host_stamp_ns());
          *set.add_colors() = image;
          return absl::OkStatus();
        });
    if (read.ok()) {
      read = take_->ForEach<v1::Skeleton>(
          SensorTopic("k0", "skeleton"), [&](const v1::Skeleton& skeleton) {
            *sets[skeleton.frame_index()].add_skeletons() = skeleton;
            return absl::OkStatus();
          });
    }
    if (!read.ok()) return grpc::Status(grpc::StatusCode::INTERNAL, std::string(read.message()));
    uint64_t index = 0;
    for (auto& [frame, set] : sets) {
      if (context->IsCancelled()) break;
      set.set_set_index(++index);
      if (!writer->Write(set)) break;
      // The pause between sets ends early when the client cancels.
      const auto next = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(pace_fps_ > 0 ? 1 / pace_fps_ : 0.0);
      while (std::chrono::steady_clock::now() < next && !context->IsCancelled()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
    }
    return grpc::Status::OK;
  }

  const v1::StreamFramesRequest& last_request() const { return last_request_; }

 private:
  std::unique_ptr<TakeReader> take_;
  double pace_fps_ = 0.0;
  v1::StreamFramesRequest last_request_;
};

// The fake served on 127.0.0.1 at a port the system picks.
struct FakeDaemonServer {
  explicit FakeDaemonServer(const std::string& take_path, double pace_fps = 0.0)
      : service(take_path, pace_fps) {
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(&service);
    server = builder.BuildAndStart();
  }
  ~FakeDaemonServer() { server->Shutdown(std::chrono::system_clock::now()); }

  std::string address() const { return "127.0.0.1:" + std::to_string(port); }

  FakeDaemon service;
  int port = 0;
  std::unique_ptr<grpc::Server> server;
};

}  // namespace reenact::mirror::testing
