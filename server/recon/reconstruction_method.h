// The interface every reconstruction method implements, and TypedMethod, the
// one implementation of it that the methods use: a public options struct
// (Read(OptionReader&) with each option's bounds and documentation, and
// Validate() for what spans options), a run function on a loaded take, and
// the method's MethodSpec (name, summary, thesis sections, live or not,
// texture mode). The registry (registry.h) lists every method once; the
// worker runs them through RunMethod (methods.h), the server checks jobs
// against them and lists them (Jobs.ListMethods, `reenact jobs methods`).
//
// Adding a method: a folder under server/recon with a CMakeLists.txt that
// adds its sources to reenact_recon, a `const ReconstructionMethod&
// <Name>Method()` built as below, and one line in registry.cc:
//
//   const ReconstructionMethod& RigidCylindersMethod() {
//     static const TypedMethod<CylinderOptions> method(
//         {"rigid-cylinders", "cylinders per body part ...", "3.3, Eq. 3.3-3.6",
//          /*live=*/false, methods::TextureMode::kPoseClosest, {}},
//         &RunRigidCylinders);
//     return method;
//   }
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/methods/method_spec.h"
#include "common/methods/option_reader.h"
#include "common/model/reenactment.h"
#include "common/model/sensor_calibration.h"
#include "common/model/take.h"
#include "server/recon/live_follower.h"
#include "server/recon/memory_estimate.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

using methods::OptionMap;

// Human-readable log lines of a running method (one line per call).
using LogCallback = std::function<void(const std::string& line)>;

// What a method gets besides the take and its options.
struct MethodContext {
  // Folders whose subfolders an option model=makehuman:NAME names (the
  // server's --assets); never from a client.
  std::vector<std::string> asset_roots;
  // Stages and fractions 0..1 of the method's own run; returning false
  // cancels it (Cancelled).
  ProgressCallback progress;
  LogCallback log;
};

// One segment of a take split across several workers: the instants
// [first, end) that it delivers, fitted from `warmup_first` on.
struct SegmentRange {
  int first = 0;
  int end = 0;
  int warmup_first = 0;
};

// Segment `index` of `count` equal runs of `num_instants` instants, with
// `warmup` instants before its first (none before the take's start).
SegmentRange SegmentOf(int num_instants, int index, int count, int warmup);

// A stitch's check of one segment's part file, which says it is segment
// `part_index` of `part_count` holding the instants [part_first, part_end):
// InvalidArgument unless it is segment `index` of `count` of a take of
// `num_instants` instants (SegmentOf without warm-up) and starts at
// `next_first`, where the one before it ended.
absl::Status CheckSegmentPart(int index, int count, int num_instants, int next_first,
                              int part_index, int part_count, int part_first, int part_end);

// Which part of a job a run makes (ReconstructionMethod::Prepare): the
// whole reenactment, or one phase of a take split across several workers.
enum class MethodPhase {
  kWhole,    // The reenactment.
  kPrepare,  // What every segment needs, from the whole take (a part file).
  kSegment,  // One segment's part file, from the prepared one.
  kStitch,   // The reenactment, from the prepared and every segment's part.
};

// The images of the take a phase decodes, by instant (sorted, each once): a
// worker that streams the take from the server asks for these bytes alone
// (ReadTake's selection); the other frames come without their bytes.
struct TakeNeeds {
  std::vector<int> depth;  // Depth and actor mask.
  std::vector<int> color;
  // Every instant's depth and colour (what a method needs by default).
  static TakeNeeds All(const TakeFrames& take);
};

class ReconstructionMethod {
 public:
  virtual ~ReconstructionMethod() = default;

  // Name, summary, live, texture mode and the options with their defaults.
  virtual const methods::MethodSpec& spec() const = 0;

  // InvalidArgument for an unknown key (naming the known ones), a value
  // that does not parse or lies outside its bounds, or options that fail
  // the struct's Validate(). Cheap: jobs are checked before the take loads.
  virtual absl::Status CheckOptions(const OptionMap& options) const = 0;

  // The method's own large terms of a job's memory on a take of `take`'s
  // size (memory_estimate.h; recon::JobMemoryBytes adds what every run
  // holds). CheckOptions' errors. By default 0: the method holds nothing
  // that grows with its options or the take beyond the run's own terms.
  virtual absl::StatusOr<int64_t> MemoryBytes(const OptionMap& options, const TakeSize& take) const;

