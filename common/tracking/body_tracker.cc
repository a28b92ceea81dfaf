#include "common/tracking/body_tracker.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/tracking/body_part_forest.h"
#include "common/tracking/pose_net.h"

namespace reenact::tracking {
namespace {

// The network's joint confidences. Its heat maps say nothing of how right a
// joint is (on held-out real frames the flattest maps are the most accurate
// ones: integral regression needs no peak), so a joint's confidence comes
// from the depth: whether it lies on the person's surface where it projects
// (SetState). The values are the shares of such joints within 10 cm of the
// reference, the lower of two held-out measurements rounded down: real
// frames facing the sensor against the Kinect SDK (seen 93 %, not seen 73 %)
// and synthetic frames at any yaw against the truth (89 % and 47 %).
constexpr double kNetworkSeenConfidence = 0.85;
constexpr double kNetworkUnseenConfidence = 0.4;

struct Vote {
  Eigen::Vector3f position_m;
  float weight;
};

// Undistorted normalised rays of every pixel, cached per intrinsics.
class RayCache {
 public:
  const std::vector<Eigen::Vector2f>& Get(const CameraIntrinsics& k) {
    if (k.width == k_.width && k.height == k_.height && k.fx == k_.fx && k.fy == k_.fy &&
        k.cx == k_.cx && k.cy == k_.cy && k.k1 == k_.k1 && k.k2 == k_.k2 && k.k3 == k_.k3 &&
        k.p1 == k_.p1 && k.p2 == k_.p2) {
      return rays_;
    }
    k_ = k;
    rays_.resize(static_cast<size_t>(k.width) * k.height);
    for (int y = 0; y < k.height; ++y) {
      for (int x = 0; x < k.width; ++x) {
        const Eigen::Vector2d distorted((x - k.cx) / k.fx, (y - k.cy) / k.fy);
        const Eigen::Vector2d n =
            k.HasDistortion() ? k.Undistort(distorted).value_or(distorted) : distorted;
        rays_[static_cast<size_t>(y) * k.width + x] = n.cast<float>();
      }
    }
    return rays_;
  }

 private:
  CameraIntrinsics k_;
  std::vector<Eigen::Vector2f> rays_;
};

// One person's pixels: a crop of the depth (metres, background elsewhere).
struct PersonView {
  int label = 0;
  int x0 = 0, y0 = 0;
  FloatImage depth_m;  // Crop, kBackgroundDepthM off the person.
};

std::vector<PersonView> CutPeople(const DepthImageMm& depth, const MaskImage& labels) {
  std::map<int, std::array<int, 4>> boxes;  // label -> x0, y0, x1, y1.
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const int l = labels.at(x, y);
      if (l == 0 || depth.at(x, y) == 0) continue;
      auto [it, fresh] = boxes.try_emplace(l, std::array<int, 4>{x, y, x, y});
      auto& b = it->second;
      b = {std::min(b[0], x), std::min(b[1], y), std::max(b[2], x), std::max(b[3], y)};
    }
  }
  std::vector<PersonView> people;
  for (const auto& [label, b] : boxes) {
    PersonView view{label, b[0], b[1],
                    FloatImage(b[2] - b[0] + 1, b[3] - b[1] + 1, kBackgroundDepthM)};
    for (int y = b[1]; y <= b[3]; ++y) {
      for (int x = b[0]; x <= b[2]; ++x) {
        if (labels.at(x, y) == label && depth.at(x, y) != 0) {
          view.depth_m.at(x - b[0], y - b[1]) = depth.at(x, y) * 0.001f;
        }
      }
    }
    people.push_back(std::move(view));
  }
  return people;
}

// Keeps the `max_votes` heaviest votes, heaviest first; returns their total
// weight.
float KeepHeaviest(std::vector<Vote>* votes, int max_votes) {
  if (static_cast<int>(votes->size()) > max_votes) {
    std::nth_element(votes->begin(), votes->begin() + max_votes, votes->end(),
                     [](const Vote& a, const Vote& b) { return a.weight > b.weight; });
    votes->resize(static_cast<size_t>(max_votes));
  }
  std::sort(votes->begin(), votes->end(),
            [](const Vote& a, const Vote& b) { return a.weight > b.weight; });
  float total = 0;
  for (const Vote& v : *votes) total += v.weight;
  return total;
}

