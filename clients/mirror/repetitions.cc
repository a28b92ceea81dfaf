#include "clients/mirror/repetitions.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/mirror/pose_comparison.h"
#include "common/base/status_macros.h"

namespace reenact::mirror {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

using Directions = PerPart<Eigen::Vector3d>;

std::vector<Directions> AllDirections(const std::vector<GradeFrame>& frames) {
  std::vector<Directions> out;
  out.reserve(frames.size());
  for (const GradeFrame& f : frames) {
    out.push_back(f.pose ? PartDirectionsInSpine(*f.pose) : Directions{});
  }
  return out;
}

// Action-weighted mean part angle of a pair, or `missing` when no part is in
// both.
double WeightedDistanceDeg(const Directions& learner, const Directions& teacher,
                           const std::array<double, kNumBodyParts>& weight, double missing) {
  double sum = 0.0, weights = 0.0;
  for (int p = 0; p < kNumBodyParts; ++p) {
    if (!learner[p] || !teacher[p]) continue;
    sum += weight[p] * AngleBetweenDeg(*learner[p], *teacher[p]);
    weights += weight[p];
  }
  return weights > 0.0 ? sum / weights : missing;
}

// Subsequence DTW table, learner-major: accumulated cost, path length, the
// learner frame where the path began, and the step that reached each cell.
enum Step : uint8_t { kStart = 0, kDiagonal, kFromPreviousLearner, kFromPreviousTeacher };
struct Table {
  int num_learner = 0;
  int num_teacher = 0;
  std::vector<double> cost;
  std::vector<int32_t> length;
  std::vector<int32_t> start;
  std::vector<Step> step;
  size_t At(int i, int j) const { return static_cast<size_t>(i) * num_teacher + j; }
};

// Fills the table over the learner frames not yet taken (`taken`): the
// least summed distance of a path from the teacher's first frame, started at
// any learner frame, to each cell.
void Fill(const std::vector<double>& pair_cost, const std::vector<bool>& taken, Table& t) {
  std::fill(t.cost.begin(), t.cost.end(), kInf);
  for (int i = 0; i < t.num_learner; ++i) {
    if (taken[i]) continue;
    for (int j = 0; j < t.num_teacher; ++j) {
      const size_t at = t.At(i, j);
      const double d = pair_cost[at];
      if (j == 0) {  // The teacher's first frame starts a path anywhere.
        t.cost[at] = d, t.length[at] = 1, t.start[at] = i, t.step[at] = kStart;
        continue;
      }
      auto consider = [&](int pi, int pj, Step step) {
        if (pi < 0) return;
        const size_t from = t.At(pi, pj);
        if (t.cost[from] == kInf || t.cost[from] + d >= t.cost[at]) return;
        t.cost[at] = t.cost[from] + d, t.length[at] = t.length[from] + 1;
        t.start[at] = t.start[from], t.step[at] = step;
      };
      consider(i - 1, j - 1, kDiagonal);
      consider(i, j - 1, kFromPreviousTeacher);
      consider(i - 1, j, kFromPreviousLearner);
    }
  }
}

std::vector<FramePair> Backtrack(const Table& t, int end_learner) {
  std::vector<FramePair> pairs;
  int i = end_learner;
  int j = t.num_teacher - 1;
  while (true) {
    pairs.push_back({i, j});
    const Step step = t.step[t.At(i, j)];
    if (step == kStart) break;
    if (step != kFromPreviousTeacher) --i;
    if (step != kFromPreviousLearner) --j;
  }
  std::reverse(pairs.begin(), pairs.end());
  return pairs;
}

// Largest angle of any part present in `window` from its mean there.
double SpreadDeg(const std::vector<Directions>& dirs, const std::vector<GradeFrame>& frames,
                 int first, int last) {
  double worst = 0.0;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const PartBone bone = BodyPartBone(BodyPartAt(p));
    auto seen = [&](int k) {
      return dirs[k][p] && frames[k].seen[body::Index(bone.from)] &&
             frames[k].seen[body::Index(bone.to)];
    };
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int k = first; k <= last; ++k) {
      if (seen(k)) sum += *dirs[k][p];
    }
    if (sum.norm() <= 1e-9) continue;
    const Eigen::Vector3d mean = sum.normalized();
    for (int k = first; k <= last; ++k) {
      if (seen(k)) worst = std::max(worst, AngleBetweenDeg(*dirs[k][p], mean));
    }
  }
  return worst;
}

}  // namespace

