#include "clients/mirror/repetitions.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/mirror/testing/mocap_learners.h"
#include "common/testing/test_data.h"

namespace reenact::mirror {
namespace {

using testing::LoadCmuTeacher;
using testing::TurnRightForearm;

constexpr double kFps = 30.0;

// A phrase of a move: the right forearm turned from 0 to `peak_deg` over
// `ramp_s`, held for `hold_s`, and back over `ramp_s` (smooth ramps).
struct Phrase {
  double peak_deg = 90.0;
  double ramp_s = 0.7;
  double hold_s = 1.0;
  double Duration() const { return 2.0 * ramp_s + hold_s; }
  double AngleAt(double t) const {
    auto smooth = [](double x) { return 0.5 - 0.5 * std::cos(x * M_PI); };
    if (t < ramp_s) return peak_deg * smooth(t / ramp_s);
    if (t < ramp_s + hold_s) return peak_deg;
    return peak_deg * smooth(1.0 - (t - ramp_s - hold_s) / ramp_s);
  }
};

// Builds a sequence of rests (peak 0) and phrases from `rest`, with 4 mm of
// noise on every joint.
class Builder {
 public:
  explicit Builder(const body::SkeletonPose& rest, unsigned seed = 7) : rest_(rest), rng_(seed) {}
  Builder& Rest(double seconds) { return Add({0.0, 0.0, seconds}); }
  Builder& Add(const Phrase& phrase) {
    const int n = static_cast<int>(std::lround(phrase.Duration() * kFps));
    for (int k = 0; k < n; ++k) {
      GradeFrame f;
      f.time_s = static_cast<double>(frames_.size()) / kFps;
      f.pose = TurnRightForearm(rest_, phrase.AngleAt(k / kFps));
      std::normal_distribution<double> noise(0.0, 0.004);
      for (auto& p : f.pose->position_m)
        p += Eigen::Vector3d(noise(rng_), noise(rng_), noise(rng_));
      MarkValidJointsSeen(f);
      frames_.push_back(std::move(f));
    }
    return *this;
  }
  double Now() const { return static_cast<double>(frames_.size()) / kFps; }
  std::vector<GradeFrame> Take() { return std::move(frames_); }

 private:
  body::SkeletonPose rest_;
  std::mt19937 rng_;
  std::vector<GradeFrame> frames_;
};

class RepetitionsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
    const std::vector<body::SkeletonPose> poses = LoadCmuTeacher(4, 1);
    ASSERT_EQ(poses.size(), 1u);
    rest_ = poses[0];
  }
  body::SkeletonPose rest_;
};

