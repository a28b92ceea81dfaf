#include "server/rpc/work_service.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/take.h"
#include "common/io/take_selection.h"
#include "proto/grpc_status.h"
#include "server/jobs/job_scheduler.h"
#include "server/rpc/rpc_auth.h"

namespace reenact::server {
namespace {

// Sends the take of a lease (or one of its inputs, or a selection of the
// take) chunk by chunk.
class TakeStream final : public grpc::ServerWriteReactor<v1::TakeChunk> {
 public:
  TakeStream(ServerContext& context, const v1::ReadTakeRequest& request)
      : context_(context), lease_id_(request.lease_id()) {
    if (request.has_selection()) {
      StartSelection(context, request);
      return;
    }
    const absl::Status opened = Open(context, request.lease_id(), request.input());
    if (!opened.ok()) {
      Finish(ToGrpcStatus(opened));
      return;
    }
    Next();
  }
  ~TakeStream() override {
    if (fd_ >= 0) ::close(fd_);
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the take stream was cancelled"));
      return;
    }
    Next();
  }
  void OnCancel() override { cancelled_.store(true); }
  void OnDone() override { delete this; }

 private:
  absl::Status Open(ServerContext& context, const std::string& lease_id, const std::string& input) {
    ASSIGN_OR_RETURN(const std::string path, context.jobs->LeasedTakePath(lease_id, input));
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    struct stat st {};
    if (fd_ < 0 || ::fstat(fd_, &st) != 0) {
      return absl::DataLossError(absl::StrCat(
          "the ", input.empty() ? "take" : "input " + input.substr(0, 64), " of lease ",
          lease_id.substr(0, 96), " cannot be read: ", std::strerror(errno)));
    }
    size_ = static_cast<int64_t>(st.st_size);
    return absl::OkStatus();
  }

  // A selection is made into a file of the job's folder by a thread of its
  // own (reading and writing the take takes seconds; gRPC's callback
  // threads must not block), opened and unlinked at once (nothing is left
  // behind, whatever happens to the stream), then streamed.
  void StartSelection(ServerContext& context, const v1::ReadTakeRequest& request) {
    if (!request.input().empty()) {
      Finish(ToGrpcStatus(absl::InvalidArgumentError(
          "a selection reads the take, not an input; leave input empty")));
      return;
    }
    const absl::StatusOr<std::string> take = context.jobs->LeasedTakePath(request.lease_id(), "");
    const absl::StatusOr<std::string> dir =
        take.ok() ? context.jobs->LeaseScratchDir(request.lease_id()) : take.status();
    if (!dir.ok()) {
      Finish(ToGrpcStatus(dir.status()));
      return;
    }
    static std::atomic<uint64_t> serial{0};
    const std::string path = absl::StrCat(*dir, "/selection-", ::getpid(), "-", ++serial, ".mcap");
    std::thread([this, take = *take, path, selection = request.selection()] {
      const absl::Status made = MakeSelection(take, selection, path);
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
      if (!made.ok()) {
        Finish(ToGrpcStatus(made));
        return;
      }
      Next();  // Touches nothing of `this` after its StartWrite or Finish.
    }).detach();
  }

  absl::Status MakeSelection(const std::string& take_path, const v1::TakeSelection& selection,
                             const std::string& path) {
    ASSIGN_OR_RETURN(const std::unique_ptr<TakeReader> take, TakeReader::Open(take_path));
    RETURN_IF_ERROR(ValidateTakeSelection(*take, selection));
    RETURN_IF_ERROR(
        WriteTakeSelection(*take, selection, path, [this] { return cancelled_.load(); }));
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    struct stat st {};
    if (fd_ < 0 || ::fstat(fd_, &st) != 0) {
      return absl::InternalError(
          absl::StrCat("the take selection cannot be read back: ", std::strerror(errno)));
    }
    size_ = static_cast<int64_t>(st.st_size);
    return absl::OkStatus();
  }

  void Next() {
    if (offset_ >= size_) {
      context_.jobs->CountRead(lease_id_, size_);
      Finish(grpc::Status::OK);
      return;
    }
    const int64_t n = std::min<int64_t>(kWorkTakeChunkBytes, size_ - offset_);
    if (const absl::Status read = ReadAt(fd_, offset_, n, chunk_.mutable_data()); !read.ok()) {
      Finish(ToGrpcStatus(absl::DataLossError(absl::StrCat("the take: ", read.message()))));
      return;
    }
    chunk_.set_offset(offset_);
    chunk_.set_file_bytes(size_);
    offset_ += n;
    StartWrite(&chunk_);
  }

