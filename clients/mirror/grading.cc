#include "clients/mirror/grading.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;

// The learner's part is seen when both of its joints were.
bool PartSeen(const GradeFrame& frame, BodyPart part) {
  const PartBone bone = BodyPartBone(part);
  return frame.seen[body::Index(bone.from)] && frame.seen[body::Index(bone.to)];
}

PerPart<Eigen::Vector3d> Directions(const GradeFrame& frame) {
  if (!frame.pose) return {};
  return PartDirectionsInSpine(*frame.pose);
}

bool AnyPart(const PerPart<Eigen::Vector3d>& directions) {
  return std::any_of(directions.begin(), directions.end(),
                     [](const auto& d) { return d.has_value(); });
}

// The upper part of a lower arm or leg (whose angle with it is the bend of
// the elbow or knee), or nullopt.
std::optional<BodyPart> UpperOf(BodyPart part) {
  switch (part) {
    case BodyPart::kLeftLowerArm:
      return BodyPart::kLeftUpperArm;
    case BodyPart::kRightLowerArm:
      return BodyPart::kRightUpperArm;
    case BodyPart::kLeftLowerLeg:
      return BodyPart::kLeftUpperLeg;
    case BodyPart::kRightLowerLeg:
      return BodyPart::kRightUpperLeg;
    default:
      return std::nullopt;
  }
}

std::string BendWords(BodyPart part) {
  switch (part) {
    case BodyPart::kLeftLowerArm:
      return "left elbow";
    case BodyPart::kRightLowerArm:
      return "right elbow";
    case BodyPart::kLeftLowerLeg:
      return "left knee";
    default:
      return "right knee";
  }
}

// Degrees rounded to a multiple of 5, at least 5.
int RoundDeg(double deg) { return std::max(5, static_cast<int>(std::lround(deg / 5.0)) * 5); }

// A correction in words for `part` at the pair (see grading.h).
std::string CorrectionText(BodyPart part, double time_s, double error_deg,
                           const PerPart<Eigen::Vector3d>& learner,
                           const PerPart<Eigen::Vector3d>& teacher) {
  const std::string at = absl::StrFormat(" at %.1f s", time_s);
  if (const std::optional<BodyPart> upper = UpperOf(part)) {
    const auto& lu = learner[Index(*upper)];
    const auto& tu = teacher[Index(*upper)];
    const auto& ll = learner[Index(part)];
    const auto& tl = teacher[Index(part)];
    if (lu && tu && ll && tl) {
      const double bend_diff = AngleBetweenDeg(*tu, *tl) - AngleBetweenDeg(*lu, *ll);
      if (std::abs(bend_diff) >= 0.5 * error_deg) {
        return bend_diff > 0 ? absl::StrCat(BendWords(part), ": bend about ", RoundDeg(bend_diff),
                                            " degrees more", at)
                             : absl::StrCat(BendWords(part), ": straighten about ",
                                            RoundDeg(-bend_diff), " degrees", at);
      }
    }
  }
  const auto& l = learner[Index(part)];
  const auto& t = teacher[Index(part)];
  const std::string who = PartWords(part);
  if (!l || !t) return absl::StrCat(who, ": about ", RoundDeg(error_deg), " degrees off", at);
  // Spine frame axes: x the person's left, y up, z forward.
  const Eigen::Vector3d d = *t - *l;
  int axis = 0;
  d.cwiseAbs().maxCoeff(&axis);
  static constexpr std::array<std::array<const char*, 2>, 3> kWords = {{
      {"move it to your left", "move it to your right"},
      {"raise it", "lower it"},
      {"bring it forward", "take it back"},
  }};
  const char* words = kWords[axis][d[axis] > 0 ? 0 : 1];
  return absl::StrCat(who, ": ", words, " about ", RoundDeg(error_deg), " degrees", at);
}

}  // namespace

void MarkValidJointsSeen(GradeFrame& frame) {
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    frame.seen[j] =
        frame.pose.has_value() && IsJointUsable(*frame.pose, static_cast<KinectV2Joint>(j));
  }
}