TEST_F(RepetitionsTest, CountsEachRepetitionAtItsOwnSpeedAndTimesItsHold) {
  // The teacher: rest, raise the forearm, hold it 1.0 s, lower, rest.
  Builder teacher_builder(rest_, 1);
  teacher_builder.Rest(0.3).Add({90.0, 0.7, 1.0}).Rest(0.3);
  const std::vector<GradeFrame> teacher = teacher_builder.Take();

  // The learner: rest, the move slower and held longer, another move (the
  // forearm the other way), the move faster and held shorter, rest.
  Builder learner_builder(rest_, 2);
  learner_builder.Rest(1.0);
  const double rep1_start = learner_builder.Now();
  learner_builder.Add({90.0, 0.9, 1.5});
  const double rep1_end = learner_builder.Now();
  learner_builder.Rest(0.5).Add({-100.0, 0.5, 0.4}).Rest(0.5);
  const double rep2_start = learner_builder.Now();
  learner_builder.Add({85.0, 0.5, 0.8});
  const double rep2_end = learner_builder.Now();
  learner_builder.Rest(1.0);
  const std::vector<GradeFrame> learner = learner_builder.Take();

  const absl::StatusOr<std::vector<Repetition>> reps = FindRepetitions(teacher, learner);
  ASSERT_TRUE(reps.ok()) << reps.status();
  ASSERT_EQ(reps->size(), 2u);
  const double starts[2] = {rep1_start, rep2_start};
  const double ends[2] = {rep1_end, rep2_end};
  for (int r = 0; r < 2; ++r) {
    const Repetition& rep = (*reps)[r];
    SCOPED_TRACE(r);
    // The repetition's stretch, to within 0.4 s: resting at the teacher's
    // start or end pose may be paired either way.
    EXPECT_NEAR(rep.start_s, starts[r], 0.4);
    EXPECT_NEAR(rep.end_s, ends[r], 0.4);
    EXPECT_LT(rep.distance_deg, 5.0);
    EXPECT_EQ(rep.pairs.front().teacher_frame, 0);
    EXPECT_EQ(rep.pairs.back().teacher_frame, static_cast<int>(teacher.size()) - 1);
  }

  // The holds: the teacher's 1.0 s, the learner's 1.5 s and 0.8 s (a hold
  // lasts from its first still frame to its last: the hold plus the slow
  // ends of the ramps, less one frame).
  const absl::StatusOr<std::vector<Hold>> teacher_holds = FindHolds(teacher);
  const absl::StatusOr<std::vector<Hold>> learner_holds = FindHolds(learner);
  ASSERT_TRUE(teacher_holds.ok() && learner_holds.ok());
  ASSERT_EQ(teacher_holds->size(), 1u);
  EXPECT_NEAR((*teacher_holds)[0].duration_s, 1.0, 0.3);
  EXPECT_NEAR((*teacher_holds)[0].start_s, 0.3 + 0.7, 0.3);
  const double learner_hold[2] = {1.5, 0.8};
  for (int r = 0; r < 2; ++r) {
    SCOPED_TRACE(r);
    const std::vector<HoldMatch> matches =
        MatchHolds(*teacher_holds, *learner_holds, (*reps)[r].pairs);
    ASSERT_EQ(matches.size(), 1u);
    ASSERT_TRUE(matches[0].learner.has_value());
    // Both measured the same way, so their difference is nearly the true
    // one; the slow ends of the ramps, which count as held, differ with the
    // ramps' speeds (0.7 s for the teacher, 0.9 and 0.5 s here).
    EXPECT_NEAR(matches[0].difference_s, learner_hold[r] - 1.0, 0.25);
    EXPECT_NEAR(matches[0].learner->duration_s - matches[0].teacher.duration_s,
                matches[0].difference_s, 1e-9);
  }

  // The whole take: graded over the two repetitions only (the other move is
  // left out), each repetition with its grade and its hold in words.
  const absl::StatusOr<TakeGrade> take = GradeTake(teacher, learner);
  ASSERT_TRUE(take.ok()) << take.status();
  EXPECT_FALSE(take->whole_take);
  ASSERT_EQ(take->repetition_grades.size(), 2u);
  ASSERT_TRUE(take->overall.mean_error_deg.has_value());
  EXPECT_LT(*take->overall.mean_error_deg, 5.0);
  for (const Grade& g : take->repetition_grades) {
    ASSERT_TRUE(g.mean_error_deg.has_value());
    EXPECT_LT(*g.mean_error_deg, 5.0);
    EXPECT_GT(g.coverage, 0.99);
  }
  const std::string first = HoldWords(take->repetition_holds[0][0]);
  const std::string second = HoldWords(take->repetition_holds[1][0]);
  EXPECT_NE(first.find("longer"), std::string::npos) << first;
  EXPECT_NE(second.find("shorter"), std::string::npos) << second;
  const nlohmann::json j = nlohmann::json::parse(RepetitionsJson(*take));
  EXPECT_EQ(j["count"], 2);
  EXPECT_EQ(j["repetitions"][1]["holds"][0]["text"], second);
  EXPECT_EQ(j["teacher_holds"].size(), 1u);

  // A take of the other move alone: no repetition, graded as a whole.
  Builder other(rest_, 9);
  other.Rest(0.5).Add({-100.0, 0.7, 1.0}).Rest(0.5);
  const absl::StatusOr<TakeGrade> none = GradeTake(teacher, other.Take());
  ASSERT_TRUE(none.ok()) << none.status();
  EXPECT_TRUE(none->whole_take);
  EXPECT_TRUE(none->repetitions.empty());
  ASSERT_TRUE(none->overall.action_error_deg.has_value());
  EXPECT_GT(*none->overall.action_error_deg, 30.0);
}