// Kernel density of the votes at `point` over their total weight.
float ShareAt(const std::vector<Vote>& votes, float total, const Eigen::Vector3f& point,
              float inv_2b2) {
  if (!(total > 0)) return 0.0f;
  float density = 0;
  for (const Vote& v : votes) {
    density += v.weight * std::exp(-(v.position_m - point).squaredNorm() * inv_2b2);
  }
  return std::clamp(density / total, 0.0f, 1.0f);
}

// Girshick et al. sec. 3.2: mean shift with a Gaussian kernel from several
// of the heaviest votes. Returns up to `max_modes` distinct modes, densest
// first, each with its density over the votes' total weight.
std::vector<JointMode> VoteModes(const std::vector<Vote>& votes, float total, float bandwidth_m,
                                 int max_modes) {
  std::vector<JointMode> modes;
  if (votes.empty() || !(total > 0)) return modes;
  const float inv_2b2 = 1.0f / (2 * bandwidth_m * bandwidth_m);
  const size_t seeds = std::min<size_t>(votes.size(), 8);
  const size_t seed_step = std::max<size_t>(1, votes.size() / 12);
  for (size_t s = 0; s < seeds; ++s) {
    Eigen::Vector3f mode = votes[s * seed_step % votes.size()].position_m;
    // A seed near a mode found already converges to it.
    bool known = false;
    for (const JointMode& m : modes) known |= (m.position_m - mode).norm() < bandwidth_m;
    if (known) continue;
    float density = 0;
    for (int it = 0; it < 8; ++it) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      density = 0;
      for (const Vote& v : votes) {
        const float w = v.weight * std::exp(-(v.position_m - mode).squaredNorm() * inv_2b2);
        sum += w * v.position_m;
        density += w;
      }
      if (density <= 0) break;
      const Eigen::Vector3f next = sum / density;
      const bool settled = (next - mode).squaredNorm() < 1e-6f;
      mode = next;
      if (settled) break;
    }
    if (!(density > 0)) continue;
    bool merged = false;
    for (JointMode& m : modes) {
      if ((m.position_m - mode).norm() < bandwidth_m) {
        merged = true;
        if (density / total > m.share) m = {mode, density / total};
      }
    }
    if (!merged) modes.push_back({mode, std::clamp(density / total, 0.0f, 1.0f)});
  }
  std::sort(modes.begin(), modes.end(),
            [](const JointMode& a, const JointMode& b) { return a.share > b.share; });
  if (static_cast<int>(modes.size()) > max_modes) modes.resize(static_cast<size_t>(max_modes));
  return modes;
}

}  // namespace

std::string DefaultForestPath() {
  if (const char* env = std::getenv("REENACT_TRACKER_FOREST"); env && *env) return env;
  if (std::string installed = InstalledTrackerFile("body_parts.rtf"); !installed.empty()) {
    return installed;
  }
  return REENACT_DEFAULT_TRACKER_FOREST;
}

absl::Status BodyTrackerOptions::Validate() const {
  if (pixel_stride < 1 || pixel_stride > 16) {
    return absl::InvalidArgumentError("tracker: pixel stride must be 1..16");
  }
  if (!(vote_bandwidth_m > 0 && vote_bandwidth_m < 1) || max_votes_per_joint < 1) {
    return absl::InvalidArgumentError("tracker: bad vote bandwidth or count");
  }
  if (!(min_tracked_confidence >= 0 && min_tracked_confidence <= 1) ||
      !(max_behind_surface_m > 0) || !(max_behind_surface_trunk_m > 0) || !(max_id_jump_m > 0)) {
    return absl::InvalidArgumentError("tracker: bad confidence, surface or id distance");
  }
  if (!(min_prior_confidence >= 0 && min_prior_confidence <= 1)) {
    return absl::InvalidArgumentError("tracker: prior confidence must be within [0, 1]");
  }
  if (refine) RETURN_IF_ERROR(refinement.Validate());
  if (assemble) {
    if (modes_per_joint < 1 || modes_per_joint > 8) {
      return absl::InvalidArgumentError("tracker: modes per joint must be 1..8");
    }
    RETURN_IF_ERROR(assembly.Validate());
  }
  return segmentation.Validate();
}