std::string_view PartStatusName(PartStatus status) {
  switch (status) {
    case PartStatus::kGraded:
      return "graded";
    case PartStatus::kNoLearner:
      return "no_learner";
    case PartStatus::kNotSeen:
      return "not_seen";
    case PartStatus::kNoTeacherPart:
      return "no_teacher_part";
  }
  return "unknown";
}

namespace {
std::string ReasonWords(PartStatus status) {
  switch (status) {
    case PartStatus::kNoLearner:
      return "learner not in view";
    case PartStatus::kNotSeen:
      return "hidden from the sensor";
    case PartStatus::kNoTeacherPart:
      return "teacher has no such joints";
    default:
      return "";
  }
}
}  // namespace

std::string PartWords(BodyPart part) {
  std::string words(BodyPartName(part));
  std::replace(words.begin(), words.end(), '_', ' ');
  return words;
}

absl::Status GradeOptions::Validate() const {
  RETURN_IF_ERROR(dtw.Validate());
  if (!(smoothing_s >= 0.0 && std::isfinite(smoothing_s))) {
    return absl::InvalidArgumentError("smoothing_s must be finite and >= 0");
  }
  if (max_corrections < 0 || max_corrections > kNumBodyParts) {
    return absl::InvalidArgumentError("max_corrections must be in 0..13");
  }
  if (!(min_correction_deg >= 0.0 && min_correction_deg <= 180.0)) {
    return absl::InvalidArgumentError("min_correction_deg must be in [0, 180]");
  }
  if (max_worst_moments < 0) return absl::InvalidArgumentError("max_worst_moments must be >= 0");
  if (!(worst_separation_s >= 0.0 && std::isfinite(worst_separation_s))) {
    return absl::InvalidArgumentError("worst_separation_s must be finite and >= 0");
  }
  if (!(min_part_coverage >= 0.0 && min_part_coverage <= 1.0)) {
    return absl::InvalidArgumentError("min_part_coverage must be in [0, 1]");
  }
  if (!(motion_weight_floor_deg >= 0.0 && motion_weight_floor_deg <= 180.0)) {
    return absl::InvalidArgumentError("motion_weight_floor_deg must be in [0, 180]");
  }
  return absl::OkStatus();
}