absl::Status RepetitionOptions::Validate() const {
  if (!(max_distance_deg > 0.0 && max_distance_deg <= 180.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("max_distance_deg must be in (0, 180]: ", max_distance_deg));
  }
  if (!(min_length_ratio > 0.0 && min_length_ratio <= max_length_ratio &&
        std::isfinite(max_length_ratio))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "length ratios must satisfy 0 < min <= max: ", min_length_ratio, ", ", max_length_ratio));
  }
  if (max_repetitions < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("max_repetitions must be >= 1: ", max_repetitions));
  }
  if (!(motion_weight_floor_deg >= 0.0 && motion_weight_floor_deg <= 180.0)) {
    return absl::InvalidArgumentError("motion_weight_floor_deg must be in [0, 180]");
  }
  if (!(missing_cost_deg >= 0.0 && missing_cost_deg <= 180.0)) {
    return absl::InvalidArgumentError("missing_cost_deg must be in [0, 180]");
  }
  if (max_cells < 1) return absl::InvalidArgumentError("max_cells must be >= 1");
  return absl::OkStatus();
}

absl::StatusOr<std::vector<Repetition>> FindRepetitions(const std::vector<GradeFrame>& teacher,
                                                        const std::vector<GradeFrame>& learner,
                                                        const RepetitionOptions& options) {
  if (absl::Status valid = options.Validate(); !valid.ok()) return valid;
  if (teacher.empty()) return absl::InvalidArgumentError("the teacher has no frames");
  if (learner.empty()) return absl::InvalidArgumentError("the learner has no frames");
  const int64_t cells = static_cast<int64_t>(learner.size()) * static_cast<int64_t>(teacher.size());
  if (cells > options.max_cells) {
    return absl::InvalidArgumentError(absl::StrCat("repetition search over ", learner.size(), " x ",
                                                   teacher.size(), " frames exceeds max_cells ",
                                                   options.max_cells));
  }
  const std::vector<Directions> teacher_dirs = AllDirections(teacher);
  const std::vector<Directions> learner_dirs = AllDirections(learner);
  std::array<double, kNumBodyParts> weight = PartMotionDeg(teacher_dirs);
  for (double& w : weight) w += options.motion_weight_floor_deg;
  if (options.motion_weight_floor_deg == 0.0 &&
      std::all_of(weight.begin(), weight.end(), [](double w) { return w == 0.0; })) {
    weight.fill(1.0);  // A frozen teacher: every part counts alike.
  }

  Table t;
  t.num_learner = static_cast<int>(learner.size());
  t.num_teacher = static_cast<int>(teacher.size());
  const auto n = static_cast<size_t>(cells);
  std::vector<double> pair_cost(n);
  for (int i = 0; i < t.num_learner; ++i) {
    for (int j = 0; j < t.num_teacher; ++j) {
      pair_cost[t.At(i, j)] =
          WeightedDistanceDeg(learner_dirs[i], teacher_dirs[j], weight, options.missing_cost_deg);
    }
  }
  t.cost.resize(n);
  t.length.assign(n, 0);
  t.start.assign(n, 0);
  t.step.assign(n, kStart);

  // Durations compared in time, so that the two may differ in frame rate;
  // one frame period is added to each so that single frames compare too.
  auto period = [](const std::vector<GradeFrame>& f) {
    return f.size() > 1 ? (f.back().time_s - f.front().time_s) / static_cast<double>(f.size() - 1)
                        : 0.0;
  };
  const double learner_period = period(learner);
  const double teacher_duration = teacher.back().time_s - teacher.front().time_s + period(teacher);
  const double min_duration = options.min_length_ratio * teacher_duration;
  const double max_duration = options.max_length_ratio * teacher_duration;
  std::vector<bool> taken(t.num_learner, false);
  std::vector<Repetition> repetitions;
  while (static_cast<int>(repetitions.size()) < options.max_repetitions) {
    Fill(pair_cost, taken, t);
    // Among the stretches that qualify (duration, mean distance), the one of
    // least summed distance: a sum, unlike a mean, is not lowered by resting
    // in the teacher's last pose after the action, so each stretch ends
    // where the learner reaches that pose.
    int best_end = -1;
    double best = kInf;
    for (int i = 0; i < t.num_learner; ++i) {
      const size_t at = t.At(i, t.num_teacher - 1);
      if (t.cost[at] == kInf) continue;
      const double span = learner[i].time_s - learner[t.start[at]].time_s + learner_period;
      if (span < min_duration || span > max_duration) continue;
      if (t.cost[at] / t.length[at] > options.max_distance_deg) continue;
      if (t.cost[at] < best) best = t.cost[at], best_end = i;
    }
    if (best_end < 0) break;
    Repetition r;
    r.pairs = Backtrack(t, best_end);
    r.first_learner_frame = r.pairs.front().learner_frame;
    r.last_learner_frame = r.pairs.back().learner_frame;
    r.start_s = learner[r.first_learner_frame].time_s;
    r.end_s = learner[r.last_learner_frame].time_s;
    r.distance_deg = best / static_cast<double>(r.pairs.size());
    for (int i = r.first_learner_frame; i <= r.last_learner_frame; ++i) taken[i] = true;
    repetitions.push_back(std::move(r));
  }
  std::sort(repetitions.begin(), repetitions.end(), [](const Repetition& a, const Repetition& b) {
    return a.first_learner_frame < b.first_learner_frame;
  });
  return repetitions;
}