struct BodyTracker::Impl {
  BodyTrackerOptions options;
  std::shared_ptr<const BodyPartForest> forest;
  std::unique_ptr<PoseNet> net;
  RayCache rays;
  std::vector<TrackedPerson> previous;
  int next_id = 1;
  std::unique_ptr<BodyModelRefiner> refiner;

  TrackedPerson TrackPerson(const PersonView& view, const DepthImageMm& depth,
                            const MaskImage& labels, const CameraIntrinsics& k);
  absl::StatusOr<TrackedPerson> TrackPersonNet(const PersonView& view, const DepthImageMm& depth,
                                               const MaskImage& labels, const CameraIntrinsics& k);
  void KeepSides(TrackedPerson* person) const;
  void AssignIds(std::vector<TrackedPerson>* people);
  void SetState(const DepthImageMm& depth, const MaskImage& labels, const CameraIntrinsics& k,
                int label, int joint_index, TrackedJoint* joint) const;
  absl::Status Refine(const PersonView& view, const CameraIntrinsics& k, TrackedPerson* person);
};

// The person's points with normals from their depth neighbours, oriented
// towards the camera; every `stride`-th pixel.
PersonCloud MakeCloud(const PersonView& view, const std::vector<Eigen::Vector2f>& ray,
                      const CameraIntrinsics& k, int stride) {
  const auto point = [&](int cx, int cy) {
    const float z = view.depth_m.at(cx, cy);
    const Eigen::Vector2f& r = ray[static_cast<size_t>(cy + view.y0) * k.width + cx + view.x0];
    return Eigen::Vector3f(r.x() * z, r.y() * z, z);
  };
  PersonCloud cloud;
  const float max_step_m = 0.05f;
  for (int cy = 0; cy + stride < view.depth_m.height; cy += stride) {
    for (int cx = 0; cx + stride < view.depth_m.width; cx += stride) {
      const float z = view.depth_m.at(cx, cy);
      if (z >= kBackgroundDepthM) continue;
      if (std::abs(view.depth_m.at(cx + stride, cy) - z) > max_step_m ||
          std::abs(view.depth_m.at(cx, cy + stride) - z) > max_step_m) {
        continue;  // An edge (or a flying pixel): no reliable normal.
      }
      const Eigen::Vector3f p = point(cx, cy);
      Eigen::Vector3f n = (point(cx + stride, cy) - p).cross(point(cx, cy + stride) - p);
      if (n.squaredNorm() < 1e-12f) continue;
      n.normalize();
      if (n.dot(p) > 0) n = -n;
      cloud.points_m.push_back(p);
      cloud.normals.push_back(n);
    }
  }
  return cloud;
}

absl::Status BodyTracker::Impl::Refine(const PersonView& view, const CameraIntrinsics& k,
                                       TrackedPerson* person) {
  TrackedPerson prior = *person;
  for (TrackedJoint& joint : prior.joints) {
    if (joint.confidence < options.min_prior_confidence) joint.state = JointState::kNotTracked;
  }
  const PersonCloud cloud = MakeCloud(view, rays.Get(k), k, options.pixel_stride);
  if (cloud.points_m.size() < 50) return absl::OkStatus();
  ASSIGN_OR_RETURN(const bool fitted, refiner->Refine(cloud, &prior));
  if (!fitted) return absl::OkStatus();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    person->joints[j].position_in_camera_m = prior.joints[j].position_in_camera_m;
  }
  return absl::OkStatus();
}

