#include "common/tracking/skeleton_fusion.h"

#include <algorithm>
#include <bitset>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"

namespace reenact::tracking {
namespace {

using J = body::KinectV2Joint;
constexpr int kNumJoints = body::kNumKinectV2Joints;

// The medoid replaces the weighted mean as the start of IRLS when the
// estimates of a joint spread wider than this many robust scales.
constexpr double kMedoidSpreadScales = 3.0;
// Two medoid candidates whose costs are this close (relative) are a tie.
constexpr double kMedoidTieShare = 0.01;
// Facing cue: the shortest left-to-right line and foot direction that count, metres.
constexpr double kMinLateralM = 0.05;
constexpr double kMinFootM = 0.02;

// One sensor's joints in the world after its swaps, with their weights
// (0: not used).
struct WorldView {
  std::array<Eigen::Vector3d, kNumJoints> position_m;
  std::array<double, kNumJoints> weight{};
  std::array<double, kNumJoints> confidence{};
  std::array<JointState, kNumJoints> state{};
};

bool IsFinite(const Rigid3d& transform) {
  return transform.rotation.coeffs().allFinite() && transform.translation.allFinite() &&
         std::abs(transform.rotation.norm() - 1.0) < 1e-3;
}

double StateWeight(JointState state, const SkeletonFusionOptions& options) {
  switch (state) {
    case JointState::kTracked:
      return options.tracked_weight;
    case JointState::kInferred:
      return options.inferred_weight;
    case JointState::kNotTracked:
      break;
  }
  return 0.0;
}

// The sensor's joints in the world; counts used and rejected joints.
WorldView ToWorld(const SensorSkeleton& sensor, const SkeletonFusionOptions& options,
                  SensorFusionReport* report) {
  WorldView view;
  const bool pose_ok = IsFinite(sensor.world_from_camera);
  for (int j = 0; j < kNumJoints; ++j) {
    const TrackedJoint& joint = sensor.joints[j];
    view.state[j] = joint.state;
    if (joint.state == JointState::kNotTracked || !pose_ok) continue;
    if (!joint.position_in_camera_m.allFinite() || !std::isfinite(joint.confidence)) {
      ++report->joints_rejected;
      continue;
    }
    const double confidence = std::clamp(joint.confidence, 0.0, 1.0);
    const double weight = confidence * StateWeight(joint.state, options);
    if (confidence < options.min_confidence || !(weight > 0.0)) continue;
    view.position_m[j] = sensor.world_from_camera * joint.position_in_camera_m;
    view.weight[j] = weight;
    view.confidence[j] = confidence;
    ++report->joints_used;
  }
  report->used = report->joints_used > 0;
  return view;
}

// The previous fused skeleton as one more (never swapped) view.
WorldView PreviousView(const FusedSkeleton& previous, double weight) {
  WorldView view;
  for (int j = 0; j < kNumJoints; ++j) {
    const FusedJoint& joint = previous.joints[j];
    view.state[j] = joint.state;
    if (joint.state == JointState::kNotTracked || !joint.position_in_world_m.allFinite()) continue;
    view.position_m[j] = joint.position_in_world_m;
    view.weight[j] = weight;
    view.confidence[j] = joint.confidence;
  }
  return view;
}

// Sum of (left - right) over the pairs of `lefts` that the view has.
Eigen::Vector3d LateralLine(const WorldView& view, std::initializer_list<J> lefts) {
  Eigen::Vector3d lateral = Eigen::Vector3d::Zero();
  for (J left : lefts) {
    const int l = body::Index(left), r = body::Index(MirrorKinectV2Joint(left));
    if (view.weight[l] > 0 && view.weight[r] > 0)
      lateral += view.position_m[l] - view.position_m[r];
  }
  return lateral;
}

// The cosine between the facing the view's labels imply (left-to-right
// line x up: a person facing +Z with +Y up has their left at +X) and where
// its feet point (ankle to foot), both horizontal; 0 when either is unknown.
double FacingAgreement(const WorldView& view) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  Eigen::Vector3d facing = LateralLine(view, {J::kShoulderLeft, J::kHipLeft}).cross(up);
  Eigen::Vector3d feet = Eigen::Vector3d::Zero();
  for (auto [ankle, foot] :
       {std::pair{J::kAnkleLeft, J::kFootLeft}, {J::kAnkleRight, J::kFootRight}}) {
    const int a = body::Index(ankle), f = body::Index(foot);
    if (view.weight[a] > 0 && view.weight[f] > 0) feet += view.position_m[f] - view.position_m[a];
  }
  facing.y() = 0.0;
  feet.y() = 0.0;
  if (facing.norm() < kMinLateralM || feet.norm() < kMinFootM) return 0.0;
  return facing.normalized().dot(feet.normalized());
}

void SwapPair(LimbPair pair, WorldView* view) {
  for (J left : LimbPairLeftJoints(pair)) {
    const int l = body::Index(left), r = body::Index(MirrorKinectV2Joint(left));
    std::swap(view->position_m[l], view->position_m[r]);
    std::swap(view->weight[l], view->weight[r]);
    std::swap(view->confidence[l], view->confidence[r]);
    std::swap(view->state[l], view->state[r]);
  }
}

// Cauchy cost of the disagreement of `a` (its labels swapped in `pair` when
// `swap_a`) with `b` over the joints of the pair, weighted by both joints'
// weights. Swapping both views costs the same as swapping neither.
double PairCost(const WorldView& a, bool swap_a, const WorldView& b, LimbPair pair,
                double scale_m) {
  double cost = 0.0;
  for (J left : LimbPairLeftJoints(pair)) {
    for (J j : {left, MirrorKinectV2Joint(left)}) {
      const int ja = body::Index(swap_a ? MirrorKinectV2Joint(j) : j), jb = body::Index(j);
      const double w = std::sqrt(a.weight[ja] * b.weight[jb]);
      if (w <= 0) continue;
      const double d = (a.position_m[ja] - b.position_m[jb]).norm() / scale_m;
      cost += w * std::log1p(d * d);
    }
  }
  return cost;
}

// Costs of the swap search of one limb pair: between two sensors with the
// same or opposite labelling, and of each sensor against the previous
// skeleton as labelled or swapped.
struct SwapCosts {
  std::vector<std::vector<double>> same, opposite;
  std::vector<double> previous_kept, previous_swapped;
};

SwapCosts ComputeSwapCosts(const std::vector<WorldView>& views, const WorldView* previous,
                           LimbPair pair, double scale_m) {
  const size_t n = views.size();
  SwapCosts c{std::vector<std::vector<double>>(n, std::vector<double>(n, 0.0)),
              std::vector<std::vector<double>>(n, std::vector<double>(n, 0.0)),
              std::vector<double>(n, 0.0), std::vector<double>(n, 0.0)};
  for (size_t s = 0; s < n; ++s) {
    for (size_t t = s + 1; t < n; ++t) {
      c.same[s][t] = PairCost(views[s], false, views[t], pair, scale_m);
      c.opposite[s][t] = PairCost(views[s], true, views[t], pair, scale_m);
    }
    if (previous) {
      c.previous_kept[s] = PairCost(views[s], false, *previous, pair, scale_m);
      c.previous_swapped[s] = PairCost(views[s], true, *previous, pair, scale_m);
    }
  }
  return c;
}

bool Bit(uint32_t mask, size_t s) { return (mask >> s) & 1u; }

double LabellingCost(const SwapCosts& c, uint32_t mask) {
  const size_t n = c.same.size();
  double cost = 0.0;
  for (size_t s = 0; s < n; ++s) {
    cost += Bit(mask, s) ? c.previous_swapped[s] : c.previous_kept[s];
    for (size_t t = s + 1; t < n; ++t) {
      cost += Bit(mask, s) != Bit(mask, t) ? c.opposite[s][t] : c.same[s][t];
    }
  }
  return cost;
}

// Tie-break between labellings of equal cost: agreement of the swapped
// sensors' facing cue, then fewer swaps.
double TieScore(uint32_t mask, const std::vector<double>& facing) {
  double score = 0.0;
  for (size_t s = 0; s < facing.size(); ++s) score += Bit(mask, s) ? -facing[s] : facing[s];
  return score - 1e-6 * static_cast<double>(std::bitset<32>(mask).count());
}

// The labelling (bit s set: swap sensor s) of one limb pair.
uint32_t ChooseSwaps(const SwapCosts& costs, const std::vector<double>& facing,
                     double min_swap_gain) {
  const uint32_t count = 1u << facing.size();
  std::vector<double> cost(count);
  for (uint32_t mask = 0; mask < count; ++mask) cost[mask] = LabellingCost(costs, mask);
  const double best = *std::min_element(cost.begin(), cost.end());
  if (cost[0] - best <= min_swap_gain) return 0;
  const double tie = 1e-9 * (1.0 + std::abs(best));
  uint32_t chosen = 0;
  double chosen_score = -std::numeric_limits<double>::infinity();
  for (uint32_t mask = 1; mask < count; ++mask) {
    if (cost[mask] > best + tie) continue;
    const double score = TieScore(mask, facing);
    if (score > chosen_score) chosen = mask, chosen_score = score;
  }
  return chosen;
}

// Decides and applies the swaps of every limb pair to `views`.
void ResolveSwaps(const WorldView* previous, const SkeletonFusionOptions& options,
                  std::vector<WorldView>* views, std::vector<SensorFusionReport>* reports) {
  std::vector<double> facing(views->size());
  for (size_t s = 0; s < views->size(); ++s) {
    facing[s] = (*reports)[s].facing_agreement = FacingAgreement((*views)[s]);
  }
  for (int p = 0; p < kNumLimbPairs; ++p) {
    const auto pair = static_cast<LimbPair>(p);
    const SwapCosts costs = ComputeSwapCosts(*views, previous, pair, options.swap_scale_m);
    const uint32_t mask = ChooseSwaps(costs, facing, options.min_swap_gain);
    for (size_t s = 0; s < views->size(); ++s) {
      if (!Bit(mask, s)) continue;
      SwapPair(pair, &(*views)[s]);
      (*reports)[s].swapped_limbs[p] = true;
      (*reports)[s].swapped_left_right = true;
    }
  }
}

// The robust kernel's weight of a residual: Cauchy 1 / (1 + (r/c)^2), Huber
// min(1, c / r) (the IRLS weights psi(r) / r of the two M-estimators).
double KernelWeight(double residual_m, const SkeletonFusionOptions& options) {
  const double u = residual_m / options.robust_scale_m;
  if (options.kernel == SkeletonFusionOptions::Kernel::kHuber) return u <= 1.0 ? 1.0 : 1.0 / u;
  return 1.0 / (1.0 + u * u);
}

// The estimates of one joint: positions, base weights, sensor indices.
struct JointEstimates {
  std::vector<Eigen::Vector3d> position_m;
  std::vector<double> weight;
  std::vector<int> sensor;
};

JointEstimates CollectEstimates(const std::vector<WorldView>& views, int j) {
  JointEstimates e;
  for (size_t s = 0; s < views.size(); ++s) {
    if (views[s].weight[j] <= 0) continue;
    e.position_m.push_back(views[s].position_m[j]);
    e.weight.push_back(views[s].weight[j]);
    e.sensor.push_back(static_cast<int>(s));
  }
  return e;
}

// Weighted mean with each base weight times `scale[k]` (1 when empty).
Eigen::Vector3d WeightedMean(const JointEstimates& e, const std::vector<double>& scale) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double total = 0.0;
  for (size_t k = 0; k < e.weight.size(); ++k) {
    const double w = e.weight[k] * (scale.empty() ? 1.0 : scale[k]);
    sum += w * e.position_m[k];
    total += w;
  }
  return total > 0 ? Eigen::Vector3d(sum / total) : e.position_m.front();
}

