// `reenact grade`: the magic mirror's comparison (clients/mirror/grading.h)
// with no window or video, so that a coach can grade a class's recordings in
// a batch:
//   reenact grade --teacher REENACTMENT|TAKE --learner TAKE [--json]
// and the same comparison checked on real people, over every pair of
// recordings of a folder laid out like ../shared/data/rgbd-seq:
//   reenact grade --real DIR [--tracked] [--json]
#include <fnmatch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "clients/cli/commands.h"
#include "clients/cli/real_sequences.h"
#include "clients/mirror/facing.h"
#include "clients/mirror/grading.h"
#include "clients/mirror/learner_source.h"
#include "clients/mirror/repetitions.h"
#include "clients/mirror/teacher_view.h"
#include "clients/sdk/reenactment_source.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/rpc/channel.h"
#include "common/tracking/body_tracker.h"

namespace reenact::cli {
namespace {

namespace fs = std::filesystem;
using mirror::GradeFrame;

// ---------------------------------------------------------------------------
// Teacher and learner from files.

// The frames of a take's learner sensor (tracked from depth when the take
// has no skeletons), timed from the first frame.
absl::StatusOr<std::vector<GradeFrame>> TakeFrames(const std::string& path,
                                                   const std::string& sensor, bool all_seen) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return absl::NotFoundError(absl::StrCat("no take ", path));
  ASSIGN_OR_RETURN(std::unique_ptr<mirror::LearnerSource> source,
                   mirror::OpenTakeLearner(path, sensor));
  std::vector<GradeFrame> frames;
  std::optional<int64_t> first_ns;
  while (true) {
    ASSIGN_OR_RETURN(std::optional<mirror::LearnerFrame> frame, source->Next());
    if (!frame) break;
    if (!first_ns) first_ns = frame->stamp_ns;
    GradeFrame f;
    f.time_s = static_cast<double>(frame->stamp_ns - *first_ns) * 1e-9;
    f.pose = frame->skeleton_in_color;
    f.seen = frame->joint_seen;
    if (all_seen) mirror::MarkValidJointsSeen(f);
    frames.push_back(std::move(f));
  }
  if (frames.empty()) {
    return absl::FailedPreconditionError(absl::StrCat(source->Describe(), " has no frame"));
  }
  return frames;
}

bool IsTakePath(const std::string& path) { return absl::EndsWithIgnoreCase(path, ".mcap"); }

// The learner's facing relative to their sensor: the median over the frames
// with a readable facing (0 when none has one).
double LearnerFacingDeg(const std::vector<GradeFrame>& learner) {
  std::vector<double> yaws;
  for (const GradeFrame& f : learner) {
    if (!f.pose) continue;
    if (const std::optional<double> yaw = mirror::FacingYawInSensorDeg(*f.pose)) {
      yaws.push_back(*yaw);
    }
  }
  if (yaws.empty()) return 0.0;
  std::nth_element(yaws.begin(), yaws.begin() + yaws.size() / 2, yaws.end());
  return yaws[yaws.size() / 2];
}

// The learner as the teacher's joints are matched to it: its facing (the
// side from which the tracker sees the teacher with --teacher-joints
// tracked).
struct LearnerView {
  double facing_deg = 0.0;
};

absl::StatusOr<std::vector<GradeFrame>> TeacherFrames(const Flags& flags,
                                                      const LearnerView& learner,
                                                      std::string* described) {
  const std::string teacher = flags.GetOr("teacher", "");
  if (!flags.Has("server") && IsTakePath(teacher)) {
    *described = "take " + teacher;
    return TakeFrames(teacher, flags.GetOr("teacher-sensor", ""), /*all_seen=*/true);
  }
  std::unique_ptr<client::ReenactmentSource> source;
  std::string id;
  if (flags.Has("server")) {
    ASSIGN_OR_RETURN(
        const rpc::ClientSecurity security,
        rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""), flags.GetOr("token-file", "")));
    ASSIGN_OR_RETURN(source,
                     client::OpenReenactmentSource(
                         absl::StrCat("grpc:", *flags.Get("server")),
                         flags.GetOr("cache", client::DefaultReenactmentCacheDir()), security));
    id = teacher;
  } else {
    ASSIGN_OR_RETURN(source, client::OpenReenactmentSource(teacher));
    id = flags.GetOr("teacher-id", "");
  }
  ASSIGN_OR_RETURN(const Reenactment data,
                   client::LoadReenactmentOrOnly(*source, id, "--teacher-id ID", &id));
  if (!(data.info.fps > 0.0) || !std::isfinite(data.info.fps)) {
    return absl::FailedPreconditionError(
        absl::StrCat("reenactment ", id, " has no frame rate (ReenactmentInfo.fps)"));
  }
  ASSIGN_OR_RETURN(const mirror::TeacherJoints joints,
                   mirror::ParseTeacherJoints(flags.GetOr("teacher-joints", "stored")));
  mirror::TeacherTrackingOptions tracking;
  tracking.view_yaw_deg = learner.facing_deg;
  tracking.tracker.refine = joints == mirror::TeacherJoints::kTrackedRefined;
  ASSIGN_OR_RETURN(const std::vector<body::SkeletonPose> poses,
                   joints != mirror::TeacherJoints::kStored
                       ? mirror::TeacherSkeletonsAsTracked(data, tracking)
                       : mirror::TeacherSkeletons(data));
  std::vector<GradeFrame> frames;
  frames.reserve(poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    GradeFrame f;
    f.time_s = static_cast<double>(i) / data.info.fps;
    f.pose = poses[i];
    mirror::MarkValidJointsSeen(f);
    frames.push_back(std::move(f));
  }
  *described = absl::StrCat("reenactment ", id, " (", source->Describe(), ")",
                            joints != mirror::TeacherJoints::kStored
                                ? absl::StrFormat(", its joints as the tracker finds them seen "
                                                  "at the learner's facing, %+.0f deg",
                                                  learner.facing_deg)
                                : "");
  return frames;
}

