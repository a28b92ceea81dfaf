#include "server/recon/reconstruction_method.h"

#include <algorithm>
#include <numeric>

#include "absl/strings/str_cat.h"

namespace reenact::recon {
namespace {

absl::Status NotSegmentable(const ReconstructionMethod& method) {
  return absl::UnimplementedError(absl::StrCat("method ", method.spec().name,
                                               " cannot split a take across workers (segments)"));
}

}  // namespace

SegmentRange SegmentOf(int num_instants, int index, int count, int warmup) {
  SegmentRange range;
  if (num_instants <= 0 || count <= 0 || index < 0 || index >= count) return range;
  range.first = static_cast<int>(int64_t{index} * num_instants / count);
  range.end = static_cast<int>(int64_t{index + 1} * num_instants / count);
  range.warmup_first = std::max(0, range.first - std::max(0, warmup));
  return range;
}

absl::Status CheckSegmentPart(int index, int count, int num_instants, int next_first,
                              int part_index, int part_count, int part_first, int part_end) {
  const SegmentRange range = SegmentOf(num_instants, index, count, 0);
  if (part_index != index || part_count != count || part_first != range.first ||
      part_end != range.end || part_first != next_first) {
    return absl::InvalidArgumentError(
        absl::StrCat("segment ", index, " of ", count, " holds instants [", part_first, ", ",
                     part_end, ") as segment ", part_index, " of ", part_count, "; expected [",
                     range.first, ", ", range.end, ")"));
  }
  return absl::OkStatus();
}

TakeNeeds TakeNeeds::All(const TakeFrames& take) {
  TakeNeeds all;
  all.depth.resize(take.num_instants());
  std::iota(all.depth.begin(), all.depth.end(), 0);
  all.color = all.depth;
  return all;
}

absl::StatusOr<TakeNeeds> ReconstructionMethod::Needs(const TakeFrames& take, const OptionMap&,
                                                      MethodPhase, int, int) const {
  return TakeNeeds::All(take);
}

absl::Status ReconstructionMethod::CheckAssets(const OptionMap& options,
                                               const std::vector<std::string>& /*roots*/) const {
  return CheckOptions(options);
}

absl::StatusOr<std::unique_ptr<LiveFollower>> ReconstructionMethod::MakeLiveFollower(
    const TakeInfo&, const std::vector<SensorCalibration>&, const OptionMap&,
    const std::vector<std::string>&) const {
  return absl::UnimplementedError(
      absl::StrCat("method ", spec().name, " cannot follow a take while it is recorded"));
}

absl::StatusOr<int64_t> ReconstructionMethod::MemoryBytes(const OptionMap& options,
                                                          const TakeSize& /*take*/) const {
  if (absl::Status status = CheckOptions(options); !status.ok()) return status;
  return int64_t{0};
}

absl::StatusOr<std::string> ReconstructionMethod::Prepare(const TakeFrames&, const OptionMap&,
                                                          const MethodContext&) const {
  return NotSegmentable(*this);
}

absl::StatusOr<std::string> ReconstructionMethod::Segment(const TakeFrames&, const OptionMap&,
                                                          const MethodContext&, const std::string&,
                                                          int, int) const {
  return NotSegmentable(*this);
}

absl::StatusOr<Reenactment> ReconstructionMethod::Stitch(const TakeFrames&, const OptionMap&,
                                                         const MethodContext&, const std::string&,
                                                         const std::vector<std::string>&) const {
  return NotSegmentable(*this);
}

}  // namespace reenact::recon
