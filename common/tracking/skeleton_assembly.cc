#include "common/tracking/skeleton_assembly.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace reenact::tracking {
namespace {

using J = body::KinectV2Joint;
constexpr int kNumJoints = body::kNumKinectV2Joints;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Bone lengths of an adult whose SpineBase-SpineShoulder distance is
// kTorsoM (the procedural body's mean shape, within a centimetre; the
// forest's training bodies), metres.
constexpr double kTorsoM = 0.45;
double RestBoneM(J child) {
  switch (child) {
    case J::kHipLeft:
    case J::kHipRight:
      return 0.10;
    case J::kKneeLeft:
    case J::kKneeRight:
      return 0.43;
    case J::kAnkleLeft:
    case J::kAnkleRight:
      return 0.42;
    case J::kFootLeft:
    case J::kFootRight:
      return 0.16;
    case J::kShoulderLeft:
    case J::kShoulderRight:
      return 0.21;
    case J::kElbowLeft:
    case J::kElbowRight:
      return 0.31;
    case J::kWristLeft:
    case J::kWristRight:
      return 0.23;
    case J::kHandLeft:
    case J::kHandRight:
      return 0.075;
    case J::kHandTipLeft:
    case J::kHandTipRight:
    case J::kThumbLeft:
    case J::kThumbRight:
      return 0.08;
    default:
      return 0.0;
  }
}

// One level of a limb pair: the left and right joint and their parents'
// levels (-1: the torso joint `torso_parent`).
struct Level {
  J left, right;
  int parent_level;  // Index into the limb's levels, or -1.
  bool no_crossing;  // Left lies left of right (knees, ankles, elbows).
  // Times the coincide penalty where both picks are one place: the hips and
  // the shoulders can never be, knees and elbows hardly, hands and feet may.
  double coincide_factor = 1.0;
};

struct Limb {
  J torso_parent;
  std::vector<Level> levels;  // Parents before children.
};

const std::array<Limb, 2>& Limbs() {
  static const std::array<Limb, 2> limbs = {
      Limb{J::kSpineBase,
           {{J::kHipLeft, J::kHipRight, -1, false, 10.0},
            {J::kKneeLeft, J::kKneeRight, 0, true, 3.0},
            {J::kAnkleLeft, J::kAnkleRight, 1, true},
            {J::kFootLeft, J::kFootRight, 2, false}}},
      Limb{J::kSpineShoulder,
           {{J::kShoulderLeft, J::kShoulderRight, -1, false, 10.0},
            {J::kElbowLeft, J::kElbowRight, 0, true, 3.0},
            {J::kWristLeft, J::kWristRight, 1, false},
            {J::kHandLeft, J::kHandRight, 2, false},
            {J::kHandTipLeft, J::kHandTipRight, 3, false},
            {J::kThumbLeft, J::kThumbRight, 2, false}}}};
  return limbs;
}

struct Candidate {
  Eigen::Vector3f p;
  float share_left = 0, share_right = 0;  // Of the level's left / right joint's votes.
};

// An ordered choice at one level: candidate a for the left joint, b for the
// right one.
struct Pair {
  int a, b;
};

class Assembler {
 public:
  Assembler(const JointEvidence& evidence, const std::array<TrackedJoint, kNumJoints>* previous,
            const SkeletonAssemblyOptions& options)
      : e_(evidence), previous_(previous), o_(options) {}