// The grade as JSON: GradeJson's with the repetitions and holds added.
nlohmann::json TakeGradeJson(const mirror::TakeGrade& take, bool with_pairs) {
  nlohmann::json j = nlohmann::json::parse(mirror::GradeJson(take.overall, with_pairs));
  j["repetitions"] = nlohmann::json::parse(mirror::RepetitionsJson(take));
  return j;
}

absl::Status WriteReport(const std::string& dir, const mirror::TakeGrade& take,
                         const std::vector<GradeFrame>& teacher,
                         const std::vector<GradeFrame>& learner) {
  const mirror::Grade& grade = take.overall;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat("cannot make ", dir, ": ", ec.message()));
  RETURN_IF_ERROR(
      WriteFileAtomically((fs::path(dir) / "grade.json").string(),
                          TakeGradeJson(take, /*with_pairs=*/true)
                                  .dump(2, ' ', false, nlohmann::json::error_handler_t::replace) +
                              "\n"));
  ASSIGN_OR_RETURN(const std::string heat, mirror::GradeHeatMapPng(grade));
  RETURN_IF_ERROR(WriteFileAtomically((fs::path(dir) / "heatmap.png").string(), heat));
  ASSIGN_OR_RETURN(const std::string worst, mirror::WorstMomentsPng(grade, teacher, learner));
  return WriteFileAtomically((fs::path(dir) / "worst-moments.png").string(), worst);
}

void PrintGrade(const mirror::Grade& grade, const mirror::GradeOptions& options,
                std::ostream& out) {
  if (grade.mean_error_deg) {
    out << absl::StrFormat(
        "mean error %.1f degrees over the graded parts (%.0f%% of the body over time was seen "
        "and graded); %.1f degrees weighted by how much the teacher moves each part\n",
        *grade.mean_error_deg, 100.0 * grade.coverage,
        grade.action_error_deg.value_or(*grade.mean_error_deg));
  } else {
    out << "nothing could be graded: no part was seen in enough frames\n";
  }
  for (int p = 0; p < mirror::kNumBodyParts; ++p) {
    const mirror::PartGrade& part = grade.parts[p];
    const std::string name = mirror::PartWords(mirror::BodyPartAt(p));
    if (part.graded) {
      out << absl::StrFormat("  %-16s %5.1f deg  (seen %3.0f%%, teacher moves it %.0f deg)\n", name,
                             *part.mean_error_deg, 100.0 * part.coverage, part.teacher_motion_deg);
    } else {
      out << absl::StrFormat("  %-16s not graded: %s\n", name, part.not_graded_reason);
    }
  }
  if (grade.corrections.empty()) {
    out << "no correction: every graded part stayed within " << options.min_correction_deg
        << " degrees\n";
  }
  for (const mirror::Correction& c : grade.corrections) out << "correction: " << c.text << "\n";
}