  ServerContext& context_;
  const std::string lease_id_;
  int fd_ = -1;
  int64_t size_ = 0;
  int64_t offset_ = 0;
  std::atomic<bool> cancelled_{false};
  v1::TakeChunk chunk_;
};

// Receives a reenactment into the path the scheduler gives and commits it.
class UploadStream final : public grpc::ServerReadReactor<v1::UploadChunk> {
 public:
  // `holder`: the caller's credential (JobScheduler::CheckLeaseHolder).
  UploadStream(ServerContext& context, std::string holder, v1::UploadResponse* response)
      : context_(context), holder_(std::move(holder)), response_(response) {
    StartRead(&chunk_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      End();
      return;
    }
    const absl::Status taken = Take();
    if (!taken.ok()) {
      Fail(taken);
      return;
    }
    chunk_.Clear();
    StartRead(&chunk_);
  }

  void OnDone() override {
    if (fd_ >= 0) ::close(fd_);
    // A stream that broke gives its claim back; the worker may try again.
    if (claimed_ && !finished_) context_.jobs->AbortUpload(lease_id_);
    delete this;
  }

 private:
  absl::Status Take() {
    if (!claimed_) {
      lease_id_ = chunk_.lease_id();
      declared_ = chunk_.result().file_bytes();
      if (declared_ <= 0 || declared_ > kMaxUploadBytes) {
        return absl::InvalidArgumentError(
            absl::StrCat("result.file_bytes ", declared_, " is outside 1..", kMaxUploadBytes));
      }
      RETURN_IF_ERROR(context_.jobs->CheckLeaseHolder(lease_id_, holder_));
      ASSIGN_OR_RETURN(path_, context_.jobs->BeginUpload(lease_id_));
      claimed_ = true;
      fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
      if (fd_ < 0) {
        return absl::UnavailableError(
            absl::StrCat("the server cannot write the upload: ", std::strerror(errno)));
      }
    } else {
      if (!chunk_.lease_id().empty() && chunk_.lease_id() != lease_id_) {
        return absl::InvalidArgumentError("an upload carries one lease");
      }
      RETURN_IF_ERROR(context_.jobs->ContinueUpload(lease_id_));
    }
    const std::string& data = chunk_.data();
    if (written_ + static_cast<int64_t>(data.size()) > declared_) {
      return absl::InvalidArgumentError(
          absl::StrCat("the upload is longer than its file_bytes ", declared_));
    }
    size_t done = 0;
    while (done < data.size()) {
      const ssize_t n = ::write(fd_, data.data() + done, data.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        return errno == ENOSPC ? absl::ResourceExhaustedError(
                                     "the server's disk is full; the upload was not stored")
                               : absl::UnavailableError(absl::StrCat(
                                     "the server cannot write the upload: ", std::strerror(errno)));
      }
      done += static_cast<size_t>(n);
    }
    written_ += static_cast<int64_t>(data.size());
    return absl::OkStatus();
  }

  void End() {
    if (!claimed_) {
      Fail(absl::InvalidArgumentError("an empty upload: the first message names the lease"));
      return;
    }
    if (written_ != declared_) {
      Fail(absl::InvalidArgumentError(
          absl::StrCat("the upload ended after ", written_, " of ", declared_, " bytes")));
      return;
    }
    // Syncing and reading the file back block: off the callback thread.
    context_.blocking->Schedule([this] {
      const bool synced = ::fsync(fd_) == 0;
      ::close(fd_);
      fd_ = -1;
      if (!synced) {
        Fail(absl::UnavailableError(
            absl::StrCat("the server cannot write the upload: ", std::strerror(errno))));
        return;
      }
      const absl::StatusOr<v1::Job> job = context_.jobs->CommitUpload(lease_id_);
      finished_ = true;
      if (job.ok()) *response_->mutable_job() = *job;
      Finish(ToGrpcStatus(job.status()));
    });
  }

  void Fail(const absl::Status& status) {
    if (claimed_) context_.jobs->AbortUpload(lease_id_);
    finished_ = true;
    Finish(ToGrpcStatus(status));
  }

