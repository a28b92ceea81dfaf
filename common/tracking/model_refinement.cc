#include "common/tracking/model_refinement.h"

#include <algorithm>

#include "common/base/status_macros.h"
#include "common/body/model_spec.h"
#include "common/bodyfit/body_fit.h"

namespace reenact::tracking {
namespace {

// What is kept of one person between frames.
struct PersonState {
  std::unique_ptr<bodyfit::BodyFitter> fitter;
  std::optional<body::BodyPose> previous;
  int fitted = 0;
  bool shape_done = false;
  std::vector<bodyfit::PointCloud> shape_clouds;
  std::vector<bodyfit::SkeletonJoints> shape_skeletons;
  std::vector<body::BodyPose> shape_poses;
};

bodyfit::PointCloud ToCloud(const PersonCloud& cloud) {
  return bodyfit::PointCloud{cloud.points_m, cloud.normals, {}};
}

bodyfit::SkeletonJoints ToSkeleton(const TrackedPerson& person) {
  bodyfit::SkeletonJoints s = bodyfit::NoSkeletonJoints();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (person.joints[j].state != JointState::kNotTracked)
      s[j] = person.joints[j].position_in_camera_m;
  }
  return s;
}

}  // namespace

absl::Status ModelRefinementOptions::Validate() const {
  if (!body::IsBodyModelSpec(model)) {
    return absl::InvalidArgumentError("tracker model: expected 'procedural' or 'makehuman:DIR'");
  }
  if (rounds < 1 || iterations_per_round < 1 || max_points < 50 || shape_frames < 0 ||
      shape_spacing < 1 || !(skeleton_weight >= 0)) {
    return absl::InvalidArgumentError("tracker model: bad rounds, points or shape frames");
  }
  return absl::OkStatus();
}

struct BodyModelRefiner::Impl {
  ModelRefinementOptions options;
  bodyfit::BodyFitOptions fit;
  std::unique_ptr<body::BodyModel> model;  // Outlives the fitters.
  std::map<int, PersonState> people;

  absl::Status MaybeFitShape(PersonState* state, const bodyfit::PointCloud& cloud,
                             const bodyfit::SkeletonJoints& skeleton, const body::BodyPose& pose);
};

absl::Status BodyModelRefiner::Impl::MaybeFitShape(PersonState* state,
                                                   const bodyfit::PointCloud& cloud,
                                                   const bodyfit::SkeletonJoints& skeleton,
                                                   const body::BodyPose& pose) {
  if (state->shape_done || options.shape_frames == 0) return absl::OkStatus();
  if (state->fitted % options.shape_spacing != 0) return absl::OkStatus();
  state->shape_clouds.push_back(cloud);
  state->shape_skeletons.push_back(skeleton);
  state->shape_poses.push_back(pose);
  if (static_cast<int>(state->shape_clouds.size()) < options.shape_frames) return absl::OkStatus();
  std::vector<bodyfit::FitInput> inputs;
  for (size_t i = 0; i < state->shape_clouds.size(); ++i) {
    inputs.push_back(bodyfit::FitInput{&state->shape_clouds[i], state->shape_skeletons[i]});
  }
  RETURN_IF_ERROR(state->fitter->FitShape(inputs, &state->shape_poses));
  state->shape_done = true;
  state->shape_clouds.clear();
  state->shape_skeletons.clear();
  state->shape_poses.clear();
  state->previous.reset();  // The old pose belongs to the old shape.
  return absl::OkStatus();
}

BodyModelRefiner::BodyModelRefiner(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BodyModelRefiner::~BodyModelRefiner() = default;

absl::StatusOr<std::unique_ptr<BodyModelRefiner>> BodyModelRefiner::Create(
    const ModelRefinementOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  ASSIGN_OR_RETURN(body::BodyModel model, body::LoadBodyModelSpec(options.model));
  impl->model = std::make_unique<body::BodyModel>(std::move(model));
  impl->fit.rounds = options.rounds;
  impl->fit.iterations_per_round = options.iterations_per_round;
  impl->fit.max_points = options.max_points;
  impl->fit.skeleton_weight = options.skeleton_weight;
  impl->fit.refine_vertices = false;  // Joints need the model's pose only.
  RETURN_IF_ERROR(impl->fit.Validate());
  return std::unique_ptr<BodyModelRefiner>(new BodyModelRefiner(std::move(impl)));
}

absl::StatusOr<bool> BodyModelRefiner::Refine(const PersonCloud& person_cloud,
                                              TrackedPerson* person) {
  PersonState& state = impl_->people[person->person_id];
  if (!state.fitter) {
    ASSIGN_OR_RETURN(state.fitter, bodyfit::BodyFitter::Create(*impl_->model, impl_->fit));
  }
  const bodyfit::SkeletonJoints skeleton = ToSkeleton(*person);
  const body::BodyPose* previous = state.previous ? &*state.previous : nullptr;
  ASSIGN_OR_RETURN(std::optional<body::BodyPose> initial,
                   state.fitter->InitialPose(previous, skeleton));
  if (!initial) return false;
  const bodyfit::PointCloud cloud = ToCloud(person_cloud);
  ASSIGN_OR_RETURN(bodyfit::FrameFit fit,
                   state.fitter->FitFrame(bodyfit::FitInput{&cloud, skeleton}, *initial, previous));
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    person->joints[j].position_in_camera_m = fit.joints_m[j];
  }
  state.previous = fit.pose;
  RETURN_IF_ERROR(impl_->MaybeFitShape(&state, cloud, skeleton, fit.pose));
  ++state.fitted;
  return true;
}

void BodyModelRefiner::Keep(const std::vector<int>& person_ids) {
  for (auto it = impl_->people.begin(); it != impl_->people.end();) {
    const bool keep =
        std::find(person_ids.begin(), person_ids.end(), it->first) != person_ids.end();
    it = keep ? std::next(it) : impl_->people.erase(it);
  }
}

}  // namespace reenact::tracking