void PrintRepetitions(const mirror::TakeGrade& take, const mirror::RepetitionOptions& options,
                      std::ostream& out) {
  if (take.repetitions.empty()) {
    out << absl::StrFormat(
        "repetitions: none found (no stretch of the take came within %.0f degrees of the "
        "teacher's action); the whole take is graded against it\n",
        options.max_distance_deg);
    return;
  }
  out << "repetitions: " << take.repetitions.size() << " of the teacher's action";
  if (!take.teacher_holds.empty()) {
    out << ", which holds a pose " << take.teacher_holds.size()
        << (take.teacher_holds.size() == 1 ? " time" : " times");
  }
  out << "\n";
  for (size_t i = 0; i < take.repetitions.size(); ++i) {
    const mirror::Repetition& r = take.repetitions[i];
    const mirror::Grade& g = take.repetition_grades[i];
    out << absl::StrFormat("  %2d  %6.1f .. %6.1f s  ", i + 1, r.start_s, r.end_s);
    if (g.mean_error_deg) {
      out << absl::StrFormat("mean error %.1f deg (%.1f weighted) over %.0f%% seen\n",
                             *g.mean_error_deg, g.action_error_deg.value_or(*g.mean_error_deg),
                             100.0 * g.coverage);
    } else {
      out << "nothing seen to grade\n";
    }
    for (const mirror::HoldMatch& h : take.repetition_holds[i]) {
      out << "      " << mirror::HoldWords(h) << "\n";
    }
    // With one repetition its corrections are the overall ones, below.
    if (take.repetitions.size() < 2) continue;
    for (const mirror::Correction& c : g.corrections) out << "      correction: " << c.text << "\n";
  }
  out << "over all repetitions:\n";
}

// ---------------------------------------------------------------------------
// Real people: every pair of recordings of a folder like rgbd-seq.

struct RealSequence {
  RefSequence ref;
  std::vector<GradeFrame> sdk;      // The stored SDK skeletons (no states: all seen).
  std::vector<GradeFrame> tracked;  // Ours, with TRACKED as seen.
};

// How often a same-action pair grades lower than a different-action pair for
// the same learner (ties count half).
struct Ranking {
  double wins = 0.0;
  int64_t comparisons = 0;
  int pairs = 0, failed = 0;
  double same_sum = 0.0, different_sum = 0.0;
  int same_n = 0, different_n = 0;
  double Share() const { return comparisons ? 100.0 * wins / comparisons : 0.0; }
};

// Per-part errors of the same pairs from two skeleton sources.
struct Agreement {
  std::vector<double> sdk, tracked;
  double coverage_sum = 0.0;
  int pairs = 0;
  double Correlation() const {
    const size_t n = sdk.size();
    if (n < 2) return 0.0;
    double mx = 0, my = 0;
    for (size_t i = 0; i < n; ++i) mx += sdk[i], my += tracked[i];
    mx /= n, my /= n;
    double sxy = 0, sxx = 0, syy = 0;
    for (size_t i = 0; i < n; ++i) {
      sxy += (sdk[i] - mx) * (tracked[i] - my);
      sxx += (sdk[i] - mx) * (sdk[i] - mx);
      syy += (tracked[i] - my) * (tracked[i] - my);
    }
    return sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : 0.0;
  }
  double MeanAbsDifference() const {
    double sum = 0;
    for (size_t i = 0; i < sdk.size(); ++i) sum += std::abs(sdk[i] - tracked[i]);
    return sdk.empty() ? 0.0 : sum / sdk.size();
  }
};

struct PairGrades {
  const RealSequence* teacher;
  const RealSequence* learner;
  std::optional<mirror::Grade> sdk, tracked;
  // Repetitions of the teacher's action found in the learner's recording
  // (each recording holds one), or -1 when the search failed.
  int sdk_repetitions = -1, tracked_repetitions = -1;
};