  // Builds the reenactment from a loaded take: parts, frames, keyframes and
  // in `info` at least frame_count, fps and figures; RunMethod fills the
  // bookkeeping (ids, method, options, sensors, texture mode) and writes it.
  // CheckOptions' errors; InvalidArgument for a take the method cannot use;
  // Cancelled when the context's progress returned false.
  virtual absl::StatusOr<Reenactment> Run(const TakeFrames& take, const OptionMap& options,
                                          const MethodContext& context) const = 0;

  // One take split across several workers, for a method whose spec says
  // `segmentable`: Prepare makes what every segment needs from the whole
  // take (the body method: its shape), Segment the part of the result of
  // instants SegmentOf(..., index, count, ...) from the prepared bytes,
  // Stitch the reenactment (as Run makes it) from the prepared bytes and
  // every segment's, in order. The bytes are the method's own. Others:
  // Unimplemented.
  virtual absl::StatusOr<std::string> Prepare(const TakeFrames& take, const OptionMap& options,
                                              const MethodContext& context) const;
  virtual absl::StatusOr<std::string> Segment(const TakeFrames& take, const OptionMap& options,
                                              const MethodContext& context,
                                              const std::string& prepared, int index,
                                              int count) const;
  virtual absl::StatusOr<Reenactment> Stitch(const TakeFrames& take, const OptionMap& options,
                                             const MethodContext& context,
                                             const std::string& prepared,
                                             const std::vector<std::string>& segments) const;

  // Checks what `options` name among the server's assets (`asset_roots`:
  // its --assets folders), e.g. a body model, so that a job the workers
  // could not run fails at Submit rather than after the queue. NotFound or
  // InvalidArgument naming the option. By default OK: nothing to look up.
  virtual absl::Status CheckAssets(const OptionMap& options,
                                   const std::vector<std::string>& asset_roots) const;

  // The follower of a take while it is recorded, for a live job of this
  // method (spec().live): fitted FrameSet by FrameSet on the live hub's
  // thread. `options` are the job's, live-only ones included. Unimplemented
  // for a method that cannot follow a take (the default).
  virtual absl::StatusOr<std::unique_ptr<LiveFollower>> MakeLiveFollower(
      const TakeInfo& info, const std::vector<SensorCalibration>& sensors, const OptionMap& options,
      const std::vector<std::string>& asset_roots) const;

  // The images phase `phase` (segment `index` of `count`) decodes from
  // `take`, which may be the take without any image bytes (it groups into
  // the same instants). By default every instant's depth and colour; a
  // segmentable method names only what each phase reads. Errors as the
  // phase's for bad options.
  virtual absl::StatusOr<TakeNeeds> Needs(const TakeFrames& take, const OptionMap& options,
                                          MethodPhase phase, int index, int count) const;
};

// The phases of a segmentable method with options `Options` (see
// ReconstructionMethod::Prepare).
template <typename Options>
struct SegmentFunctions {
  absl::StatusOr<std::string> (*prepare)(const TakeFrames& take, const Options& options,
                                         const MethodContext& context) = nullptr;
  absl::StatusOr<std::string> (*segment)(const TakeFrames& take, const Options& options,
                                         const MethodContext& context, const std::string& prepared,
                                         int index, int count) = nullptr;
  absl::StatusOr<Reenactment> (*stitch)(const TakeFrames& take, const Options& options,
                                        const MethodContext& context, const std::string& prepared,
                                        const std::vector<std::string>& segments) = nullptr;
  // What each phase decodes (ReconstructionMethod::Needs); null: all.
  absl::StatusOr<TakeNeeds> (*needs)(const TakeFrames& take, const Options& options,
                                     MethodPhase phase, int index, int count) = nullptr;
};

// A method's live follow and asset check (ReconstructionMethod::
// MakeLiveFollower, CheckAssets), each optional.
template <typename Options>
struct LiveAndAssetFunctions {
  // Null: the method cannot follow a take live (and its spec says so).
  absl::StatusOr<std::unique_ptr<LiveFollower>> (*make_live_follower)(
      const TakeInfo& info, const std::vector<SensorCalibration>& sensors, const OptionMap& options,
      const std::vector<std::string>& asset_roots) = nullptr;
  // Null: its options name no assets.
  absl::Status (*check_assets)(const Options& options,
                               const std::vector<std::string>& asset_roots) = nullptr;
};