  std::array<TrackedJoint, kNumJoints> Run() {
    std::array<TrackedJoint, kNumJoints> out;
    for (int j = 0; j < kNumJoints; ++j) {
      if (e_.modes[j].empty()) continue;
      out[j].position_in_camera_m = e_.modes[j][0].position_m.cast<double>();
      out[j].confidence = std::clamp(static_cast<double>(e_.modes[j][0].share), 0.0, 1.0);
      out[j].state = JointState::kInferred;
    }
    const auto torso = [&](J j) -> const std::vector<JointMode>& {
      return e_.modes[body::Index(j)];
    };
    if (torso(J::kSpineBase).empty() || torso(J::kSpineShoulder).empty()) return out;
    const double torso_m =
        (torso(J::kSpineShoulder)[0].position_m - torso(J::kSpineBase)[0].position_m).norm();
    scale_ = std::clamp(torso_m / kTorsoM, 0.6, 1.4);

    // Per limb and per choice of its root pair: the best total of the rest.
    std::array<std::vector<LimbSolution>, 2> solutions;
    for (int l = 0; l < 2; ++l) solutions[l] = SolveLimb(Limbs()[l]);
    // Tie hips and shoulders (twist term).
    double best = -kInf;
    int best_leg = -1, best_arm = -1;
    for (size_t a = 0; a < solutions[0].size(); ++a) {
      for (size_t b = 0; b < solutions[1].size(); ++b) {
        const LimbSolution& leg = solutions[0][a];
        const LimbSolution& arm = solutions[1][b];
        double score = leg.score + arm.score;
        if (leg.lateral.dot(arm.lateral) < 0) score -= o_.twist_penalty;
        if (score > best)
          best = score, best_leg = static_cast<int>(a), best_arm = static_cast<int>(b);
      }
    }
    if (best_leg >= 0) Write(solutions[0][best_leg], &out);
    if (best_arm >= 0) Write(solutions[1][best_arm], &out);
    return out;
  }

 private:
  struct LimbSolution {
    double score = -kInf;
    Eigen::Vector3f lateral = Eigen::Vector3f::Zero();  // Root left - root right.
    // Per level: the joints and their picks.
    std::vector<std::pair<J, Eigen::Vector3f>> picks;
    std::vector<std::pair<J, float>> shares;
  };

  double Rho(double s) const { return std::min(s, o_.cap); }

  double BonePenalty(J child, const Eigen::Vector3f& child_p,
                     const Eigen::Vector3f& parent_p) const {
    const double length = RestBoneM(child) * scale_;
    if (length <= 0) return 0;
    const double d = ((child_p - parent_p).norm() - length) / (o_.bone_sigma * length);
    return Rho(d * d);
  }

  double TemporalPenalty(J joint, const Eigen::Vector3f& p) const {
    if (!previous_) return 0;
    const TrackedJoint& prev = (*previous_)[body::Index(joint)];
    if (prev.state == JointState::kNotTracked || !prev.position_in_camera_m.allFinite()) return 0;
    const double d = (p.cast<double>() - prev.position_in_camera_m).norm() / o_.temporal_sigma_m;
    return Rho(d * d);
  }

  std::vector<Candidate> Candidates(const Level& level) const {
    std::vector<Candidate> out;
    const auto add = [&](const Eigen::Vector3f& p) {
      for (const Candidate& c : out) {
        if ((c.p - p).norm() < o_.merge_distance_m) return;
      }
      out.push_back(
          {p, e_.share_at(body::Index(level.left), p), e_.share_at(body::Index(level.right), p)});
    };
    for (const JointMode& m : e_.modes[body::Index(level.left)]) add(m.position_m);
    for (const JointMode& m : e_.modes[body::Index(level.right)]) add(m.position_m);
    return out;
  }

  // Score of a pair at a level without its parents' bones.
  double Unary(const Level& level, const std::vector<Candidate>& c, const Pair& p) const {
    double s = o_.vote_weight * (c[p.a].share_left + c[p.b].share_right);
    if ((c[p.a].p - c[p.b].p).norm() < o_.min_pair_distance_m) {
      s -= o_.coincide_penalty * level.coincide_factor;
    }
    s -= TemporalPenalty(level.left, c[p.a].p) + TemporalPenalty(level.right, c[p.b].p);
    return s;
  }