// How well repetitions are counted: a recording of the same action should
// hold exactly one, one of a different action none.
struct Counting {
  int same = 0, same_once = 0, different = 0, different_none = 0;
  void Add(const PairGrades& p, bool tracked) {
    const int n = tracked ? p.tracked_repetitions : p.sdk_repetitions;
    if (n < 0) return;
    if (p.teacher->ref.action_id == p.learner->ref.action_id) {
      ++same, same_once += n == 1;
    } else {
      ++different, different_none += n == 0;
    }
  }
  double SameOnce() const { return same ? 100.0 * same_once / same : 0.0; }
  double DifferentNone() const { return different ? 100.0 * different_none / different : 0.0; }
  nlohmann::json Json() const {
    return {{"same_action_pairs", same},
            {"same_action_counted_once_percent", SameOnce()},
            {"different_action_pairs", different},
            {"different_action_counted_none_percent", DifferentNone()}};
  }
  std::string Words() const {
    return absl::StrFormat(
        "repetitions counted: once in %.1f %% of same-action recordings, none in %.1f %% of "
        "different-action ones",
        SameOnce(), DifferentNone());
  }
};

// `plain`: by the plain mean over the graded parts instead of the
// action-weighted error.
void Rank(const std::vector<PairGrades>& pairs, bool tracked, Ranking* r, bool plain = false) {
  // learner -> (same-action means, different-action means)
  std::map<const RealSequence*, std::pair<std::vector<double>, std::vector<double>>> by_learner;
  for (const PairGrades& p : pairs) {
    const std::optional<mirror::Grade>& g = tracked ? p.tracked : p.sdk;
    ++r->pairs;
    const std::optional<double> score = !g      ? std::nullopt
                                        : plain ? g->mean_error_deg
                                                : g->action_error_deg;
    if (!score) {
      ++r->failed;
      continue;
    }
    const bool same = p.teacher->ref.action_id == p.learner->ref.action_id;
    auto& lists = by_learner[p.learner];
    (same ? lists.first : lists.second).push_back(*score);
    (same ? r->same_sum : r->different_sum) += *score;
    ++(same ? r->same_n : r->different_n);
  }
  for (const auto& [learner, lists] : by_learner) {
    for (const double s : lists.first) {
      for (const double d : lists.second) {
        r->wins += s < d ? 1.0 : s == d ? 0.5 : 0.0;
        ++r->comparisons;
      }
    }
  }
}

void Agree(const std::vector<PairGrades>& pairs, Agreement* a) {
  for (const PairGrades& p : pairs) {
    if (!p.sdk || !p.tracked) continue;
    ++a->pairs;
    a->coverage_sum += p.tracked->coverage;
    for (int part = 0; part < mirror::kNumBodyParts; ++part) {
      const mirror::PartGrade& s = p.sdk->parts[part];
      const mirror::PartGrade& t = p.tracked->parts[part];
      if (!s.graded || !t.graded) continue;
      a->sdk.push_back(*s.mean_error_deg);
      a->tracked.push_back(*t.mean_error_deg);
    }
  }
}

nlohmann::json RankingJson(const Ranking& r, const Ranking& plain) {
  return {{"pairs", r.pairs},
          {"same_action_lower_percent_plain_mean", plain.Share()},
          {"pairs_not_graded", r.failed},
          {"comparisons", r.comparisons},
          {"same_action_lower_percent", r.Share()},
          {"mean_same_action_deg", r.same_n ? r.same_sum / r.same_n : 0.0},
          {"mean_different_action_deg", r.different_n ? r.different_sum / r.different_n : 0.0}};
}

nlohmann::json AgreementJson(const Agreement& a) {
  return {{"pairs", a.pairs},
          {"part_values", a.sdk.size()},
          {"correlation", a.Correlation()},
          {"mean_abs_difference_deg", a.MeanAbsDifference()},
          {"mean_tracked_coverage", a.pairs ? a.coverage_sum / a.pairs : 0.0}};
}

