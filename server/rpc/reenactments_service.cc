#include "server/rpc/reenactments_service.h"

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/mcap_reader.h"
#include "common/io/reenactment_file.h"
#include "proto/grpc_status.h"
#include "server/rpc/follow_stream.h"
#include "server/rpc/pagination.h"
#include "server/rpc/rpc_auth.h"
#include "server/store/reenactment_store.h"

namespace reenact::server {
namespace {

absl::Status CheckStore(const ServerContext& context) {
  if (context.reenactments == nullptr) {
    return absl::UnavailableError("this server has no reenactment store");
  }
  return absl::OkStatus();
}

// Streams one reenactment file. A reader thread fills a bounded queue; the
// reactor drains it one write at a time. StartWrite and Finish are called
// outside the mutex (gRPC may run reactions inline); `writing_` and
// `finished_` make sure there is one write in flight at most and one Finish.
class FetchStream final : public grpc::ServerWriteReactor<v1::FetchReenactmentChunk> {
 public:
  FetchStream(ServerContext& context, const v1::FetchReenactmentRequest& request)
      : request_(request) {
    absl::Status status = CheckStore(context);
    if (status.ok()) {
      absl::StatusOr<v1::ReenactmentSummary> summary =
          context.reenactments->Get(request.reenactment_id());
      status = summary.status();
      if (status.ok()) path_ = context.reenactments->PathFor(request.reenactment_id());
    }
    if (!status.ok()) {
      finished_ = true;
      Finish(ToGrpcStatus(status));
      return;
    }
    reader_ = std::thread([this] { ReaderDone(Read()); });
  }

  void OnWriteDone(bool ok) override {
    bool cancelled = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      writing_ = false;
      queued_bytes_ -= in_flight_bytes_;
      in_flight_bytes_ = 0;
      if (!ok) cancelled_ = true;
      cancelled = cancelled_;
    }
    space_.notify_all();
    if (cancelled) {
      FinishOnce(grpc::Status(grpc::StatusCode::CANCELLED, "the fetch was cancelled"));
      return;
    }
    Pump();
  }

  void OnCancel() override {
    bool finish = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      cancelled_ = true;
      finish = !writing_;
    }
    space_.notify_all();
    if (finish) FinishOnce(grpc::Status(grpc::StatusCode::CANCELLED, "the fetch was cancelled"));
  }

  void OnDone() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      cancelled_ = true;
    }
    space_.notify_all();
    if (reader_.joinable()) reader_.join();
    delete this;
  }

 private:
  // The reader thread: every message in order, then the end.
  absl::Status Read() {
    ASSIGN_OR_RETURN(ReenactmentData data, ReadReenactmentFile(path_, /*skip_keyframes=*/true));
    v1::FetchReenactmentChunk chunk;
    *chunk.mutable_info() = std::move(data.info);
    RETURN_IF_ERROR(Push(std::move(chunk)));
    for (v1::BodyMesh& body : data.body) {
      // The appearance video after the mesh, in pieces (the proto's rule).
      std::string video;
      if (body.has_appearance()) video = std::move(*body.mutable_appearance()->mutable_mp4());
      if (body.has_appearance()) body.mutable_appearance()->clear_mp4();
      chunk.Clear();
      *chunk.mutable_body_mesh() = std::move(body);
      RETURN_IF_ERROR(Push(std::move(chunk)));
      constexpr size_t kPieceBytes = size_t{1} << 20;
      for (size_t at = 0; at < video.size(); at += kPieceBytes) {
        chunk.Clear();
        chunk.set_appearance_mp4_piece(video.substr(at, kPieceBytes));
        RETURN_IF_ERROR(Push(std::move(chunk)));
      }
    }
    for (v1::PartMesh& mesh : data.parts) {
      chunk.Clear();
      *chunk.mutable_part_mesh() = std::move(mesh);
      RETURN_IF_ERROR(Push(std::move(chunk)));
    }
    RETURN_IF_ERROR(PushFrames(data.frames));
    if (request_.skip_keyframes()) return absl::OkStatus();
    McapReaderOptions options;
    options.allow_recovery = false;
    ASSIGN_OR_RETURN(const std::unique_ptr<McapReader> mcap, McapReader::Open(path_, options));
    return mcap->ForEachMessage(
        [&](const McapChannel&, const McapMessage& message) -> absl::Status {
          v1::FetchReenactmentChunk keyframe;
          if (!keyframe.mutable_keyframe()->ParseFromString(message.data)) {
            return absl::DataLossError(
                absl::StrCat(path_, ": keyframe ", message.sequence, " does not parse"));
          }
          return Push(std::move(keyframe));
        },
        kReenactmentKeyframeTopic);
  }

  absl::Status PushFrames(std::vector<v1::PartFrame>& frames) {
    v1::FetchReenactmentChunk chunk;
    int64_t batch_bytes = 0;
    for (v1::PartFrame& frame : frames) {
      const auto bytes = static_cast<int64_t>(frame.ByteSizeLong());
      if (batch_bytes > 0 && batch_bytes + bytes > kFetchFrameBatchBytes) {
        RETURN_IF_ERROR(Push(std::move(chunk)));
        chunk.Clear();
        batch_bytes = 0;
      }
      *chunk.mutable_frames()->add_frames() = std::move(frame);
      batch_bytes += bytes;
    }
    if (batch_bytes > 0) RETURN_IF_ERROR(Push(std::move(chunk)));
    return absl::OkStatus();
  }

  // Queues one message, waiting while the queue is full; Cancelled once the
  // stream is gone.
  absl::Status Push(v1::FetchReenactmentChunk chunk) {
    const auto bytes = static_cast<int64_t>(chunk.ByteSizeLong());
    {
      std::unique_lock<std::mutex> lock(mutex_);
      space_.wait(lock, [&] {
        return cancelled_ || queued_bytes_ == 0 || queued_bytes_ + bytes <= kFetchQueueBytes;
      });
      if (cancelled_) return absl::CancelledError("the fetch was cancelled");
      queue_.emplace_back(std::move(chunk), bytes);
      queued_bytes_ += bytes;
    }
    Pump();
    return absl::OkStatus();
  }

  void ReaderDone(const absl::Status& status) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      reader_done_ = true;
      reader_status_ = status;
    }
    Pump();
  }

  // Starts the next write, or finishes once the reader is done and the
  // queue is drained.
  void Pump() {
    enum { kNothing, kWrite, kFinish } action = kNothing;
    grpc::Status status;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (writing_ || finished_ || cancelled_) return;
      if (!queue_.empty()) {
        current_ = std::move(queue_.front().first);
        in_flight_bytes_ = queue_.front().second;
        queue_.pop_front();
        writing_ = true;
        action = kWrite;
      } else if (reader_done_) {
        finished_ = true;
        status = ToGrpcStatus(reader_status_);
        action = kFinish;
      }
    }
    if (action == kWrite) StartWrite(&current_);
    if (action == kFinish) Finish(status);
  }

  void FinishOnce(const grpc::Status& status) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (finished_) return;
      finished_ = true;
    }
    Finish(status);
  }

  const v1::FetchReenactmentRequest request_;
  std::string path_;
  std::thread reader_;
  std::mutex mutex_;
  std::condition_variable space_;
  std::deque<std::pair<v1::FetchReenactmentChunk, int64_t>> queue_;
  int64_t queued_bytes_ = 0;     // Queued and in flight.
  int64_t in_flight_bytes_ = 0;  // Of current_.
  v1::FetchReenactmentChunk current_;
  bool writing_ = false;
  bool finished_ = false;
  bool cancelled_ = false;
  bool reader_done_ = false;
  absl::Status reader_status_;
};

}  // namespace