// A method whose options are the struct `Options`: default-constructible,
// with `absl::Status Read(methods::OptionReader&)` and
// `absl::Status Validate() const`, and, when the method holds memory that
// grows with its options, `int64_t MemoryBytes(const TakeSize&) const`.
template <typename Options>
class TypedMethod final : public ReconstructionMethod {
 public:
  using RunFunction = absl::StatusOr<Reenactment> (*)(const TakeFrames& take,
                                                      const Options& options,
                                                      const MethodContext& context);

  // `spec`'s options are filled from Options' Read, followed by
  // `live_options`: those only a live follow of the take reads (marked
  // live_only; the worker never gets them).
  // `segments`: the phases of a run split across workers (all three, or
  // none: the method is not segmentable).
  // `extra`: its live follower (then spec().live is true) and its check of
  // the server's assets.
  TypedMethod(methods::MethodSpec spec, RunFunction run,
              std::vector<methods::OptionSpec> live_options = {},
              SegmentFunctions<Options> segments = {}, LiveAndAssetFunctions<Options> extra = {})
      : spec_(std::move(spec)), run_(run), segments_(segments), extra_(extra) {
    spec_.segmentable =
        segments_.prepare != nullptr && segments_.segment != nullptr && segments_.stitch != nullptr;
    spec_.live = extra_.make_live_follower != nullptr;
    spec_.options = methods::DescribeOptions<Options>();
    for (methods::OptionSpec& option : live_options) {
      option.live_only = true;
      spec_.options.push_back(std::move(option));
    }
  }

  const methods::MethodSpec& spec() const override { return spec_; }

  // Live-only options are the follower's to check (live_body.h).
  absl::Status CheckOptions(const OptionMap& options) const override {
    Options parsed;
    return methods::ParseOptions(options, &parsed);
  }

  absl::StatusOr<int64_t> MemoryBytes(const OptionMap& options,
                                      const TakeSize& take) const override {
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    if constexpr (requires { parsed.MemoryBytes(take); }) {
      return static_cast<int64_t>(parsed.MemoryBytes(take));
    } else {
      return int64_t{0};
    }
  }

  absl::StatusOr<Reenactment> Run(const TakeFrames& take, const OptionMap& options,
                                  const MethodContext& context) const override {
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    return run_(take, parsed, context);
  }

  absl::StatusOr<std::string> Prepare(const TakeFrames& take, const OptionMap& options,
                                      const MethodContext& context) const override {
    if (!spec_.segmentable) return ReconstructionMethod::Prepare(take, options, context);
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    return segments_.prepare(take, parsed, context);
  }

  absl::StatusOr<std::string> Segment(const TakeFrames& take, const OptionMap& options,
                                      const MethodContext& context, const std::string& prepared,
                                      int index, int count) const override {
    if (!spec_.segmentable) {
      return ReconstructionMethod::Segment(take, options, context, prepared, index, count);
    }
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    return segments_.segment(take, parsed, context, prepared, index, count);
  }

  absl::StatusOr<Reenactment> Stitch(const TakeFrames& take, const OptionMap& options,
                                     const MethodContext& context, const std::string& prepared,
                                     const std::vector<std::string>& segments) const override {
    if (!spec_.segmentable) {
      return ReconstructionMethod::Stitch(take, options, context, prepared, segments);
    }
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    return segments_.stitch(take, parsed, context, prepared, segments);
  }

  absl::Status CheckAssets(const OptionMap& options,
                           const std::vector<std::string>& asset_roots) const override {
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    if (extra_.check_assets == nullptr) return absl::OkStatus();
    return extra_.check_assets(parsed, asset_roots);
  }

  absl::StatusOr<std::unique_ptr<LiveFollower>> MakeLiveFollower(
      const TakeInfo& info, const std::vector<SensorCalibration>& sensors, const OptionMap& options,
      const std::vector<std::string>& asset_roots) const override {
    if (extra_.make_live_follower == nullptr) {
      return ReconstructionMethod::MakeLiveFollower(info, sensors, options, asset_roots);
    }
    return extra_.make_live_follower(info, sensors, options, asset_roots);
  }

  absl::StatusOr<TakeNeeds> Needs(const TakeFrames& take, const OptionMap& options,
                                  MethodPhase phase, int index, int count) const override {
    Options parsed;
    if (absl::Status status = methods::ParseOptions(options, &parsed); !status.ok()) {
      return status;
    }
    if (segments_.needs == nullptr) return TakeNeeds::All(take);
    return segments_.needs(take, parsed, phase, index, count);
  }

 private:
  methods::MethodSpec spec_;
  RunFunction run_;
  SegmentFunctions<Options> segments_;
  LiveAndAssetFunctions<Options> extra_;
};

}  // namespace reenact::recon
