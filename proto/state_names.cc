#include "proto/state_names.h"

namespace reenact {
namespace {

constexpr v1::TakeState kTakeStates[] = {v1::TAKE_STATE_RECORDING, v1::TAKE_STATE_COMPLETE,
                                         v1::TAKE_STATE_INTERRUPTED};
constexpr v1::JobState kJobStates[] = {v1::JOB_STATE_QUEUED, v1::JOB_STATE_RUNNING,
                                       v1::JOB_STATE_SUCCEEDED, v1::JOB_STATE_FAILED,
                                       v1::JOB_STATE_CANCELLED};

}  // namespace

const std::string& TakeStateName(v1::TakeState state) {
  static const std::string kRecording = "recording", kComplete = "complete",
                           kInterrupted = "interrupted", kUnspecified = "unspecified";
  switch (state) {
    case v1::TAKE_STATE_RECORDING:
      return kRecording;
    case v1::TAKE_STATE_COMPLETE:
      return kComplete;
    case v1::TAKE_STATE_INTERRUPTED:
      return kInterrupted;
    default:
      return kUnspecified;
  }
}

const std::string& JobStateName(v1::JobState state) {
  static const std::string kQueued = "queued", kRunning = "running", kSucceeded = "succeeded",
                           kFailed = "failed", kCancelled = "cancelled",
                           kUnspecified = "unspecified";
  switch (state) {
    case v1::JOB_STATE_QUEUED:
      return kQueued;
    case v1::JOB_STATE_RUNNING:
      return kRunning;
    case v1::JOB_STATE_SUCCEEDED:
      return kSucceeded;
    case v1::JOB_STATE_FAILED:
      return kFailed;
    case v1::JOB_STATE_CANCELLED:
      return kCancelled;
    default:
      return kUnspecified;
  }
}

std::optional<v1::TakeState> TakeStateFromName(std::string_view name) {
  for (const v1::TakeState state : kTakeStates) {
    if (name == TakeStateName(state)) return state;
  }
  return std::nullopt;
}

std::optional<v1::JobState> JobStateFromName(std::string_view name) {
  for (const v1::JobState state : kJobStates) {
    if (name == JobStateName(state)) return state;
  }
  return std::nullopt;
}

}  // namespace reenact