// Robust cost of `x` against the estimates (and the previous position, when
// it has a weight): sum of w * log(1 + (r / c)^2).
double MedoidCost(const Eigen::Vector3d& x, const JointEstimates& e,
                  const std::optional<Eigen::Vector3d>& previous_m, double previous_weight,
                  double scale_m) {
  auto rho = [scale_m](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double u = (a - b).norm() / scale_m;
    return std::log1p(u * u);
  };
  double cost = previous_m ? previous_weight * rho(x, *previous_m) : 0.0;
  for (size_t k = 0; k < e.weight.size(); ++k) cost += e.weight[k] * rho(x, e.position_m[k]);
  return cost;
}

// Where IRLS starts: the weighted mean, or the weighted medoid when the
// estimates spread wide and one estimate is a clear best.
Eigen::Vector3d StartPoint(const JointEstimates& e,
                           const std::optional<Eigen::Vector3d>& previous_m,
                           const SkeletonFusionOptions& options) {
  Eigen::Vector3d mean = WeightedMean(e, {});
  double spread = 0.0;
  for (const Eigen::Vector3d& p : e.position_m) spread = std::max(spread, (p - mean).norm());
  if (spread <= kMedoidSpreadScales * options.robust_scale_m) return mean;
  std::vector<std::pair<double, size_t>> costs;
  for (size_t k = 0; k < e.weight.size(); ++k) {
    costs.emplace_back(
        MedoidCost(e.position_m[k], e, previous_m, options.previous_weight, options.robust_scale_m),
        k);
  }
  std::sort(costs.begin(), costs.end());
  const Eigen::Vector3d& best = e.position_m[costs[0].second];
  // A tie between two estimates that disagree: neither is the consensus.
  const bool tie = costs.size() > 1 &&
                   costs[1].first - costs[0].first <= kMedoidTieShare * costs[0].first &&
                   (e.position_m[costs[1].second] - best).norm() > options.robust_scale_m;
  return tie ? mean : best;
}

