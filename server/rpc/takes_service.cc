#include "server/rpc/takes_service.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "proto/grpc_status.h"
#include "server/jobs/job_scheduler.h"
#include "server/rpc/pagination.h"
#include "server/rpc/rpc_auth.h"
#include "server/store/frame_set_validation.h"
#include "server/store/reenactment_store.h"

namespace reenact::server {
namespace {

// Sends a take file chunk by chunk.
class DownloadStream final : public grpc::ServerWriteReactor<v1::TakeFileChunk> {
 public:
  DownloadStream(ServerContext& context, const v1::DownloadTakeRequest& request)
      : context_(context), take_id_(request.take_id()) {
    const absl::Status opened = Open(request);
    if (!opened.ok()) {
      Finish(ToGrpcStatus(opened));
      return;
    }
    Next();
  }
  ~DownloadStream() override {
    if (fd_ >= 0) ::close(fd_);
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the download was cancelled"));
      return;
    }
    Next();
  }
  void OnDone() override { delete this; }

 private:
  absl::Status Open(const v1::DownloadTakeRequest& request) {
    RETURN_IF_ERROR(ValidateTakeId(request.take_id()));
    if (request.chunk_bytes() < 0 || request.chunk_bytes() > kMaxDownloadChunkBytes) {
      return absl::InvalidArgumentError(absl::StrCat("chunk_bytes ", request.chunk_bytes(),
                                                     " is outside 0..", kMaxDownloadChunkBytes));
    }
    chunk_bytes_ = request.chunk_bytes() == 0 ? kDefaultDownloadChunkBytes : request.chunk_bytes();
    generation_ = context_.takes->FileGeneration(take_id_);
    ASSIGN_OR_RETURN(const std::string path, context_.takes->TakeFileForReading(take_id_));
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    struct stat st {};
    if (fd_ < 0 || ::fstat(fd_, &st) != 0) {
      return absl::DataLossError(absl::StrCat("take ", take_id_, ": cannot read its file ", path,
                                              ": ", std::strerror(errno)));
    }
    size_ = static_cast<int64_t>(st.st_size);
    return absl::OkStatus();
  }

  // Writes the next chunk, or finishes at the end of the file.
  void Next() {
    if (offset_ >= size_) {
      Finish(grpc::Status::OK);
      return;
    }
    const int64_t n = std::min<int64_t>(chunk_bytes_, size_ - offset_);
    if (const absl::Status read = ReadAt(fd_, offset_, n, chunk_.mutable_data()); !read.ok()) {
      Finish(
          ToGrpcStatus(absl::DataLossError(absl::StrCat("take ", take_id_, ": ", read.message()))));
      return;
    }
    if (context_.takes->FileGeneration(take_id_) != generation_) {
      Finish(ToGrpcStatus(absl::AbortedError(
          absl::StrCat("take ", take_id_, " was resumed during the download; start again"))));
      return;
    }
    chunk_.set_offset(offset_);
    chunk_.set_total_bytes(size_);
    offset_ += n;
    StartWrite(&chunk_);
  }

  ServerContext& context_;
  const std::string take_id_;
  int fd_ = -1;
  int64_t size_ = 0;
  int64_t offset_ = 0;
  int32_t chunk_bytes_ = kDefaultDownloadChunkBytes;
  uint64_t generation_ = 0;
  v1::TakeFileChunk chunk_;
};

}  // namespace

absl::Status ListTakes(ServerContext& context, const v1::ListTakesRequest& request,
                       v1::ListTakesResponse* response) {
  if (!v1::TakeState_IsValid(request.state())) {
    return absl::InvalidArgumentError(absl::StrCat("unknown take state ", request.state()));
  }
  ASSIGN_OR_RETURN(std::vector<v1::Take> takes, context.takes->ListTakes(request.state()));
  ASSIGN_OR_RETURN(*response->mutable_next_page_token(),
                   Paginate<v1::Take>(
                       std::move(takes), request.page_size(), request.page_token(),
                       [](const v1::Take& t) {
                         return PageKey{t.created_unix_ns(), t.take_id()};
                       },
                       [response](v1::Take&& t) { *response->add_takes() = std::move(t); }));
  return absl::OkStatus();
}

absl::Status GetTake(ServerContext& context, const v1::GetTakeRequest& request,
                     v1::Take* response) {
  RETURN_IF_ERROR(ValidateTakeId(request.take_id()));
  ASSIGN_OR_RETURN(*response, context.takes->GetTake(request.take_id()));
  return absl::OkStatus();
}

absl::Status DeleteTake(ServerContext& context, const v1::DeleteTakeRequest& request,
                        v1::DeleteTakeResponse* response) {
  RETURN_IF_ERROR(ValidateTakeId(request.take_id()));
  const std::string& id = request.take_id();
  const bool derived = !context.keep_derived;
  if (derived && context.jobs != nullptr) RETURN_IF_ERROR(context.jobs->CheckNoUnfinishedJobs(id));
  ASSIGN_OR_RETURN(int64_t freed, context.takes->DeleteTake(id));
  if (!derived) {
    response->set_freed_bytes(freed);
    return absl::OkStatus();
  }
  // The take is gone; what was made from it (images of the person) follows.
  int reenactments = 0;
  if (context.reenactments != nullptr) {
    for (const v1::ReenactmentSummary& r : context.reenactments->List(id)) {
      const std::string& rid = r.info().reenactment_id();
      std::error_code error;
      const auto size = std::filesystem::file_size(context.reenactments->PathFor(rid), error);
      RETURN_IF_ERROR(context.reenactments->Delete(rid));
      if (!error) freed += static_cast<int64_t>(size);
      ++reenactments;
    }
  }
  int jobs = 0;
  if (context.jobs != nullptr) {
    jobs = static_cast<int>(context.jobs->List(v1::JOB_STATE_UNSPECIFIED, id).size());
    ASSIGN_OR_RETURN(const int64_t job_bytes, context.jobs->DeleteJobsOfTake(id));
    freed += job_bytes;
  }
  response->set_freed_bytes(freed);
  response->set_reenactments_deleted(reenactments);
  response->set_jobs_deleted(jobs);
  return absl::OkStatus();
}

grpc::ServerUnaryReactor* TakesService::List(grpc::CallbackServerContext* rpc,
                                             const v1::ListTakesRequest* request,
                                             v1::ListTakesResponse* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Takes/List")) return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(ListTakes(context_, *request, response)));
  return reactor;
}

grpc::ServerUnaryReactor* TakesService::Get(grpc::CallbackServerContext* rpc,
                                            const v1::GetTakeRequest* request, v1::Take* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Takes/Get")) return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(GetTake(context_, *request, response)));
  return reactor;
}

grpc::ServerUnaryReactor* TakesService::Delete(grpc::CallbackServerContext* rpc,
                                               const v1::DeleteTakeRequest* request,
                                               v1::DeleteTakeResponse* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Takes/Delete"))
    return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(DeleteTake(context_, *request, response)));
  return reactor;
}

grpc::ServerWriteReactor<v1::TakeFileChunk>* TakesService::Download(
    grpc::CallbackServerContext* rpc, const v1::DownloadTakeRequest* request) {
  if (auto who = Authorize(context_, *rpc, "/reenact.v1.Takes/Download"); !who.ok()) {
    return new RefusedWriter<v1::TakeFileChunk>(ToGrpcStatus(who.status()));
  }
  return new DownloadStream(context_, *request);
}

}  // namespace reenact::server
