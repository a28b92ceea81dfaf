// PumpedWriteReactor: the write side shared by the server-streaming RPCs
// that push events as they happen (a job's Watch, a live Follow, the
// daemon's StreamFrames). gRPC's callback API allows one write in flight per
// stream; events arrive on other threads meanwhile. The subclass keeps its
// own queue of what is still to send (merged, bounded, newest only: its
// choice) under mutex(), and calls Pump() after changing it; the pump starts
// the next write when none is in flight, and finishes the stream once the
// subclass has marked the end and its queue is empty, or at once when the
// client cancels or a write fails (CANCELLED).
//
// A subclass implements TakeNextLocked (move the next message out of its
// queue, or return false when it is empty) and EndStatusLocked (the status to
// finish with after the end), and OnDone (unsubscribe, then delete this).
// Both *Locked hooks run with mutex() held.
#pragma once

#include <mutex>
#include <string>
#include <utility>

#include <grpcpp/grpcpp.h>

namespace reenact {

template <typename Message>
class PumpedWriteReactor : public grpc::ServerWriteReactor<Message> {
 public:
  void OnWriteDone(bool ok) override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      writing_ = false;
      if (!ok) broken_ = true;
    }
    Pump();
  }

  void OnCancel() override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      broken_ = true;
    }
    Pump();
  }

 protected:
  // `what` names the stream in the CANCELLED message ("the watch").
  explicit PumpedWriteReactor(std::string what) : what_(std::move(what)) {}

  // The next message to write, moved out of the subclass's queue; false
  // when there is none now.
  virtual bool TakeNextLocked(Message* next) = 0;
  // The status to finish with once the end is marked and everything is out.
  virtual grpc::Status EndStatusLocked() = 0;

  std::mutex& mutex() { return mu_; }
  // With mutex() held: nothing comes after what is queued now.
  void MarkEndedLocked() { ended_ = true; }
  bool ended_locked() const { return ended_; }

  // Starts the next write, or finishes the stream when it is over. Call it
  // without mutex() held, after every change to the queue or the end.
  void Pump() {
    bool finish = false;
    grpc::Status status;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (writing_ || finished_) return;
      if (!broken_ && TakeNextLocked(&in_flight_)) {
        writing_ = true;
      } else if (broken_ || ended_) {
        finished_ = true;
        finish = true;
        status = broken_ ? grpc::Status(grpc::StatusCode::CANCELLED, what_ + " was cancelled")
                         : EndStatusLocked();
      } else {
        return;
      }
    }
    if (finish) {
      this->Finish(status);
    } else {
      this->StartWrite(&in_flight_);
    }
  }

  // Finishes at once with `status` (e.g. from the constructor, when the
  // request cannot be served); later pumps do nothing.
  void FinishNow(const grpc::Status& status) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (finished_) return;
      finished_ = true;
    }
    this->Finish(status);
  }

 private:
  const std::string what_;
  std::mutex mu_;
  Message in_flight_;
  bool writing_ = false;
  bool broken_ = false;
  bool ended_ = false;
  bool finished_ = false;
};

}  // namespace reenact