// Robust weighted mean of one joint by IRLS (Holland & Welsch 1977) from
// `start`; `share` gets each estimate's final kernel weight.
Eigen::Vector3d RobustMean(const JointEstimates& e, Eigen::Vector3d x,
                           const SkeletonFusionOptions& options, std::vector<double>* share,
                           int* iterations) {
  share->assign(e.weight.size(), 1.0);
  for (*iterations = 1; *iterations <= options.max_iterations; ++*iterations) {
    for (size_t k = 0; k < e.weight.size(); ++k) {
      (*share)[k] = KernelWeight((e.position_m[k] - x).norm(), options);
    }
    const Eigen::Vector3d next = WeightedMean(e, *share);
    const double step = (next - x).norm();
    x = next;
    if (step < options.convergence_m) break;
  }
  *iterations = std::min(*iterations, options.max_iterations);
  return x;
}

// Confidence, state and inlier sensors of a fused joint from its estimates'
// final kernel weights.
void DescribeFused(const JointEstimates& e, const std::vector<double>& share,
                   const std::vector<WorldView>& views, int j, const SkeletonFusionOptions& options,
                   FusedJoint* fused, std::vector<SensorFusionReport>* reports) {
  double all_wrong = 1.0;
  fused->state = JointState::kInferred;
  for (size_t k = 0; k < e.weight.size(); ++k) {
    const int s = e.sensor[k];
    all_wrong *= 1.0 - views[s].confidence[j] * share[k];
    if (share[k] < options.inlier_weight_share) {
      ++(*reports)[s].joints_outlying;
      continue;
    }
    fused->sensors.push_back(s);
    if (views[s].state[j] == JointState::kTracked) fused->state = JointState::kTracked;
  }
  fused->confidence = 1.0 - all_wrong;
}

