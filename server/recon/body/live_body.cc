#include "server/recon/body/live_body.h"

#include <chrono>
#include <future>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/model_spec.h"
#include "common/bodyfit/body_fit.h"
#include "server/recon/body/body_cloud.h"
#include "server/recon/body/body_method.h"
#include "server/recon/method_util.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

struct LiveBodyFollower::State {
  body::BodyModel model;
  std::unique_ptr<TakeFrames> take;
  std::unique_ptr<CloudBuilder> builder;
  std::unique_ptr<bodyfit::BodyFitter> fitter;
  // The shape is fitted off the Push path, by its own fitter on a thread of
  // its own; frames are posed with the mean shape meanwhile.
  std::unique_ptr<bodyfit::BodyFitter> shape_fitter;
  std::future<absl::StatusOr<Eigen::VectorXd>> shape_future;
  int shape_frames = 5;
  int shape_spacing = 5;
  // Shape samples until the shape settles.
  std::vector<bodyfit::PointCloud> shape_clouds;
  std::vector<JointArray> shape_skeletons;
  int last_sample = -1000000;
  bool settled = false;
  std::optional<body::BodyPose> previous;
};

absl::Status LiveBodyOptions::Read(methods::OptionReader& reader) {
  return reader.Int("shape_spacing", &shape_spacing, 1, 10000,
                    "live: frame sets between the samples the shape is fitted on");
}

bodyfit::BodyFitOptions LiveFitOptions() {
  bodyfit::BodyFitOptions o;
  o.refine_vertices = false;
  o.max_points = 600;
  o.rounds = 2;
  o.iterations_per_round = 4;
  return o;
}

LiveBodyFollower::LiveBodyFollower() : state_(std::make_unique<State>()) {}
LiveBodyFollower::~LiveBodyFollower() { WaitForShape(); }

void LiveBodyFollower::WaitForShape() {
  if (state_ && state_->shape_future.valid()) state_->shape_future.wait();
}

absl::StatusOr<std::unique_ptr<LiveBodyFollower>> LiveBodyFollower::Create(
    const TakeInfo& info, const std::vector<SensorCalibration>& sensors,
    const std::map<std::string, std::string>& options,
    const std::vector<std::string>& asset_roots) {
  BodyMethodOptions o;
  o.fit = LiveFitOptions();
  std::unique_ptr<LiveBodyFollower> follower(new LiveBodyFollower());
  State& s = *follower->state_;
  {
    OptionReader reader(options);
    RETURN_IF_ERROR(o.Read(reader));
    LiveBodyOptions live;
    RETURN_IF_ERROR(live.Read(reader));
    RETURN_IF_ERROR(reader.Finish());
    RETURN_IF_ERROR(o.Validate());
    s.shape_spacing = live.shape_spacing;
  }
  s.shape_frames = o.fit.shape_frames;
  ASSIGN_OR_RETURN(s.model, body::LoadAssetModelSpec(o.model, asset_roots));
  ASSIGN_OR_RETURN(s.fitter, bodyfit::BodyFitter::Create(s.model, o.fit));
  ASSIGN_OR_RETURN(s.shape_fitter, bodyfit::BodyFitter::Create(s.model, o.fit));
  TakeFramesOptions frames;
  frames.load_color = false;
  frames.num_threads = 1;
  ASSIGN_OR_RETURN(s.take, TakeFrames::CreateLive(info, sensors, frames));
  ASSIGN_OR_RETURN(s.builder, CloudBuilder::Create(*s.take));
  return follower;
}

int LiveBodyFollower::frames_pushed() const { return state_->take->num_instants(); }
bool LiveBodyFollower::shape_settled() const { return state_->settled; }

absl::StatusOr<LiveUpdate> LiveBodyFollower::Push(FrameSet set) {
  const auto start = std::chrono::steady_clock::now();
  State& s = *state_;
  const int64_t stamp_ns = set.stamp_ns;
  RETURN_IF_ERROR(s.take->AppendFrameSet(std::move(set)));
  const int i = s.take->num_instants() - 1;
  LiveUpdate update;
  if (i == 0) {
    ASSIGN_OR_RETURN(update.mesh, BuildBodyMesh(s.model, s.fitter->shape(), ""));
  }
  absl::StatusOr<bodyfit::PointCloud> cloud = s.builder->Build(i);
  const JointArray skeleton = s.take->instant(i).joints_in_world_m;
  s.take->ReleaseInstant(i);
  RETURN_IF_ERROR(cloud.status());
  constexpr size_t kMinPoints = 200;
  const bool usable = cloud->size() >= kMinPoints && bodyfit::HasTorso(skeleton);

  // A shape fitted in the background takes over here.
  if (s.shape_future.valid() &&
      s.shape_future.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
    ASSIGN_OR_RETURN(const Eigen::VectorXd shape, s.shape_future.get());
    RETURN_IF_ERROR(s.fitter->set_shape(shape));
    s.settled = true;
    ASSIGN_OR_RETURN(update.mesh, BuildBodyMesh(s.model, shape, ""));
  }
  // The shape, from the first usable instants `shape_spacing` apart.
  const bool sampling = !s.settled && !s.shape_future.valid();
  if (sampling && usable && i - s.last_sample >= s.shape_spacing) {
    s.shape_clouds.push_back(*cloud);
    s.shape_skeletons.push_back(skeleton);
    s.last_sample = i;
    if (static_cast<int>(s.shape_clouds.size()) >= s.shape_frames) {
      s.shape_future = std::async(
          std::launch::async,
          [fitter = s.shape_fitter.get(), clouds = std::move(s.shape_clouds),
           skeletons = std::move(s.shape_skeletons)]() -> absl::StatusOr<Eigen::VectorXd> {
            std::vector<bodyfit::FitInput> inputs(clouds.size());
            for (size_t k = 0; k < clouds.size(); ++k) {
              inputs[k].cloud = &clouds[k];
              inputs[k].skeleton_m = skeletons[k];
            }
            RETURN_IF_ERROR(fitter->FitShapeFromSkeletons(inputs));
            return fitter->shape();
          });
      s.shape_clouds.clear();
      s.shape_skeletons.clear();
    }
  }

  // The instant, from the previous fit carried to its skeleton.
  if (cloud->size() >= kMinPoints) {
    bodyfit::FitInput input;
    input.cloud = &*cloud;
    input.skeleton_m = skeleton;
    ASSIGN_OR_RETURN(const std::optional<bodyfit::BodyFitter::SequenceFit> next,
                     s.fitter->FitNext(input, s.previous ? &*s.previous : nullptr));
    if (next.has_value()) {
      s.previous = next->fit.pose;
      update.frame = BodyFrame(i, stamp_ns, next->fit, /*valid=*/true);
    }
  }
  update.fit_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return update;
}

}  // namespace reenact::recon