  // Dynamic programming over the levels of one limb for every root pair.
  std::vector<LimbSolution> SolveLimb(const Limb& limb) const {
    const int n = static_cast<int>(limb.levels.size());
    std::vector<std::vector<Candidate>> cand(n);
    std::vector<std::vector<Pair>> pairs(n);
    for (int i = 0; i < n; ++i) {
      cand[i] = Candidates(limb.levels[i]);
      const int k = static_cast<int>(cand[i].size());
      for (int a = 0; a < k; ++a) {
        for (int b = 0; b < k; ++b) pairs[i].push_back({a, b});
      }
    }
    const Eigen::Vector3f torso_p = e_.modes[body::Index(limb.torso_parent)][0].position_m;
    std::vector<LimbSolution> solutions;
    if (cand[0].empty()) return solutions;
    // Levels form a tree (the thumb hangs from the wrist): best[i][q] is the
    // best score of level i's subtree given pair q at level i, computed
    // bottom-up (levels are listed parents first); the root level is scored
    // per pair below.
    std::vector<std::vector<int>> children(n);
    for (int i = 1; i < n; ++i) children[limb.levels[i].parent_level].push_back(i);
    std::vector<std::vector<double>> best(n);
    std::vector<std::vector<std::vector<int>>> arg(n);  // [level][pair][child slot]
    for (int i = n - 1; i >= 0; --i) {
      best[i].assign(pairs[i].size(), 0.0);
      arg[i].assign(pairs[i].size(), std::vector<int>(children[i].size(), -1));
      for (size_t q = 0; q < pairs[i].size(); ++q) {
        double s = Unary(limb.levels[i], cand[i], pairs[i][q]);
        if (i == 0) {
          s -= BonePenalty(limb.levels[0].left, cand[0][pairs[0][q].a].p, torso_p) +
               BonePenalty(limb.levels[0].right, cand[0][pairs[0][q].b].p, torso_p);
        }
        for (size_t c = 0; c < children[i].size(); ++c) {
          const auto [score, which] = BestChild(limb, cand, pairs, best, children[i][c], i, q);
          s += score;
          arg[i][q][c] = which;
        }
        best[i][q] = s;
      }
    }
    for (size_t root = 0; root < pairs[0].size(); ++root) {
      LimbSolution solution;
      solution.score = best[0][root];
      const Pair& r = pairs[0][root];
      solution.lateral = cand[0][r.a].p - cand[0][r.b].p;
      // Walk down. A pick's confidence is its share of the votes times how
      // well its bone and its ancestors' bones fit (a hidden hand voted
      // somewhere implausible counts for little in fusion and refinement).
      // A pick whose bone is implausible (beyond extrapolate_sigmas) is
      // replaced by the straight continuation of its parent's bone: a better
      // guess for a hidden hand than wherever its votes went.
      std::vector<int> chosen(n, -1);
      std::vector<std::array<double, 2>> fit(n, {1.0, 1.0});
      std::vector<std::array<Eigen::Vector3f, 2>> pos(n);
      chosen[0] = static_cast<int>(root);
      for (int i = 0; i < n; ++i) {
        if (chosen[i] < 0) continue;
        const Pair& p = pairs[i][chosen[i]];
        const Level& level = limb.levels[i];
        const int up = level.parent_level;
        for (int side = 0; side < 2; ++side) {
          const J joint = side == 0 ? level.left : level.right;
          const Candidate& c = cand[i][side == 0 ? p.a : p.b];
          const Eigen::Vector3f parent = up < 0 ? torso_p : pos[up][side];
          const double term = BonePenalty(joint, c.p, parent);
          fit[i][side] = std::exp(-0.5 * term) * (up < 0 ? 1.0 : fit[up][side]);
          pos[i][side] = c.p;
          // Only below elbows and knees: the continuation of a shoulder or
          // hip line (a T-pose limb) is no better guess than the votes.
          const int up2 = up < 0 ? -1 : limb.levels[up].parent_level;
          if (up2 >= 0 && term > o_.extrapolate_sigmas * o_.extrapolate_sigmas) {
            const Eigen::Vector3f grand = pos[up2][side];
            const Eigen::Vector3f dir = parent - grand;
            if (dir.norm() > 1e-3f) {
              pos[i][side] =
                  parent + dir.normalized() * static_cast<float>(RestBoneM(joint) * scale_);
            }
          }
          // Evidence that the joint is here, whichever side the forest
          // took it for (the side is the assembly's decision).
          const float share = std::max(c.share_left, c.share_right);
          solution.picks.push_back({joint, pos[i][side]});
          solution.shares.push_back({joint, static_cast<float>(share * fit[i][side])});
        }
        for (size_t c = 0; c < children[i].size(); ++c) {
          chosen[children[i][c]] = arg[i][chosen[i]][c];
        }
      }
      solutions.push_back(std::move(solution));
    }
    return solutions;
  }