void Tally(SkeletonFusionSummary* summary) {
  for (const FusedJoint& joint : summary->skeleton.joints) {
    summary->num_tracked += joint.state == JointState::kTracked;
    summary->num_inferred += joint.state == JointState::kInferred;
  }
}

absl::Status CheckInput(const std::vector<SensorSkeleton>& sensors,
                        const SkeletonFusionOptions& options) {
  if (sensors.empty()) return absl::InvalidArgumentError("no sensor skeletons to fuse");
  if (sensors.size() > static_cast<size_t>(kMaxFusionSensors)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "cannot fuse ", sensors.size(), " sensor skeletons; at most ", kMaxFusionSensors));
  }
  return options.Validate();
}

}  // namespace

body::KinectV2Joint MirrorKinectV2Joint(body::KinectV2Joint joint) {
  static constexpr std::array<std::pair<J, J>, 10> kPairs = {{
      {J::kShoulderLeft, J::kShoulderRight},
      {J::kElbowLeft, J::kElbowRight},
      {J::kWristLeft, J::kWristRight},
      {J::kHandLeft, J::kHandRight},
      {J::kHipLeft, J::kHipRight},
      {J::kKneeLeft, J::kKneeRight},
      {J::kAnkleLeft, J::kAnkleRight},
      {J::kFootLeft, J::kFootRight},
      {J::kHandTipLeft, J::kHandTipRight},
      {J::kThumbLeft, J::kThumbRight},
  }};
  for (const auto& [left, right] : kPairs) {
    if (joint == left) return right;
    if (joint == right) return left;
  }
  return joint;
}