TrackedPerson BodyTracker::Impl::TrackPerson(const PersonView& view, const DepthImageMm& depth,
                                             const MaskImage& labels, const CameraIntrinsics& k) {
  const std::vector<Eigen::Vector2f>& ray = rays.Get(k);
  const DepthProbe probe{view.depth_m.data.data(), view.depth_m.width, view.depth_m.height,
                         static_cast<float>(k.fx), static_cast<float>(k.fy)};
  std::array<std::vector<Vote>, body::kNumKinectV2Joints> votes;
  TrackedPerson person;
  person.mask_label = view.label;
  const int stride = options.pixel_stride;
  for (int cy = 0; cy < view.depth_m.height; cy += stride) {
    for (int cx = 0; cx < view.depth_m.width; cx += stride) {
      const float z = view.depth_m.at(cx, cy);
      if (z >= kBackgroundDepthM) continue;
      const int x = cx + view.x0, y = cy + view.y0;
      const Eigen::Vector2f& r = ray[static_cast<size_t>(y) * k.width + x];
      const Eigen::Vector3f point(r.x() * z, r.y() * z, z);
      person.centroid_in_camera_m += point.cast<double>();
      ++person.num_pixels;
      for (const DecisionTree& tree : forest->trees()) {
        const ForestLeaf& leaf = DescendTree(tree, probe, cx, cy, z);
        for (const JointVote& v : leaf.votes) {
          if (v.joint == kNoJoint) break;
          votes[v.joint].push_back(Vote{point + v.offset_m, v.weight * z * z});  // Shotton Eq. 5.
        }
      }
    }
  }
  if (person.num_pixels > 0) person.centroid_in_camera_m /= person.num_pixels;
  const float bandwidth = static_cast<float>(options.vote_bandwidth_m);
  const float inv_2b2 = 1.0f / (2 * bandwidth * bandwidth);
  std::array<float, body::kNumKinectV2Joints> totals{};
  JointEvidence evidence;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    totals[j] = KeepHeaviest(&votes[j], options.max_votes_per_joint);
    evidence.modes[j] =
        VoteModes(votes[j], totals[j], bandwidth, options.assemble ? options.modes_per_joint : 1);
  }
  if (!options.assemble) {
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      if (evidence.modes[j].empty()) continue;
      TrackedJoint& joint = person.joints[j];
      joint.position_in_camera_m = evidence.modes[j][0].position_m.cast<double>();
      joint.confidence = std::clamp(static_cast<double>(evidence.modes[j][0].share), 0.0, 1.0);
      joint.state = JointState::kInferred;
    }
    return person;
  }
  evidence.share_at = [&](int joint, const Eigen::Vector3f& point) {
    return ShareAt(votes[joint], totals[joint], point, inv_2b2);
  };
  // The same person in the frame before: the nearest previous centroid.
  const TrackedPerson* before = nullptr;
  double nearest = options.max_id_jump_m;
  for (const TrackedPerson& p : previous) {
    const double d = (p.centroid_in_camera_m - person.centroid_in_camera_m).norm();
    if (d <= nearest) nearest = d, before = &p;
  }
  person.joints = AssembleSkeleton(evidence, before ? &before->joints : nullptr, options.assembly);
  return person;
}

// The person's centroid and pixel count from every `stride`-th pixel.
void Measure(const PersonView& view, const std::vector<Eigen::Vector2f>& ray,
             const CameraIntrinsics& k, int stride, TrackedPerson* person) {
  for (int cy = 0; cy < view.depth_m.height; cy += stride) {
    for (int cx = 0; cx < view.depth_m.width; cx += stride) {
      const float z = view.depth_m.at(cx, cy);
      if (z >= kBackgroundDepthM) continue;
      const Eigen::Vector2f& r = ray[static_cast<size_t>(cy + view.y0) * k.width + cx + view.x0];
      person->centroid_in_camera_m += Eigen::Vector3d(r.x() * z, r.y() * z, z);
      ++person->num_pixels;
    }
  }
  if (person->num_pixels > 0) person->centroid_in_camera_m /= person->num_pixels;
}