namespace {
absl::StatusOr<Grade> GradeImpl(const std::vector<GradeFrame>& teacher,
                                const std::vector<GradeFrame>& learner,
                                const std::vector<FramePair>* given_pairs,
                                const GradeOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (teacher.empty()) return absl::InvalidArgumentError("the teacher has no frames");
  if (learner.empty()) return absl::InvalidArgumentError("the learner has no frames");
  std::vector<PerPart<Eigen::Vector3d>> teacher_dirs, learner_dirs;
  teacher_dirs.reserve(teacher.size());
  learner_dirs.reserve(learner.size());
  for (const GradeFrame& f : teacher) teacher_dirs.push_back(Directions(f));
  for (const GradeFrame& f : learner) learner_dirs.push_back(Directions(f));
  if (std::none_of(teacher_dirs.begin(), teacher_dirs.end(), AnyPart)) {
    return absl::InvalidArgumentError(
        "the teacher has no frame with a usable skeleton (a spine and at least one part)");
  }
  if (std::none_of(learner_dirs.begin(), learner_dirs.end(), AnyPart)) {
    return absl::InvalidArgumentError(
        "the learner has no frame with a usable skeleton (a spine and at least one part)");
  }

  Grade grade;
  grade.num_teacher_frames = static_cast<int>(teacher.size());
  grade.num_learner_frames = static_cast<int>(learner.size());
  for (const GradeFrame& f : learner) grade.learner_frames_without_skeleton += !f.pose.has_value();
  Alignment alignment;
  if (given_pairs != nullptr) {
    for (const FramePair& fp : *given_pairs) {
      if (fp.learner_frame < 0 || fp.learner_frame >= grade.num_learner_frames ||
          fp.teacher_frame < 0 || fp.teacher_frame >= grade.num_teacher_frames) {
        return absl::InvalidArgumentError(absl::StrCat("pair (learner ", fp.learner_frame,
                                                       ", teacher ", fp.teacher_frame,
                                                       ") is outside the sequences"));
      }
    }
    alignment.pairs = *given_pairs;
  } else if (options.use_dtw) {
    ASSIGN_OR_RETURN(alignment, AlignDirectionsByDtw(learner_dirs, teacher_dirs, options.dtw));
    grade.used_dtw = true;
  } else {
    alignment = AlignOneToOne(grade.num_learner_frames, grade.num_teacher_frames);
  }

  // Per pair and part: graded or why not.
  grade.pairs.reserve(alignment.pairs.size());
  for (const FramePair& fp : alignment.pairs) {
    GradedPair pair;
    pair.learner_frame = fp.learner_frame;
    pair.teacher_frame = fp.teacher_frame;
    const GradeFrame& lf = learner[fp.learner_frame];
    pair.time_s = lf.time_s;
    const auto& ld = learner_dirs[fp.learner_frame];
    const auto& td = teacher_dirs[fp.teacher_frame];
    double sum = 0.0;
    int n = 0;
    for (int p = 0; p < kNumBodyParts; ++p) {
      PartStatus& status = pair.status[p];
      if (!lf.pose) {
        status = PartStatus::kNoLearner;
      } else if (!td[p]) {
        status = PartStatus::kNoTeacherPart;
      } else if (!ld[p] || !PartSeen(lf, BodyPartAt(p))) {
        status = PartStatus::kNotSeen;
      } else {
        status = PartStatus::kGraded;
        pair.error_deg[p] = AngleBetweenDeg(*ld[p], *td[p]);
        sum += *pair.error_deg[p];
        ++n;
      }
    }
    if (n > 0) pair.mean_error_deg = sum / n;
    grade.pairs.push_back(pair);
  }
  const int num_pairs = static_cast<int>(grade.pairs.size());

  // Moving mean over +-smoothing_s / 2 of learner time (two pointers: the
  // pair times never decrease).
  const double half = 0.5 * options.smoothing_s;
  for (int p = 0; p < kNumBodyParts; ++p) {
    int lo = 0, hi = 0;  // Window [lo, hi).
    double sum = 0.0;
    int n = 0;
    for (int i = 0; i < num_pairs; ++i) {
      const double t = grade.pairs[i].time_s;
      while (hi < num_pairs && grade.pairs[hi].time_s <= t + half) {
        if (const auto& e = grade.pairs[hi].error_deg[p]) sum += *e, ++n;
        ++hi;
      }
      while (lo < hi && grade.pairs[lo].time_s < t - half) {
        if (const auto& e = grade.pairs[lo].error_deg[p]) sum -= *e, --n;
        ++lo;
      }
      if (n > 0) grade.pairs[i].smoothed_deg[p] = std::max(0.0, sum / n);
    }
  }

  // Per part, then overall.
  double total_sum = 0.0;
  int64_t total_n = 0, graded_part_pairs = 0;
  for (int p = 0; p < kNumBodyParts; ++p) {
    PartGrade& part = grade.parts[p];
    double sum = 0.0;
    std::map<PartStatus, int> reasons;
    for (const GradedPair& pair : grade.pairs) {
      if (const auto& e = pair.error_deg[p]) {
        sum += *e;
        ++part.graded_pairs;
      } else {
        ++reasons[pair.status[p]];
      }
    }
    graded_part_pairs += part.graded_pairs;
    part.coverage = num_pairs > 0 ? static_cast<double>(part.graded_pairs) / num_pairs : 0.0;
    if (part.graded_pairs > 0) part.mean_error_deg = sum / part.graded_pairs;
    part.graded = part.graded_pairs > 0 && part.coverage >= options.min_part_coverage;
    if (part.graded) {
      total_sum += sum;
      total_n += part.graded_pairs;
    } else {
      PartStatus commonest = PartStatus::kNotSeen;
      int most = -1;
      for (const auto& [status, count] : reasons) {
        if (count > most) most = count, commonest = status;
      }
      part.not_graded_reason = ReasonWords(commonest);
    }
  }
  if (total_n > 0) grade.mean_error_deg = total_sum / static_cast<double>(total_n);

  // The teacher's motion per part, and the action-weighted error.
  const std::array<double, kNumBodyParts> motion = PartMotionDeg(teacher_dirs);
  double weighted_sum = 0.0, weight_sum = 0.0;
  for (int p = 0; p < kNumBodyParts; ++p) {
    PartGrade& part = grade.parts[p];
    part.teacher_motion_deg = motion[p];
    if (!part.graded) continue;
    const double weight = part.teacher_motion_deg + options.motion_weight_floor_deg;
    weighted_sum += weight * *part.mean_error_deg;
    weight_sum += weight;
  }
  if (weight_sum > 0.0) {
    grade.action_error_deg = weighted_sum / weight_sum;
  } else if (grade.mean_error_deg) {
    grade.action_error_deg = grade.mean_error_deg;  // Floor 0, a frozen teacher.
  }
  if (num_pairs > 0) {
    grade.coverage = static_cast<double>(graded_part_pairs) / (num_pairs * kNumBodyParts);
  }

  // Corrections: each graded part's worst smoothed moment, largest first.
  for (int p = 0; p < kNumBodyParts; ++p) {
    if (!grade.parts[p].graded) continue;
    int best = -1;
    double worst = options.min_correction_deg;
    for (int i = 0; i < num_pairs; ++i) {
      const auto& s = grade.pairs[i].smoothed_deg[p];
      if (s && *s >= worst && grade.pairs[i].error_deg[p]) worst = *s, best = i;
    }
    if (best < 0) continue;
    Correction c;
    c.part = BodyPartAt(p);
    c.pair_index = best;
    c.time_s = grade.pairs[best].time_s;
    c.error_deg = worst;
    grade.corrections.push_back(std::move(c));
  }
  std::stable_sort(
      grade.corrections.begin(), grade.corrections.end(),
      [](const Correction& a, const Correction& b) { return a.error_deg > b.error_deg; });
  if (static_cast<int>(grade.corrections.size()) > options.max_corrections) {
    grade.corrections.resize(options.max_corrections);
  }
  for (Correction& c : grade.corrections) {
    const GradedPair& pair = grade.pairs[c.pair_index];
    c.text = CorrectionText(c.part, c.time_s, c.error_deg, learner_dirs[pair.learner_frame],
                            teacher_dirs[pair.teacher_frame]);
  }

  // Worst moments: the pairs with the largest smoothed part error, apart.
  std::vector<std::pair<double, int>> scored;  // (error, pair index)
  std::vector<int> part_at(num_pairs, 0);
  for (int i = 0; i < num_pairs; ++i) {
    double worst = -1.0;
    for (int p = 0; p < kNumBodyParts; ++p) {
      const auto& s = grade.pairs[i].smoothed_deg[p];
      if (grade.parts[p].graded && s && grade.pairs[i].error_deg[p] && *s > worst) {
        worst = *s, part_at[i] = p;
      }
    }
    if (worst >= 0.0) scored.emplace_back(worst, i);
  }
  std::stable_sort(scored.begin(), scored.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  for (const auto& [error, i] : scored) {
    if (static_cast<int>(grade.worst_moments.size()) >= options.max_worst_moments) break;
    const double t = grade.pairs[i].time_s;
    const bool near = std::any_of(
        grade.worst_moments.begin(), grade.worst_moments.end(),
        [&](const WorstMoment& m) { return std::abs(m.time_s - t) < options.worst_separation_s; });
    if (near) continue;
    WorstMoment m;
    m.pair_index = i;
    m.learner_frame = grade.pairs[i].learner_frame;
    m.teacher_frame = grade.pairs[i].teacher_frame;
    m.time_s = t;
    m.part = BodyPartAt(part_at[i]);
    m.error_deg = error;
    grade.worst_moments.push_back(m);
  }
  return grade;
}
}  // namespace

std::array<double, kNumBodyParts> PartMotionDeg(
    const std::vector<PerPart<Eigen::Vector3d>>& directions) {
  std::array<double, kNumBodyParts> motion{};
  for (int p = 0; p < kNumBodyParts; ++p) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& d : directions) {
      if (d[p]) sum += *d[p];
    }
    if (sum.norm() <= 1e-9) continue;
    const Eigen::Vector3d mean = sum.normalized();
    double angle_sum = 0.0;
    int n = 0;
    for (const auto& d : directions) {
      if (d[p]) angle_sum += AngleBetweenDeg(*d[p], mean), ++n;
    }
    motion[p] = angle_sum / n;
  }
  return motion;
}