  ServerContext& context_;
  const std::string holder_;
  v1::UploadResponse* const response_;
  v1::UploadChunk chunk_;
  std::string lease_id_;
  std::string path_;
  int fd_ = -1;
  bool claimed_ = false;
  bool finished_ = false;
  int64_t declared_ = 0;
  int64_t written_ = 0;
};

}  // namespace

grpc::ServerUnaryReactor* WorkService::Lease(grpc::CallbackServerContext* rpc,
                                             const v1::LeaseRequest* request,
                                             v1::LeaseResponse* response) {
  const absl::StatusOr<rpc::Principal> who = Authorize(context_, *rpc, "/reenact.v1.Work/Lease");
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  if (!who.ok()) {
    reactor->Finish(ToGrpcStatus(who.status()));
    return reactor;
  }
  context_.jobs->Lease(*request, who->name,
                       [reactor, response](absl::StatusOr<v1::LeaseResponse> leased) {
                         if (leased.ok()) *response = std::move(*leased);
                         reactor->Finish(ToGrpcStatus(leased.status()));
                       });
  return reactor;
}

grpc::ServerWriteReactor<v1::TakeChunk>* WorkService::ReadTake(grpc::CallbackServerContext* rpc,
                                                               const v1::ReadTakeRequest* request) {
  const absl::StatusOr<rpc::Principal> who = Authorize(context_, *rpc, "/reenact.v1.Work/ReadTake");
  if (!who.ok()) return new rpc::RefusedWriter<v1::TakeChunk>(ToGrpcStatus(who.status()));
  if (absl::Status holder = context_.jobs->CheckLeaseHolder(request->lease_id(), who->name);
      !holder.ok()) {
    return new rpc::RefusedWriter<v1::TakeChunk>(ToGrpcStatus(holder));
  }
  return new TakeStream(context_, *request);
}

grpc::ServerUnaryReactor* WorkService::Heartbeat(grpc::CallbackServerContext* rpc,
                                                 const v1::HeartbeatRequest* request,
                                                 v1::HeartbeatResponse* response) {
  const absl::StatusOr<rpc::Principal> who =
      Authorize(context_, *rpc, "/reenact.v1.Work/Heartbeat");
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  if (!who.ok()) {
    reactor->Finish(ToGrpcStatus(who.status()));
    return reactor;
  }
  if (absl::Status holder = context_.jobs->CheckLeaseHolder(request->lease_id(), who->name);
      !holder.ok()) {
    reactor->Finish(ToGrpcStatus(holder));
    return reactor;
  }
  absl::StatusOr<v1::HeartbeatResponse> beat = context_.jobs->Heartbeat(*request);
  if (beat.ok()) *response = std::move(*beat);
  reactor->Finish(ToGrpcStatus(beat.status()));
  return reactor;
}

grpc::ServerReadReactor<v1::UploadChunk>* WorkService::Upload(grpc::CallbackServerContext* rpc,
                                                              v1::UploadResponse* response) {
  const absl::StatusOr<rpc::Principal> who = Authorize(context_, *rpc, "/reenact.v1.Work/Upload");
  if (!who.ok()) return new rpc::RefusedReader<v1::UploadChunk>(ToGrpcStatus(who.status()));
  return new UploadStream(context_, who->name, response);
}

grpc::ServerUnaryReactor* WorkService::Fail(grpc::CallbackServerContext* rpc,
                                            const v1::FailRequest* request,
                                            v1::FailResponse* response) {
  const absl::StatusOr<rpc::Principal> who = Authorize(context_, *rpc, "/reenact.v1.Work/Fail");
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  if (!who.ok()) {
    reactor->Finish(ToGrpcStatus(who.status()));
    return reactor;
  }
  context_.blocking->Schedule([this, reactor, request, response, holder = who->name] {
    if (absl::Status held = context_.jobs->CheckLeaseHolder(request->lease_id(), holder);
        !held.ok()) {
      reactor->Finish(ToGrpcStatus(held));
      return;
    }
    const absl::StatusOr<v1::Job> job = context_.jobs->FailLease(*request);
    if (job.ok()) *response->mutable_job() = *job;
    reactor->Finish(ToGrpcStatus(job.status()));
  });
  return reactor;
}

}  // namespace reenact::server