std::string_view LimbPairName(LimbPair pair) {
  static constexpr std::array<std::string_view, kNumLimbPairs> kNames = {
      "shoulders", "arms", "hands", "hips", "legs", "feet"};
  const int index = static_cast<int>(pair);
  return index >= 0 && index < kNumLimbPairs ? kNames[index] : "";
}

const std::vector<body::KinectV2Joint>& LimbPairLeftJoints(LimbPair pair) {
  static const auto* kJoints = new std::array<std::vector<J>, kNumLimbPairs>{{
      {J::kShoulderLeft},
      {J::kElbowLeft, J::kWristLeft},
      {J::kHandLeft, J::kHandTipLeft, J::kThumbLeft},
      {J::kHipLeft},
      {J::kKneeLeft, J::kAnkleLeft},
      {J::kFootLeft},
  }};
  static const auto* kNone = new std::vector<J>();
  const int index = static_cast<int>(pair);
  return index >= 0 && index < kNumLimbPairs ? (*kJoints)[index] : *kNone;
}

absl::Status SkeletonFusionOptions::Validate() const {
  if (!(tracked_weight > 0 && std::isfinite(tracked_weight))) {
    return absl::InvalidArgumentError("tracked_weight must be positive and finite");
  }
  if (!(inferred_weight >= 0 && inferred_weight <= tracked_weight)) {
    return absl::InvalidArgumentError("inferred_weight must be within [0, tracked_weight]");
  }
  if (!(min_confidence >= 0 && min_confidence < 1)) {
    return absl::InvalidArgumentError("min_confidence must be within [0, 1)");
  }
  if (!(robust_scale_m > 0 && robust_scale_m < 10)) {
    return absl::InvalidArgumentError("robust_scale_m must be within (0, 10) metres");
  }
  if (max_iterations < 1 || !(convergence_m > 0)) {
    return absl::InvalidArgumentError("max_iterations must be >= 1 and convergence_m > 0");
  }
  if (!(swap_scale_m > 0 && swap_scale_m < 10)) {
    return absl::InvalidArgumentError("swap_scale_m must be within (0, 10) metres");
  }
  if (!(min_swap_gain >= 0 && std::isfinite(min_swap_gain))) {
    return absl::InvalidArgumentError("min_swap_gain must be finite and >= 0");
  }
  if (!(previous_weight >= 0 && std::isfinite(previous_weight))) {
    return absl::InvalidArgumentError("previous_weight must be finite and >= 0");
  }
  if (max_overruled_instants < 0) {
    return absl::InvalidArgumentError("max_overruled_instants must be >= 0");
  }
  if (!(inlier_weight_share > 0 && inlier_weight_share <= 1)) {
    return absl::InvalidArgumentError("inlier_weight_share must be within (0, 1]");
  }
  return absl::OkStatus();
}

