#include "clients/mirror/time_alignment.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "absl/strings/str_cat.h"
#include "clients/mirror/pose_comparison.h"

namespace reenact::mirror {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Steps back from a cell of the DTW table.
enum Step : uint8_t { kNone = 0, kDiagonal, kFromPreviousLearner, kFromPreviousTeacher };

// Accumulated cost and the step that reached each cell, learner-major.
struct DtwTable {
  int num_learner = 0;
  int num_teacher = 0;
  std::vector<double> cost;
  std::vector<Step> step;
  size_t At(int i, int j) const { return static_cast<size_t>(i) * num_teacher + j; }
};

bool InBand(int i, int j, const DtwTable& table, int band_frames) {
  if (band_frames <= 0 || table.num_teacher < 2) return true;
  const double diagonal_i =
      static_cast<double>(j) * (table.num_learner - 1) / (table.num_teacher - 1);
  return std::abs(i - diagonal_i) <= band_frames;
}

double PairDistanceDeg(const PerPart<Eigen::Vector3d>& learner,
                       const PerPart<Eigen::Vector3d>& teacher, double missing_cost_deg) {
  const PoseComparison comparison = CompareDirections(learner, teacher);
  return comparison.mean_error_deg.value_or(missing_cost_deg);
}

// The cheapest predecessor of (i, j) and its accumulated cost.
std::pair<double, Step> BestPredecessor(const DtwTable& table, int i, int j) {
  std::pair<double, Step> best{kInf, kNone};
  if (i > 0 && j > 0) best = {table.cost[table.At(i - 1, j - 1)], kDiagonal};
  if (i > 0 && table.cost[table.At(i - 1, j)] < best.first) {
    best = {table.cost[table.At(i - 1, j)], kFromPreviousLearner};
  }
  if (j > 0 && table.cost[table.At(i, j - 1)] < best.first) {
    best = {table.cost[table.At(i, j - 1)], kFromPreviousTeacher};
  }
  return best;
}

void FillTable(const std::vector<PerPart<Eigen::Vector3d>>& learner,
               const std::vector<PerPart<Eigen::Vector3d>>& teacher, const DtwOptions& options,
               DtwTable& table) {
  for (int i = 0; i < table.num_learner; ++i) {
    for (int j = 0; j < table.num_teacher; ++j) {
      if (!InBand(i, j, table, options.band_frames)) continue;
      const double d = PairDistanceDeg(learner[i], teacher[j], options.missing_cost_deg);
      if (i == 0 && j == 0) {
        table.cost[0] = d;
        continue;
      }
      const auto [previous, step] = BestPredecessor(table, i, j);
      if (previous == kInf) continue;
      table.cost[table.At(i, j)] = previous + d;
      table.step[table.At(i, j)] = step;
    }
  }
}

std::vector<FramePair> Backtrack(const DtwTable& table) {
  std::vector<FramePair> pairs;
  int i = table.num_learner - 1;
  int j = table.num_teacher - 1;
  while (true) {
    pairs.push_back({i, j});
    const Step step = table.step[table.At(i, j)];
    if (step == kNone) break;
    if (step != kFromPreviousTeacher) --i;
    if (step != kFromPreviousLearner) --j;
  }
  std::reverse(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace

absl::Status DtwOptions::Validate() const {
  if (band_frames < 0) {
    return absl::InvalidArgumentError(absl::StrCat("DTW band_frames must be >= 0: ", band_frames));
  }
  if (!(missing_cost_deg >= 0.0 && missing_cost_deg <= 180.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("DTW missing_cost_deg must be in [0, 180]: ", missing_cost_deg));
  }
  if (max_cells < 1) {
    return absl::InvalidArgumentError(absl::StrCat("DTW max_cells must be >= 1: ", max_cells));
  }
  return absl::OkStatus();
}

Alignment AlignOneToOne(int num_learner_frames, int num_teacher_frames) {
  Alignment alignment;
  const int n = std::max(0, std::min(num_learner_frames, num_teacher_frames));
  alignment.pairs.reserve(n);
  for (int i = 0; i < n; ++i) alignment.pairs.push_back({i, i});
  return alignment;
}

absl::StatusOr<Alignment> AlignDirectionsByDtw(const std::vector<PerPart<Eigen::Vector3d>>& learner,
                                               const std::vector<PerPart<Eigen::Vector3d>>& teacher,
                                               const DtwOptions& options) {
  if (absl::Status valid = options.Validate(); !valid.ok()) return valid;
  if (learner.empty() || teacher.empty()) {
    return absl::InvalidArgumentError("DTW needs at least one learner and one teacher frame");
  }
  const int64_t cells = static_cast<int64_t>(learner.size()) * static_cast<int64_t>(teacher.size());
  if (cells > options.max_cells) {
    return absl::InvalidArgumentError(absl::StrCat("DTW table of ", learner.size(), " x ",
                                                   teacher.size(), " frames exceeds max_cells ",
                                                   options.max_cells));
  }
  DtwTable table{static_cast<int>(learner.size()), static_cast<int>(teacher.size()),
                 std::vector<double>(cells, kInf), std::vector<Step>(cells, kNone)};
  FillTable(learner, teacher, options, table);
  const double total = table.cost.back();
  if (total == kInf) {
    return absl::InvalidArgumentError(
        absl::StrCat("DTW band of ", options.band_frames, " frames is too narrow to align ",
                     learner.size(), " with ", teacher.size(), " frames"));
  }
  Alignment alignment;
  alignment.pairs = Backtrack(table);
  alignment.mean_distance_deg = total / static_cast<double>(alignment.pairs.size());
  return alignment;
}

absl::StatusOr<Alignment> AlignByDtw(const std::vector<body::SkeletonPose>& learner,
                                     const std::vector<body::SkeletonPose>& teacher,
                                     const DtwOptions& options) {
  std::vector<PerPart<Eigen::Vector3d>> learner_directions;
  std::vector<PerPart<Eigen::Vector3d>> teacher_directions;
  learner_directions.reserve(learner.size());
  teacher_directions.reserve(teacher.size());
  for (const body::SkeletonPose& pose : learner) {
    learner_directions.push_back(PartDirectionsInSpine(pose));
  }
  for (const body::SkeletonPose& pose : teacher) {
    teacher_directions.push_back(PartDirectionsInSpine(pose));
  }
  return AlignDirectionsByDtw(learner_directions, teacher_directions, options);
}

}  // namespace reenact::mirror