int RunGradeReal(const Flags& flags, std::ostream& out, std::ostream& err) {
  const std::string dir = *flags.Get("real");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return ReportError(absl::NotFoundError(absl::StrCat("no folder ", dir)), err);
  }
  const std::vector<std::string> filters =
      absl::StrSplit(flags.GetOr("sequences", ""), ',', absl::SkipEmpty());
  const std::vector<fs::path> folders = RefSequenceFolders(dir, filters);
  if (folders.empty()) {
    return ReportError(
        absl::NotFoundError(absl::StrCat("no sequence (a folder with meta.json) in ", dir,
                                         filters.empty() ? "" : " whose name matches --sequences")),
        err);
  }
  const bool with_tracker = flags.Has("tracked");
  const bool quiet = flags.Has("json");
  std::unique_ptr<tracking::BodyTracker> tracker;
  if (with_tracker) {
    tracking::BodyTrackerOptions options;
    if (flags.Has("forest")) {
      options.method = tracking::TrackerMethod::kForest;
      options.forest_path = *flags.Get("forest");
    }
    options.model_path = flags.GetOr("model", "");
    absl::StatusOr<std::unique_ptr<tracking::BodyTracker>> created =
        tracking::BodyTracker::Create(options);
    if (!created.ok()) return ReportError(created.status(), err);
    tracker = *std::move(created);
  }
  mirror::GradeOptions options;
  options.use_dtw = !flags.Has("one-to-one");
  mirror::RepetitionOptions repetition_options;
  const absl::StatusOr<double> max_deg =
      flags.GetDouble("repetition-max-deg", repetition_options.max_distance_deg);
  if (!max_deg.ok()) return ReportError(max_deg.status(), err);
  repetition_options.max_distance_deg = *max_deg;
  if (absl::Status valid = repetition_options.Validate(); !valid.ok()) {
    return ReportError(valid, err);
  }
  // Which recordings act as learners (all by default): shell patterns on
  // the folder names, e.g. the subjects a tracker never trained on.
  const std::vector<std::string> learner_patterns =
      absl::StrSplit(flags.GetOr("learners", ""), ',', absl::SkipEmpty());
  const auto is_learner = [&](const std::string& name) {
    if (learner_patterns.empty()) return true;
    return std::any_of(learner_patterns.begin(), learner_patterns.end(), [&](const std::string& p) {
      return fnmatch(p.c_str(), name.c_str(), 0) == 0;
    });
  };

  std::vector<RealSequence> sequences;
  sequences.reserve(folders.size());
  for (const fs::path& folder : folders) {
    absl::StatusOr<RefSequence> ref = ReadRefSequence(folder);
    if (!ref.ok()) return ReportError(ref.status(), err);
    RealSequence seq;
    seq.ref = *std::move(ref);
    seq.sdk = SdkGradeFrames(seq.ref);
    if (tracker) {
      absl::StatusOr<std::vector<TrackedRefFrame>> tracked =
          TrackRefSequence(*tracker, seq.ref, /*history=*/true, /*own_segmentation=*/false);
      if (!tracked.ok()) return ReportError(tracked.status(), err);
      seq.tracked = TrackedGradeFrames(seq.ref, *tracked);
      if (!quiet && !flags.Has("quiet"))
        err << "tracked " << seq.ref.name << " (" << seq.tracked.size() << " frames)\n";
    }
    sequences.push_back(std::move(seq));
  }

  // Pairs within a dataset (one sensor type), teacher and learner different
  // people.
  std::map<std::string, std::vector<PairGrades>> by_dataset;
  for (const RealSequence& learner : sequences) {
    if (!is_learner(learner.ref.name)) continue;
    for (const RealSequence& teacher : sequences) {
      if (&teacher == &learner || teacher.ref.dataset != learner.ref.dataset ||
          teacher.ref.subject == learner.ref.subject) {
        continue;
      }
      PairGrades pair{&teacher, &learner, std::nullopt, std::nullopt};
      absl::StatusOr<mirror::Grade> sdk = mirror::GradeSequences(teacher.sdk, learner.sdk, options);
      if (sdk.ok()) pair.sdk = *std::move(sdk);
      const auto count = [&](const std::vector<GradeFrame>& t, const std::vector<GradeFrame>& l) {
        const absl::StatusOr<std::vector<mirror::Repetition>> reps =
            mirror::FindRepetitions(t, l, repetition_options);
        return reps.ok() ? static_cast<int>(reps->size()) : -1;
      };
      pair.sdk_repetitions = count(teacher.sdk, learner.sdk);
      if (tracker) {
        absl::StatusOr<mirror::Grade> tracked =
            mirror::GradeSequences(teacher.tracked, learner.tracked, options);
        if (tracked.ok()) pair.tracked = *std::move(tracked);
        pair.tracked_repetitions = count(teacher.tracked, learner.tracked);
      }
      by_dataset[learner.ref.dataset].push_back(std::move(pair));
    }
  }
  if (by_dataset.empty()) {
    return ReportError(absl::FailedPreconditionError(
                           "no pair of recordings of two different people in one dataset"),
                       err);
  }
  nlohmann::json datasets = nlohmann::json::object();
  Ranking all_sdk, all_tracked, all_sdk_plain, all_tracked_plain;
  Agreement all_agree;
  Counting all_count_sdk, all_count_tracked;
  for (const auto& [name, pairs] : by_dataset) {
    Ranking sdk, tracked, sdk_plain, tracked_plain;
    Agreement agree;
    Counting count_sdk, count_tracked;
    for (const PairGrades& p : pairs) {
      count_sdk.Add(p, false), all_count_sdk.Add(p, false);
      if (tracker) count_tracked.Add(p, true), all_count_tracked.Add(p, true);
    }
    Rank(pairs, false, &sdk);
    Rank(pairs, false, &sdk_plain, /*plain=*/true);
    Rank(pairs, false, &all_sdk);
    Rank(pairs, false, &all_sdk_plain, /*plain=*/true);
    nlohmann::json entry = {{"sdk", RankingJson(sdk, sdk_plain)},
                            {"repetitions_sdk", count_sdk.Json()}};
    if (tracker) {
      Rank(pairs, true, &tracked);
      Rank(pairs, true, &tracked_plain, /*plain=*/true);
      Rank(pairs, true, &all_tracked);
      Rank(pairs, true, &all_tracked_plain, /*plain=*/true);
      Agree(pairs, &agree);
      Agree(pairs, &all_agree);
      entry["tracked"] = RankingJson(tracked, tracked_plain);
      entry["tracked_vs_sdk"] = AgreementJson(agree);
      entry["repetitions_tracked"] = count_tracked.Json();
    }
    datasets[name] = entry;
    if (!quiet) {
      out << name << ": " << sdk.pairs << " pairs; SDK skeletons: same action graded lower in "
          << absl::StrFormat("%.1f", sdk.Share()) << " % of comparisons ("
          << absl::StrFormat("%.1f", sdk_plain.Share()) << " % by the plain mean; "
          << "action-weighted "
          << absl::StrFormat("%.1f", sdk.same_n ? sdk.same_sum / sdk.same_n : 0.0)
          << " deg same action, "
          << absl::StrFormat("%.1f", sdk.different_n ? sdk.different_sum / sdk.different_n : 0.0)
          << " deg different)\n"
          << name << ": SDK skeletons: " << count_sdk.Words() << "\n";
      if (tracker) {
        out << name << ": tracked skeletons: same action graded lower in "
            << absl::StrFormat("%.1f", tracked.Share()) << " % ("
            << absl::StrFormat("%.1f", tracked_plain.Share())
            << " % by the plain mean); per-part grades against the "
            << "SDK's: correlation " << absl::StrFormat("%.3f", agree.Correlation())
            << ", mean absolute difference " << absl::StrFormat("%.1f", agree.MeanAbsDifference())
            << " deg over " << agree.sdk.size() << " part grades, tracked coverage "
            << absl::StrFormat("%.0f", 100.0 * (agree.pairs ? agree.coverage_sum / agree.pairs : 0))
            << " %\n"
            << name << ": tracked skeletons: " << count_tracked.Words() << "\n";
      }
    }
  }
  nlohmann::json result = {
      {"datasets", datasets},
      {"sequences", sequences.size()},
      {"dtw", options.use_dtw},
      {"repetition_max_deg", repetition_options.max_distance_deg},
      {"overall",
       {{"sdk", RankingJson(all_sdk, all_sdk_plain)}, {"repetitions_sdk", all_count_sdk.Json()}}}};
  if (tracker) {
    result["overall"]["tracked"] = RankingJson(all_tracked, all_tracked_plain);
    result["overall"]["repetitions_tracked"] = all_count_tracked.Json();
    result["overall"]["tracked_vs_sdk"] = AgreementJson(all_agree);
  }
  if (flags.Has("json")) {
    out << result.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  } else {
    out << "overall: same action graded lower in " << absl::StrFormat("%.1f", all_sdk.Share())
        << " % of comparisons (SDK skeletons)";
    if (tracker) {
      out << ", " << absl::StrFormat("%.1f", all_tracked.Share())
          << " % (tracked); tracked against SDK per-part grades: correlation "
          << absl::StrFormat("%.3f", all_agree.Correlation()) << ", mean absolute difference "
          << absl::StrFormat("%.1f", all_agree.MeanAbsDifference()) << " deg";
    }
    out << "\noverall: SDK skeletons: " << all_count_sdk.Words() << "\n";
    if (tracker) out << "overall: tracked skeletons: " << all_count_tracked.Words() << "\n";
  }
  return kExitOk;
}

}  // namespace