absl::StatusOr<TrackedPerson> BodyTracker::Impl::TrackPersonNet(const PersonView& view,
                                                                const DepthImageMm& depth,
                                                                const MaskImage& labels,
                                                                const CameraIntrinsics& k) {
  TrackedPerson person;
  person.mask_label = view.label;
  Measure(view, rays.Get(k), k, options.pixel_stride, &person);
  const std::optional<PoseNetCrop> crop = ChoosePoseNetCrop(depth, &labels, view.label, k);
  if (!crop) return person;  // Too few pixels: no joints.
  ASSIGN_OR_RETURN(const auto found,
                   net->Run(PoseNetInput(depth, &labels, view.label, *crop), *crop));
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (!(found[j].depth_m > 0.05)) continue;
    const std::optional<Eigen::Vector3d> p = k.Unproject(found[j].pixel, found[j].depth_m);
    if (!p || !p->allFinite()) continue;
    TrackedJoint& joint = person.joints[j];
    joint.position_in_camera_m = *p;
    // Until Track() checks the joint against the depth (SetState).
    joint.confidence = kNetworkSeenConfidence;
    joint.state = JointState::kInferred;
  }
  return person;
}

bool IsTrunkJoint(int joint) {
  switch (static_cast<body::KinectV2Joint>(joint)) {
    case body::KinectV2Joint::kSpineBase:
    case body::KinectV2Joint::kSpineMid:
    case body::KinectV2Joint::kSpineShoulder:
    case body::KinectV2Joint::kNeck:
    case body::KinectV2Joint::kHipLeft:
    case body::KinectV2Joint::kHipRight:
      return true;
    default:
      return false;
  }
}

// Left and right joints of the limbs, paired.
constexpr std::array<std::pair<body::KinectV2Joint, body::KinectV2Joint>, 10> kSides = {{
    {body::KinectV2Joint::kShoulderLeft, body::KinectV2Joint::kShoulderRight},
    {body::KinectV2Joint::kElbowLeft, body::KinectV2Joint::kElbowRight},
    {body::KinectV2Joint::kWristLeft, body::KinectV2Joint::kWristRight},
    {body::KinectV2Joint::kHandLeft, body::KinectV2Joint::kHandRight},
    {body::KinectV2Joint::kHipLeft, body::KinectV2Joint::kHipRight},
    {body::KinectV2Joint::kKneeLeft, body::KinectV2Joint::kKneeRight},
    {body::KinectV2Joint::kAnkleLeft, body::KinectV2Joint::kAnkleRight},
    {body::KinectV2Joint::kFootLeft, body::KinectV2Joint::kFootRight},
    {body::KinectV2Joint::kHandTipLeft, body::KinectV2Joint::kHandTipRight},
    {body::KinectV2Joint::kThumbLeft, body::KinectV2Joint::kThumbRight},
}};

// A limb whose left and right joints lie closer to the other side's in the
// person's previous frame than to their own, by a clear margin, was read
// with its sides swapped: swap them back. Arms and legs are decided each as
// a whole (shoulder to hand tip, hip to foot).
void BodyTracker::Impl::KeepSides(TrackedPerson* person) const {
  const TrackedPerson* before = nullptr;
  for (const TrackedPerson& p : previous) {
    if (p.person_id == person->person_id) before = &p;
  }
  if (before == nullptr) return;
  const auto limb = [&](std::initializer_list<int> pairs) {
    double same = 0, swapped = 0;
    int n = 0;
    for (int i : pairs) {
      const int l = body::Index(kSides[i].first), r = body::Index(kSides[i].second);
      const auto& now = person->joints;
      const auto& was = before->joints;
      if (now[l].state == JointState::kNotTracked || now[r].state == JointState::kNotTracked ||
          was[l].state == JointState::kNotTracked || was[r].state == JointState::kNotTracked) {
        continue;
      }
      same += (now[l].position_in_camera_m - was[l].position_in_camera_m).norm() +
              (now[r].position_in_camera_m - was[r].position_in_camera_m).norm();
      swapped += (now[l].position_in_camera_m - was[r].position_in_camera_m).norm() +
                 (now[r].position_in_camera_m - was[l].position_in_camera_m).norm();
      ++n;
    }
    // Swapped only when that is closer by half and by 5 cm a joint.
    if (n == 0 || !(swapped < 0.5 * same && same - swapped > 0.05 * 2 * n)) return;
    for (int i : pairs) {
      std::swap(person->joints[body::Index(kSides[i].first)],
                person->joints[body::Index(kSides[i].second)]);
    }
  };
  limb({0, 1, 2, 3, 8, 9});
  limb({4, 5, 6, 7});
}