  // The best pair at child level `i` given pair q at its parent level:
  // its subtree score less the bones to the parent and the crossing term.
  std::pair<double, int> BestChild(const Limb& limb,
                                   const std::vector<std::vector<Candidate>>& cand,
                                   const std::vector<std::vector<Pair>>& pairs,
                                   const std::vector<std::vector<double>>& best, int i,
                                   int parent_level, size_t q) const {
    const Level& level = limb.levels[i];
    const Eigen::Vector3f& pl = cand[parent_level][pairs[parent_level][q].a].p;
    const Eigen::Vector3f& pr = cand[parent_level][pairs[parent_level][q].b].p;
    const Eigen::Vector3f lateral = pl - pr;
    double top = -kInf;
    int which = -1;
    for (size_t k = 0; k < pairs[i].size(); ++k) {
      if (cand[i].empty()) break;
      const Eigen::Vector3f& a = cand[i][pairs[i][k].a].p;
      const Eigen::Vector3f& b = cand[i][pairs[i][k].b].p;
      double s = best[i][k] - BonePenalty(level.left, a, pl) - BonePenalty(level.right, b, pr);
      if (level.no_crossing && (a - b).dot(lateral) < 0) s -= o_.crossing_penalty;
      if (s > top) top = s, which = static_cast<int>(k);
    }
    return {which >= 0 ? top : 0.0, which};
  }

  void Write(const LimbSolution& s, std::array<TrackedJoint, kNumJoints>* out) const {
    for (size_t i = 0; i < s.picks.size(); ++i) {
      TrackedJoint& joint = (*out)[body::Index(s.picks[i].first)];
      joint.position_in_camera_m = s.picks[i].second.cast<double>();
      joint.confidence = std::clamp(static_cast<double>(s.shares[i].second), 0.0, 1.0);
      joint.state = JointState::kInferred;
    }
  }

  const JointEvidence& e_;
  const std::array<TrackedJoint, kNumJoints>* previous_;
  const SkeletonAssemblyOptions& o_;
  double scale_ = 1.0;
};

}  // namespace

absl::Status SkeletonAssemblyOptions::Validate() const {
  if (!(vote_weight >= 0) || !(bone_sigma > 0) || !(crossing_penalty >= 0) ||
      !(min_pair_distance_m >= 0) || !(coincide_penalty >= 0) || !(temporal_sigma_m > 0) ||
      !(twist_penalty >= 0) || !(extrapolate_sigmas > 0) || !(cap > 0) ||
      !(merge_distance_m >= 0)) {
    return absl::InvalidArgumentError(
        "skeleton assembly: weights and penalties must be >= 0, sigmas and cap > 0");
  }
  return absl::OkStatus();
}

std::array<TrackedJoint, body::kNumKinectV2Joints> AssembleSkeleton(
    const JointEvidence& evidence,
    const std::array<TrackedJoint, body::kNumKinectV2Joints>* previous,
    const SkeletonAssemblyOptions& options) {
  return Assembler(evidence, previous, options).Run();
}

}  // namespace reenact::tracking