absl::Status ListReenactments(ServerContext& context, const v1::ListReenactmentsRequest& request,
                              v1::ListReenactmentsResponse* response) {
  RETURN_IF_ERROR(CheckStore(context));
  ASSIGN_OR_RETURN(
      *response->mutable_next_page_token(),
      Paginate<v1::ReenactmentSummary>(
          context.reenactments->List(request.take_id()), request.page_size(), request.page_token(),
          [](const v1::ReenactmentSummary& r) {
            return PageKey{r.info().created_unix_ns(), r.info().reenactment_id()};
          },
          [response](v1::ReenactmentSummary&& r) {
            *response->add_reenactments() = std::move(r);
          }));
  return absl::OkStatus();
}

absl::Status GetReenactment(ServerContext& context, const v1::GetReenactmentRequest& request,
                            v1::ReenactmentSummary* response) {
  RETURN_IF_ERROR(CheckStore(context));
  ASSIGN_OR_RETURN(*response, context.reenactments->Get(request.reenactment_id()));
  return absl::OkStatus();
}

absl::Status DeleteReenactment(ServerContext& context, const v1::DeleteReenactmentRequest& request,
                               v1::DeleteReenactmentResponse* response) {
  RETURN_IF_ERROR(CheckStore(context));
  return context.reenactments->Delete(request.reenactment_id());
}

grpc::ServerUnaryReactor* ReenactmentsService::List(grpc::CallbackServerContext* rpc,
                                                    const v1::ListReenactmentsRequest* request,
                                                    v1::ListReenactmentsResponse* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Reenactments/List"))
    return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(ListReenactments(context_, *request, response)));
  return reactor;
}

grpc::ServerUnaryReactor* ReenactmentsService::Get(grpc::CallbackServerContext* rpc,
                                                   const v1::GetReenactmentRequest* request,
                                                   v1::ReenactmentSummary* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Reenactments/Get"))
    return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(GetReenactment(context_, *request, response)));
  return reactor;
}

grpc::ServerWriteReactor<v1::FetchReenactmentChunk>* ReenactmentsService::Fetch(
    grpc::CallbackServerContext* rpc, const v1::FetchReenactmentRequest* request) {
  if (auto who = Authorize(context_, *rpc, "/reenact.v1.Reenactments/Fetch"); !who.ok()) {
    return new RefusedWriter<v1::FetchReenactmentChunk>(ToGrpcStatus(who.status()));
  }
  return new FetchStream(context_, *request);
}

grpc::ServerWriteReactor<v1::FollowEvent>* ReenactmentsService::Follow(
    grpc::CallbackServerContext* rpc, const v1::FollowRequest* request) {
  if (auto who = Authorize(context_, *rpc, "/reenact.v1.Reenactments/Follow"); !who.ok()) {
    return new RefusedWriter<v1::FollowEvent>(ToGrpcStatus(who.status()));
  }
  return NewFollowStream(context_, *request);
}

grpc::ServerUnaryReactor* ReenactmentsService::Delete(grpc::CallbackServerContext* rpc,
                                                      const v1::DeleteReenactmentRequest* request,
                                                      v1::DeleteReenactmentResponse* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Reenactments/Delete"))
    return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(DeleteReenactment(context_, *request, response)));
  return reactor;
}

}  // namespace reenact::server
