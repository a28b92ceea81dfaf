// Test helper of server/recon: a take as a worker that streams it with a
// selection gets it (ReadTake's selection, common/io/take_selection.h): the
// image bytes of only the instants a phase's TakeNeeds names.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/status_macros.h"
#include "common/io/take.h"
#include "common/io/take_selection.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/take_frames.h"

namespace reenact::recon::testing {

// Writes the take at `path` (loaded as `take`) with the bytes of `needs`
// alone to `out` and loads it.
inline absl::StatusOr<std::unique_ptr<TakeFrames>> SelectedTake(const std::string& path,
                                                                const TakeFrames& take,
                                                                const TakeNeeds& needs,
                                                                const std::string& out) {
  v1::TakeSelection selection;
  const auto add = [&](const std::vector<int>& instants,
                       google::protobuf::RepeatedPtrField<v1::FrameRange>* ranges) {
    for (const int i : instants) {
      for (int s = 0; s < take.num_sensors(); ++s) {
        const SensorView& view = take.instant(i).views[s];
        if (!view.present) continue;
        v1::FrameRange* range = ranges->Add();
        range->set_sensor_id(take.sensors()[s].sensor_id);
        range->set_first(view.frame_index);
        range->set_end(view.frame_index + 1);
      }
    }
  };
  add(needs.depth, selection.mutable_depth());
  add(needs.color, selection.mutable_color());
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  RETURN_IF_ERROR(WriteTakeSelection(*reader, selection, out));
  return TakeFrames::Load(out);
}

}  // namespace reenact::recon::testing