int RunGrade(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags =
      Flags::Parse(args,
                   {"teacher", "teacher-id", "teacher-sensor", "learner", "sensor", "server",
                    "cache", "tls-ca", "token-file", "report", "real", "sequences", "model",
                    "forest", "smoothing-s", "learners", "repetition-max-deg", "teacher-joints"},
                   {"json", "pairs", "one-to-one", "tracked", "quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (flags->Has("real")) {
    if (flags->Has("teacher") || flags->Has("learner")) {
      return ReportError(absl::InvalidArgumentError(
                             "--real grades the folder's own pairs: no --teacher/--learner"),
                         err);
    }
    return RunGradeReal(*flags, out, err);
  }
  if (!flags->Has("teacher") || !flags->Has("learner")) {
    return ReportError(absl::InvalidArgumentError(
                           "give --teacher REENACTMENT|TAKE and --learner TAKE (or --real DIR)"),
                       err);
  }
  mirror::GradeOptions options;
  options.use_dtw = !flags->Has("one-to-one");
  auto smoothing = flags->GetDouble("smoothing-s", options.smoothing_s);
  if (!smoothing.ok()) return ReportError(smoothing.status(), err);
  options.smoothing_s = *smoothing;
  if (absl::Status valid = options.Validate(); !valid.ok()) return ReportError(valid, err);
  mirror::TakeGradeOptions take_options;
  take_options.grade = options;
  auto max_deg = flags->GetDouble("repetition-max-deg", take_options.repetitions.max_distance_deg);
  if (!max_deg.ok()) return ReportError(max_deg.status(), err);
  take_options.repetitions.max_distance_deg = *max_deg;
  if (absl::Status valid = take_options.repetitions.Validate(); !valid.ok()) {
    return ReportError(valid, err);
  }

  absl::StatusOr<std::vector<GradeFrame>> learner =
      TakeFrames(*flags->Get("learner"), flags->GetOr("sensor", ""), /*all_seen=*/false);
  if (!learner.ok()) {
    return ReportError(absl::Status(learner.status().code(),
                                    absl::StrCat("learner: ", learner.status().message())),
                       err);
  }
  std::string teacher_described;
  absl::StatusOr<std::vector<GradeFrame>> teacher =
      TeacherFrames(*flags, {LearnerFacingDeg(*learner)}, &teacher_described);
  if (!teacher.ok()) {
    return ReportError(absl::Status(teacher.status().code(),
                                    absl::StrCat("teacher: ", teacher.status().message())),
                       err);
  }
  absl::StatusOr<mirror::TakeGrade> take = mirror::GradeTake(*teacher, *learner, take_options);
  if (!take.ok()) return ReportError(take.status(), err);
  if (const auto report = flags->Get("report")) {
    if (absl::Status written = WriteReport(*report, *take, *teacher, *learner); !written.ok()) {
      return ReportError(written, err);
    }
  }
  if (flags->Has("json")) {
    nlohmann::json j = TakeGradeJson(*take, flags->Has("pairs"));
    j["teacher"] = teacher_described;
    j["learner"] = *flags->Get("learner");
    out << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    return kExitOk;
  }
  out << "teacher: " << teacher_described << "\nlearner: " << *flags->Get("learner") << "\n";
  PrintRepetitions(*take, take_options.repetitions, out);
  PrintGrade(take->overall, options, out);
  if (const auto report = flags->Get("report")) out << "report: " << *report << "\n";
  return kExitOk;
}

}  // namespace reenact::cli