std::string SkeletonFusionSummary::BriefReport() const {
  int used = 0, outlying = 0, rejected = 0;
  std::string swapped;
  for (const SensorFusionReport& s : sensors) {
    used += s.used;
    outlying += s.joints_outlying;
    rejected += s.joints_rejected;
    if (s.swapped_left_right) absl::StrAppend(&swapped, swapped.empty() ? "" : ",", s.sensor_id);
  }
  return absl::StrCat("fused ", num_tracked, " tracked + ", num_inferred, " inferred joints from ",
                      used, "/", sensors.size(),
                      " sensors; swapped: ", swapped.empty() ? "none" : swapped,
                      "; outlying estimates ", outlying, ", rejected ", rejected,
                      "; IRLS iterations <= ", max_iterations_used,
                      used_previous ? "; with the previous skeleton" : "");
}

absl::StatusOr<SkeletonFusionSummary> FuseSkeletons(const std::vector<SensorSkeleton>& sensors,
                                                    const SkeletonFusionOptions& options,
                                                    const FusedSkeleton* previous) {
  if (absl::Status status = CheckInput(sensors, options); !status.ok()) return status;
  SkeletonFusionSummary summary;
  summary.sensors.resize(sensors.size());
  std::vector<WorldView> views;
  for (size_t s = 0; s < sensors.size(); ++s) {
    summary.sensors[s].sensor_id = sensors[s].sensor_id;
    views.push_back(ToWorld(sensors[s], options, &summary.sensors[s]));
  }
  std::optional<WorldView> previous_view;
  if (previous && options.previous_weight > 0) {
    previous_view = PreviousView(*previous, options.previous_weight);
  }
  summary.used_previous = previous_view.has_value();
  ResolveSwaps(previous_view ? &*previous_view : nullptr, options, &views, &summary.sensors);
  for (int j = 0; j < kNumJoints; ++j) {
    const JointEstimates estimates = CollectEstimates(views, j);
    if (estimates.weight.empty()) continue;
    std::optional<Eigen::Vector3d> previous_m;
    if (previous_view && previous_view->weight[j] > 0) previous_m = previous_view->position_m[j];
    std::vector<double> share;
    int iterations = 0;
    FusedJoint& fused = summary.skeleton.joints[j];
    fused.position_in_world_m = RobustMean(estimates, StartPoint(estimates, previous_m, options),
                                           options, &share, &iterations);
    summary.max_iterations_used = std::max(summary.max_iterations_used, iterations);
    DescribeFused(estimates, share, views, j, options, &fused, &summary.sensors);
  }
  Tally(&summary);
  return summary;
}

SequentialSkeletonFusion::SequentialSkeletonFusion(SkeletonFusionOptions options,
                                                   int64_t max_gap_ns)
    : options_(options), max_gap_ns_(max_gap_ns) {}

absl::StatusOr<SkeletonFusionSummary> SequentialSkeletonFusion::Fuse(
    const std::vector<SensorSkeleton>& sensors, int64_t stamp_ns) {
  const bool recent =
      previous_ && stamp_ns >= previous_stamp_ns_ && stamp_ns - previous_stamp_ns_ <= max_gap_ns_;
  absl::StatusOr<SkeletonFusionSummary> summary =
      FuseSkeletons(sensors, options_, recent ? &*previous_ : nullptr);
  if (!summary.ok()) return summary;
  if (recent && options_.max_overruled_instants > 0) {
    // Did the previous skeleton make every sensor swap some limb pair?
    bool overruled = false;
    for (int p = 0; p < kNumLimbPairs && !overruled; ++p) {
      int used = 0, swapped = 0;
      for (const SensorFusionReport& report : summary->sensors) {
        if (!report.used) continue;
        ++used;
        swapped += report.swapped_limbs[p] ? 1 : 0;
      }
      overruled = used > 0 && swapped == used;
    }
    overruled_run_ = overruled ? overruled_run_ + 1 : 0;
    if (overruled_run_ >= options_.max_overruled_instants) {
      overruled_run_ = 0;
      summary = FuseSkeletons(sensors, options_, nullptr);
      if (!summary.ok()) return summary;
    }
  }
  if (summary->num_tracked + summary->num_inferred > 0) {
    previous_ = summary->skeleton;
    previous_stamp_ns_ = stamp_ns;
  }
  return summary;
}

}  // namespace reenact::tracking