void BodyTracker::Impl::SetState(const DepthImageMm& depth, const MaskImage& labels,
                                 const CameraIntrinsics& k, int label, int joint_index,
                                 TrackedJoint* joint) const {
  joint->state = JointState::kInferred;
  if (joint->confidence < options.min_tracked_confidence || !k.IsInside(joint->pixel)) return;
  const int x = static_cast<int>(std::lround(joint->pixel.x()));
  const int y = static_cast<int>(std::lround(joint->pixel.y()));
  if (labels.at(x, y) != label || depth.at(x, y) == 0) return;
  const double behind_m = joint->position_in_camera_m.z() - depth.at(x, y) * 0.001;
  const double max_behind_m =
      IsTrunkJoint(joint_index) ? options.max_behind_surface_trunk_m : options.max_behind_surface_m;
  if (behind_m > -0.05 && behind_m < max_behind_m) {
    joint->state = JointState::kTracked;
  }
}

// Each person keeps the id of the nearest person of the previous frame
// within max_id_jump_m (closest pairs first); the rest get new ids.
void BodyTracker::Impl::AssignIds(std::vector<TrackedPerson>* people) {
  std::vector<std::tuple<double, size_t, size_t>> pairs;
  for (size_t i = 0; i < people->size(); ++i) {
    for (size_t p = 0; p < previous.size(); ++p) {
      const double d =
          ((*people)[i].centroid_in_camera_m - previous[p].centroid_in_camera_m).norm();
      if (d <= options.max_id_jump_m) pairs.emplace_back(d, i, p);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<bool> person_done(people->size(), false), previous_done(previous.size(), false);
  for (const auto& [d, i, p] : pairs) {
    if (person_done[i] || previous_done[p]) continue;
    (*people)[i].person_id = previous[p].person_id;
    person_done[i] = previous_done[p] = true;
  }
  for (size_t i = 0; i < people->size(); ++i) {
    if (!person_done[i]) (*people)[i].person_id = next_id++;
  }
}

BodyTracker::BodyTracker(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BodyTracker::~BodyTracker() = default;

absl::StatusOr<std::unique_ptr<BodyTracker>> BodyTracker::Create(
    const BodyTrackerOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (options.method == TrackerMethod::kNetwork) {
    const std::string path = options.model_path.empty() ? DefaultPoseNetPath() : options.model_path;
    auto impl = std::make_unique<Impl>();
    impl->options = options;
    ASSIGN_OR_RETURN(impl->net, PoseNet::Load(path));
    if (options.refine) {
      ASSIGN_OR_RETURN(impl->refiner, BodyModelRefiner::Create(options.refinement));
    }
    return std::unique_ptr<BodyTracker>(new BodyTracker(std::move(impl)));
  }
  const std::string path = options.forest_path.empty() ? DefaultForestPath() : options.forest_path;
  ASSIGN_OR_RETURN(BodyPartForest forest, BodyPartForest::Load(path));
  return Create(std::make_shared<const BodyPartForest>(std::move(forest)), options);
}

absl::StatusOr<std::unique_ptr<BodyTracker>> BodyTracker::Create(
    std::shared_ptr<const BodyPartForest> forest, const BodyTrackerOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (!forest) return absl::InvalidArgumentError("tracker: no forest");
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->options.method = TrackerMethod::kForest;
  impl->forest = std::move(forest);
  if (options.refine) {
    ASSIGN_OR_RETURN(impl->refiner, BodyModelRefiner::Create(options.refinement));
  }
  return std::unique_ptr<BodyTracker>(new BodyTracker(std::move(impl)));
}

absl::StatusOr<std::vector<TrackedPerson>> BodyTracker::Track(const DepthImageMm& depth,
                                                              const CameraIntrinsics& intrinsics,
                                                              const MaskImage* labels,
                                                              MaskImage* own_labels_out) {
  RETURN_IF_ERROR(intrinsics.Validate());
  // No depth camera gives more; larger images are refused before the ray
  // cache (8 bytes a pixel) is made for them.
  constexpr int kMaxSide = 4096;
  if (depth.width > kMaxSide || depth.height > kMaxSide) {
    return absl::InvalidArgumentError(absl::StrCat("tracker: depth images up to ", kMaxSide, "x",
                                                   kMaxSide, " px, not ", depth.width, "x",
                                                   depth.height));
  }
  if (depth.width != intrinsics.width || depth.height != intrinsics.height ||
      depth.data.size() != depth.num_pixels()) {
    return absl::InvalidArgumentError(absl::StrCat("tracker: the depth image is ", depth.width, "x",
                                                   depth.height, " but the intrinsics are for ",
                                                   intrinsics.width, "x", intrinsics.height));
  }
  MaskImage own_labels;
  if (labels == nullptr) {
    ASSIGN_OR_RETURN(PersonSegmentation segmentation,
                     SegmentPeople(depth, intrinsics, impl_->options.segmentation));
    own_labels = std::move(segmentation.labels);
    labels = &own_labels;
  } else if (labels->width != depth.width || labels->height != depth.height ||
             labels->data.size() != depth.num_pixels()) {
    return absl::InvalidArgumentError("tracker: the label image and the depth differ in size");
  }
  const std::vector<PersonView> views = CutPeople(depth, *labels);
  std::vector<TrackedPerson> people;
  people.reserve(views.size());
  for (const PersonView& view : views) {
    if (impl_->net) {
      ASSIGN_OR_RETURN(TrackedPerson person,
                       impl_->TrackPersonNet(view, depth, *labels, intrinsics));
      people.push_back(std::move(person));
    } else {
      people.push_back(impl_->TrackPerson(view, depth, *labels, intrinsics));
    }
  }
  impl_->AssignIds(&people);
  if (impl_->options.keep_sides) {
    for (TrackedPerson& person : people) impl_->KeepSides(&person);
  }
  std::vector<int> ids;
  for (size_t i = 0; i < people.size(); ++i) {
    TrackedPerson& person = people[i];
    ids.push_back(person.person_id);
    if (impl_->refiner) RETURN_IF_ERROR(impl_->Refine(views[i], intrinsics, &person));
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      TrackedJoint& joint = person.joints[j];
      if (joint.state == JointState::kNotTracked) continue;
      if (auto pixel = intrinsics.Project(joint.position_in_camera_m)) joint.pixel = *pixel;
      impl_->SetState(depth, *labels, intrinsics, person.mask_label, j, &joint);
      if (impl_->net) {
        joint.confidence =
            joint.state == JointState::kTracked ? kNetworkSeenConfidence : kNetworkUnseenConfidence;
      }
    }
  }
  if (impl_->refiner) impl_->refiner->Keep(ids);
  impl_->previous = people;
  if (own_labels_out != nullptr && labels == &own_labels) *own_labels_out = std::move(own_labels);
  return people;
}

void BodyTracker::Reset() {
  impl_->previous.clear();
  if (impl_->refiner) impl_->refiner->Keep({});
  impl_->next_id = 1;
}

const BodyTrackerOptions& BodyTracker::options() const { return impl_->options; }

}  // namespace reenact::tracking