TEST_F(RepetitionsTest, AnotherMoveIsNoRepetitionAndAMoveWithoutAHoldHoldsNothing) {
  Builder teacher_builder(rest_, 1);
  teacher_builder.Rest(0.3).Add({90.0, 0.7, 1.0}).Rest(0.3);
  const std::vector<GradeFrame> teacher = teacher_builder.Take();
  Builder other(rest_, 3);
  other.Rest(0.5).Add({-100.0, 0.7, 1.0}).Rest(0.5).Add({-40.0, 0.4, 0.0}).Rest(0.5);
  const std::vector<GradeFrame> learner = other.Take();
  const absl::StatusOr<std::vector<Repetition>> reps = FindRepetitions(teacher, learner);
  ASSERT_TRUE(reps.ok()) << reps.status();
  EXPECT_TRUE(reps->empty());

  // Rest only: no hold (standing before and after the action is none).
  Builder rest(rest_, 4);
  rest.Rest(3.0);
  const absl::StatusOr<std::vector<Hold>> holds = FindHolds(rest.Take());
  ASSERT_TRUE(holds.ok());
  EXPECT_TRUE(holds->empty());
  // A move with no hold: none either.
  Builder swing(rest_, 5);
  swing.Rest(0.5).Add({90.0, 0.7, 0.0}).Rest(0.5);
  const absl::StatusOr<std::vector<Hold>> swing_holds = FindHolds(swing.Take());
  ASSERT_TRUE(swing_holds.ok());
  EXPECT_TRUE(swing_holds->empty());
}

TEST_F(RepetitionsTest, FramesWithoutASkeletonAndBadOptions) {
  Builder teacher_builder(rest_, 1);
  teacher_builder.Rest(0.3).Add({90.0, 0.7, 1.0}).Rest(0.3);
  const std::vector<GradeFrame> teacher = teacher_builder.Take();
  Builder learner_builder(rest_, 2);
  learner_builder.Rest(0.5).Add({90.0, 0.7, 1.0}).Rest(0.5);
  std::vector<GradeFrame> learner = learner_builder.Take();
  // The learner leaves the view during the hold: the hold is broken and the
  // repetition still found (the frames cost missing_cost_deg).
  const int middle = static_cast<int>(learner.size()) / 2;
  for (int k = middle - 2; k <= middle + 2; ++k) learner[k].pose.reset();
  const absl::StatusOr<std::vector<Repetition>> reps = FindRepetitions(teacher, learner);
  ASSERT_TRUE(reps.ok()) << reps.status();
  EXPECT_EQ(reps->size(), 1u);
  const absl::StatusOr<std::vector<Hold>> holds = FindHolds(learner);
  ASSERT_TRUE(holds.ok());
  for (const Hold& h : *holds) {
    EXPECT_TRUE(h.last_frame < middle - 2 || h.first_frame > middle + 2);
  }

  EXPECT_FALSE(FindRepetitions({}, learner).ok());
  EXPECT_FALSE(FindRepetitions(teacher, {}).ok());
  RepetitionOptions bad;
  bad.max_distance_deg = 0.0;
  EXPECT_FALSE(FindRepetitions(teacher, learner, bad).ok());
  bad = {};
  bad.min_length_ratio = 3.0;  // Above max_length_ratio.
  EXPECT_FALSE(FindRepetitions(teacher, learner, bad).ok());
  bad = {};
  bad.max_cells = 10;
  const absl::StatusOr<std::vector<Repetition>> too_big = FindRepetitions(teacher, learner, bad);
  ASSERT_FALSE(too_big.ok());
  EXPECT_NE(too_big.status().message().find("max_cells"), std::string::npos);
  HoldOptions bad_hold;
  bad_hold.window_s = std::nan("");
  EXPECT_FALSE(FindHolds(learner, bad_hold).ok());
  bad_hold = {};
  bad_hold.still_deg = -1.0;
  EXPECT_FALSE(FindHolds(learner, bad_hold).ok());
}

}  // namespace
}  // namespace reenact::mirror