absl::StatusOr<Grade> GradeSequences(const std::vector<GradeFrame>& teacher,
                                     const std::vector<GradeFrame>& learner,
                                     const GradeOptions& options) {
  return GradeImpl(teacher, learner, nullptr, options);
}

absl::StatusOr<Grade> GradePairs(const std::vector<GradeFrame>& teacher,
                                 const std::vector<GradeFrame>& learner,
                                 const std::vector<FramePair>& pairs, const GradeOptions& options) {
  return GradeImpl(teacher, learner, &pairs, options);
}

namespace {
nlohmann::json OptionalJson(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}
}  // namespace

std::string GradeJson(const Grade& grade, bool with_pairs) {
  nlohmann::json parts = nlohmann::json::object();
  nlohmann::json not_graded = nlohmann::json::array();
  for (int p = 0; p < kNumBodyParts; ++p) {
    const PartGrade& part = grade.parts[p];
    const std::string name(BodyPartName(BodyPartAt(p)));
    parts[name] = {{"mean_error_deg", OptionalJson(part.mean_error_deg)},
                   {"teacher_motion_deg", part.teacher_motion_deg},
                   {"graded", part.graded},
                   {"coverage", part.coverage},
                   {"graded_pairs", part.graded_pairs}};
    if (!part.graded) {
      parts[name]["reason"] = part.not_graded_reason;
      not_graded.push_back({{"part", name}, {"reason", part.not_graded_reason}});
    }
  }
  nlohmann::json corrections = nlohmann::json::array();
  for (const Correction& c : grade.corrections) {
    corrections.push_back({{"part", std::string(BodyPartName(c.part))},
                           {"time_s", c.time_s},
                           {"error_deg", c.error_deg},
                           {"text", c.text}});
  }
  nlohmann::json worst = nlohmann::json::array();
  for (const WorstMoment& m : grade.worst_moments) {
    worst.push_back({{"time_s", m.time_s},
                     {"learner_frame", m.learner_frame},
                     {"teacher_frame", m.teacher_frame},
                     {"part", std::string(BodyPartName(m.part))},
                     {"error_deg", m.error_deg}});
  }
  nlohmann::json j = {{"mean_error_deg", OptionalJson(grade.mean_error_deg)},
                      {"action_error_deg", OptionalJson(grade.action_error_deg)},
                      {"coverage", grade.coverage},
                      {"dtw", grade.used_dtw},
                      {"learner_frames", grade.num_learner_frames},
                      {"learner_frames_without_skeleton", grade.learner_frames_without_skeleton},
                      {"teacher_frames", grade.num_teacher_frames},
                      {"pairs", grade.pairs.size()},
                      {"parts", parts},
                      {"not_graded", not_graded},
                      {"corrections", corrections},
                      {"worst_moments", worst}};
  if (with_pairs) {
    nlohmann::json rows = nlohmann::json::array();
    for (const GradedPair& pair : grade.pairs) {
      nlohmann::json errors = nlohmann::json::object();
      for (int p = 0; p < kNumBodyParts; ++p) {
        errors[std::string(BodyPartName(BodyPartAt(p)))] =
            pair.error_deg[p] ? nlohmann::json(*pair.error_deg[p])
                              : nlohmann::json(std::string(PartStatusName(pair.status[p])));
      }
      rows.push_back({{"time_s", pair.time_s},
                      {"learner_frame", pair.learner_frame},
                      {"teacher_frame", pair.teacher_frame},
                      {"mean_error_deg", OptionalJson(pair.mean_error_deg)},
                      {"parts", errors}});
    }
    j["pair_errors"] = rows;
  }
  return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace reenact::mirror
