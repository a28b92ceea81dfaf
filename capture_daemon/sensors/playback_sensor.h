// Playback backend of reenactd: plays an MCAP take (common/io/take.h) as if
// its sensors were live, one Sensor per sensor of the take.
//
// The sensors of one take share a player thread that reads the file once,
// chunk by chunk (memory stays bounded by a chunk and one pending frame per
// sensor), gathers each sensor's depth, colour, mask and skeleton messages of
// one frame into a CapturedFrame, and hands it to that sensor's callback. The
// encoded bytes pass through unchanged (depth stays bit-identical to the
// source); only ids, stamps and frame indices are rewritten:
//   host_stamp_ns   = anchor + (source host stamp - take start) + loop * period
//   device_stamp_ns = source device stamp + loop * period
//   frame_index     = source frame index + frames of the earlier loops
// where `anchor` is the host clock (WallNowNs) when playback begins, the take
// start is TakeInfo.start_stamp_ns (or the first log time) and `period` the
// take's length plus one frame period. Frames without depth are skipped. A
// frame is handed over when the next frame of its sensor begins, or when the
// file has moved two frame periods past it (its stream went quiet).
//
// Pacing: by default each frame is handed over at its host stamp (real time;
// a consumer that blocks delays later frames, none is dropped). With
// SourceOptions.fast frames go as fast as the callbacks return. With
// SourceOptions.loop the take starts over at its end, forever.
//
// The player starts when every sensor of the take has been started, or
// 200 ms after the first Start (then sensors started later miss the frames
// before their start). Each sensor's EndCallback(OK) follows its last frame,
// so a sensor whose streams end early ends early; a read error ends every
// sensor still streaming with that error.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/sensor.h"

namespace reenact::capture {

// Opens the take at `path` and returns its sensors in sensor-id order. Ids are
// the take's own, or options.id_prefix + (options.first_index + i) when a
// prefix is given. NotFound when the file does not exist, InvalidArgument when
// it is not a take or has no sensor with depth, DataLoss when it is damaged.
absl::StatusOr<SensorList> OpenPlaybackSensors(const std::string& path,
                                               const SourceOptions& options);

}  // namespace reenact::capture