absl::Status HoldOptions::Validate() const {
  if (!(still_deg > 0.0 && still_deg <= 180.0)) {
    return absl::InvalidArgumentError(absl::StrCat("still_deg must be in (0, 180]: ", still_deg));
  }
  if (!(window_s > 0.0 && std::isfinite(window_s))) {
    return absl::InvalidArgumentError(absl::StrCat("window_s must be > 0: ", window_s));
  }
  if (!(min_hold_s > 0.0 && std::isfinite(min_hold_s))) {
    return absl::InvalidArgumentError(absl::StrCat("min_hold_s must be > 0: ", min_hold_s));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<Hold>> FindHolds(const std::vector<GradeFrame>& frames,
                                            const HoldOptions& options) {
  if (absl::Status valid = options.Validate(); !valid.ok()) return valid;
  const int n = static_cast<int>(frames.size());
  const std::vector<Directions> dirs = AllDirections(frames);
  // Still frames: a skeleton, and every seen part within still_deg of its
  // mean over the frames within window_s / 2 (two pointers over the times).
  std::vector<bool> still(n, false);
  const double half = 0.5 * options.window_s;
  int lo = 0, hi = 0;
  for (int k = 0; k < n; ++k) {
    while (lo < k && frames[lo].time_s < frames[k].time_s - half) ++lo;
    hi = std::max(hi, k);
    while (hi + 1 < n && frames[hi + 1].time_s <= frames[k].time_s + half) ++hi;
    bool all_posed = true;
    for (int m = lo; m <= hi && all_posed; ++m) all_posed = frames[m].pose.has_value();
    still[k] = all_posed && SpreadDeg(dirs, frames, lo, hi) <= options.still_deg;
  }
  std::vector<Hold> holds;
  for (int k = 0; k < n;) {
    if (!still[k]) {
      ++k;
      continue;
    }
    int end = k;
    while (end + 1 < n && still[end + 1]) ++end;
    Hold h{k, end, frames[k].time_s, frames[end].time_s - frames[k].time_s};
    // Standing before or after the action is not a hold.
    if (k > 0 && end < n - 1 && h.duration_s >= options.min_hold_s) holds.push_back(h);
    k = end + 1;
  }
  return holds;
}

std::vector<HoldMatch> MatchHolds(const std::vector<Hold>& teacher_holds,
                                  const std::vector<Hold>& learner_holds,
                                  const std::vector<FramePair>& pairs) {
  std::vector<HoldMatch> matches;
  for (const Hold& th : teacher_holds) {
    // The learner frames paired with the teacher's hold.
    int first = std::numeric_limits<int>::max(), last = -1;
    for (const FramePair& p : pairs) {
      if (p.teacher_frame < th.first_frame || p.teacher_frame > th.last_frame) continue;
      first = std::min(first, p.learner_frame);
      last = std::max(last, p.learner_frame);
    }
    if (last < 0) continue;
    HoldMatch m;
    m.teacher = th;
    int best_overlap = 0;
    for (const Hold& lh : learner_holds) {
      const int overlap = std::min(last, lh.last_frame) - std::max(first, lh.first_frame) + 1;
      if (overlap > best_overlap) best_overlap = overlap, m.learner = lh;
    }
    m.difference_s = (m.learner ? m.learner->duration_s : 0.0) - th.duration_s;
    matches.push_back(m);
  }
  return matches;
}

absl::StatusOr<TakeGrade> GradeTake(const std::vector<GradeFrame>& teacher,
                                    const std::vector<GradeFrame>& learner,
                                    const TakeGradeOptions& options) {
  RETURN_IF_ERROR(options.grade.Validate());
  RETURN_IF_ERROR(options.holds.Validate());
  TakeGrade take;
  // Paired one to one, the take is the teacher's action once: no search.
  if (options.grade.use_dtw) {
    ASSIGN_OR_RETURN(take.repetitions, FindRepetitions(teacher, learner, options.repetitions));
  }
  ASSIGN_OR_RETURN(take.teacher_holds, FindHolds(teacher, options.holds));
  ASSIGN_OR_RETURN(const std::vector<Hold> learner_holds, FindHolds(learner, options.holds));
  std::vector<FramePair> all_pairs;
  for (const Repetition& r : take.repetitions) {
    ASSIGN_OR_RETURN(Grade grade, GradePairs(teacher, learner, r.pairs, options.grade));
    take.repetition_grades.push_back(std::move(grade));
    take.repetition_holds.push_back(MatchHolds(take.teacher_holds, learner_holds, r.pairs));
    all_pairs.insert(all_pairs.end(), r.pairs.begin(), r.pairs.end());
  }
  if (take.repetitions.empty()) {
    take.whole_take = true;
    ASSIGN_OR_RETURN(take.overall, GradeSequences(teacher, learner, options.grade));
  } else {
    ASSIGN_OR_RETURN(take.overall, GradePairs(teacher, learner, all_pairs, options.grade));
    take.overall.used_dtw = true;
  }
  return take;
}

namespace {
nlohmann::json HoldJson(const Hold& h) {
  return {{"first_frame", h.first_frame},
          {"last_frame", h.last_frame},
          {"start_s", h.start_s},
          {"duration_s", h.duration_s}};
}
nlohmann::json OrNull(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}
}  // namespace

std::string RepetitionsJson(const TakeGrade& take) {
  nlohmann::json reps = nlohmann::json::array();
  for (size_t i = 0; i < take.repetitions.size(); ++i) {
    const Repetition& r = take.repetitions[i];
    const Grade& g = take.repetition_grades[i];
    nlohmann::json holds = nlohmann::json::array();
    for (const HoldMatch& m : take.repetition_holds[i]) {
      holds.push_back({{"teacher", HoldJson(m.teacher)},
                       {"learner", m.learner ? HoldJson(*m.learner) : nlohmann::json(nullptr)},
                       {"difference_s", m.difference_s},
                       {"text", HoldWords(m)}});
    }
    nlohmann::json corrections = nlohmann::json::array();
    for (const Correction& c : g.corrections) corrections.push_back(c.text);
    reps.push_back({{"index", i + 1},
                    {"first_learner_frame", r.first_learner_frame},
                    {"last_learner_frame", r.last_learner_frame},
                    {"start_s", r.start_s},
                    {"end_s", r.end_s},
                    {"distance_deg", r.distance_deg},
                    {"mean_error_deg", OrNull(g.mean_error_deg)},
                    {"action_error_deg", OrNull(g.action_error_deg)},
                    {"coverage", g.coverage},
                    {"corrections", corrections},
                    {"holds", holds}});
  }
  nlohmann::json teacher_holds = nlohmann::json::array();
  for (const Hold& h : take.teacher_holds) teacher_holds.push_back(HoldJson(h));
  const nlohmann::json j = {{"count", take.repetitions.size()},
                            {"whole_take", take.whole_take},
                            {"repetitions", reps},
                            {"teacher_holds", teacher_holds}};
  return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string HoldWords(const HoldMatch& hold) {
  const std::string head = absl::StrFormat("the teacher's hold at %.1f s (%.1f s)",
                                           hold.teacher.start_s, hold.teacher.duration_s);
  if (!hold.learner) return head + ": not held";
  const double d = hold.difference_s;
  // Under 0.15 s either way (about four frames at 30 fps) reads as as long.
  if (std::abs(d) < 0.15) {
    return absl::StrFormat("%s: held %.1f s, as long", head, hold.learner->duration_s);
  }
  return absl::StrFormat("%s: held %.1f s, %.1f s %s", head, hold.learner->duration_s, std::abs(d),
                         d > 0 ? "longer" : "shorter");
}

}  // namespace reenact::mirror
