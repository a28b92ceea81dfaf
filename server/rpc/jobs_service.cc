#include "server/rpc/jobs_service.h"

#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/proto_convert.h"
#include "proto/grpc_status.h"
#include "proto/write_pump.h"
#include "server/jobs/job_scheduler.h"
#include "server/rpc/pagination.h"
#include "server/rpc/rpc_auth.h"

namespace reenact::server {
namespace {

// One Watch stream: events from the scheduler are merged into one pending
// event (the latest job, every log line) and written one at a time.
class WatchStream final : public PumpedWriteReactor<v1::JobEvent> {
 public:
  WatchStream(ServerContext& context, const v1::WatchJobRequest& request)
      : PumpedWriteReactor("the watch"), context_(context) {
    const absl::StatusOr<uint64_t> id = context_.jobs->Watch(
        request.job_id(), [this](const v1::JobEvent& event, bool last, const absl::Status& end) {
          OnEvent(event, last, end);
        });
    if (!id.ok()) {
      FinishNow(ToGrpcStatus(id.status()));
      return;
    }
    std::lock_guard<std::mutex> lock(mutex());
    watch_id_ = *id;
  }

  void OnDone() override {
    uint64_t watch_id = 0;
    {
      std::lock_guard<std::mutex> lock(mutex());
      watch_id = watch_id_;
    }
    // After Unwatch no event comes any more.
    if (watch_id != 0) context_.jobs->Unwatch(watch_id);
    delete this;
  }

 private:
  void OnEvent(const v1::JobEvent& event, bool last, const absl::Status& end) {
    {
      std::lock_guard<std::mutex> lock(mutex());
      if (pending_.has_value()) {
        *pending_->mutable_job() = event.job();
        for (const std::string& line : event.log_lines()) pending_->add_log_lines(line);
      } else {
        pending_ = event;
      }
      if (last) {
        MarkEndedLocked();
        end_ = end;
      }
    }
    Pump();
  }

  bool TakeNextLocked(v1::JobEvent* next) override {
    if (!pending_.has_value()) return false;
    *next = std::move(*pending_);
    pending_.reset();
    return true;
  }
  grpc::Status EndStatusLocked() override { return ToGrpcStatus(end_); }

  ServerContext& context_;
  uint64_t watch_id_ = 0;
  std::optional<v1::JobEvent> pending_;
  absl::Status end_;
};

}  // namespace

absl::Status SubmitJob(ServerContext& context, const v1::SubmitJobRequest& request,
                       const std::string& submitter, v1::Job* response) {
  ASSIGN_OR_RETURN(*response, context.jobs->Submit(request, submitter));
  return absl::OkStatus();
}

absl::Status ListJobs(ServerContext& context, const v1::ListJobsRequest& request,
                      v1::ListJobsResponse* response) {
  if (!v1::JobState_IsValid(request.state())) {
    return absl::InvalidArgumentError(absl::StrCat("unknown job state ", request.state()));
  }
  ASSIGN_OR_RETURN(*response->mutable_next_page_token(),
                   Paginate<v1::Job>(
                       context.jobs->List(request.state(), request.take_id()), request.page_size(),
                       request.page_token(),
                       [](const v1::Job& j) {
                         return PageKey{j.submitted_unix_ns(), j.job_id()};
                       },
                       [response](v1::Job&& j) { *response->add_jobs() = std::move(j); }));
  return absl::OkStatus();
}

absl::Status GetJob(ServerContext& context, const v1::GetJobRequest& request, v1::Job* response) {
  ASSIGN_OR_RETURN(*response, context.jobs->Get(request.job_id()));
  return absl::OkStatus();
}

v1::ListMethodsResponse ListMethods(const std::vector<methods::MethodSpec>& specs) {
  v1::ListMethodsResponse response;
  for (const methods::MethodSpec& spec : specs) {
    v1::MethodDescription& method = *response.add_methods();
    method.set_name(spec.name);
    method.set_summary(spec.summary);
    method.set_thesis(spec.thesis);
    method.set_live(spec.live);
    method.set_segmentable(spec.segmentable);
    method.set_texture_mode(ToProto(spec.texture));
    for (const methods::OptionSpec& option : spec.options) {
      v1::MethodOption& out = *method.add_options();
      out.set_name(option.name);
      out.set_type(methods::OptionTypeName(option.type));
      out.set_default_value(option.default_value);
      out.set_has_bounds(option.has_bounds);
      out.set_min(option.min);
      out.set_max(option.max);
      out.set_doc(option.doc);
      out.set_common(option.common);
      out.set_live_only(option.live_only);
    }
  }
  return response;
}

grpc::ServerUnaryReactor* JobsService::Submit(grpc::CallbackServerContext* rpc,
                                              const v1::SubmitJobRequest* request,
                                              v1::Job* response) {
  const absl::StatusOr<rpc::Principal> who = Authorize(context_, *rpc, "/reenact.v1.Jobs/Submit");
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  if (!who.ok()) {
    reactor->Finish(ToGrpcStatus(who.status()));
    return reactor;
  }
  // Storing the job commits (fsync) to the catalog: off gRPC's threads.
  context_.blocking->Schedule([this, reactor, request, response, submitter = who->name] {
    reactor->Finish(ToGrpcStatus(SubmitJob(context_, *request, submitter, response)));
  });
  return reactor;
}

grpc::ServerWriteReactor<v1::JobEvent>* JobsService::Watch(grpc::CallbackServerContext* rpc,
                                                           const v1::WatchJobRequest* request) {
  if (auto who = Authorize(context_, *rpc, "/reenact.v1.Jobs/Watch"); !who.ok()) {
    return new RefusedWriter<v1::JobEvent>(ToGrpcStatus(who.status()));
  }
  return new WatchStream(context_, *request);
}

grpc::ServerUnaryReactor* JobsService::Cancel(grpc::CallbackServerContext* rpc,
                                              const v1::CancelJobRequest* request,
                                              v1::Job* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Jobs/Cancel")) return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  context_.blocking->Schedule([this, reactor, request, response] {
    const absl::StatusOr<v1::Job> job = context_.jobs->Cancel(request->job_id());
    if (!job.ok() || job->state() != v1::JOB_STATE_RUNNING) {
      if (job.ok()) *response = *job;
      reactor->Finish(ToGrpcStatus(job.status()));
      return;
    }
    // Answer when the worker has stopped: the watch's last event. The call
    // (and `response`) live until Finish, even when the client has gone.
    const absl::StatusOr<uint64_t> watch = context_.jobs->Watch(
        request->job_id(),
        [reactor, response](const v1::JobEvent& event, bool last, const absl::Status& end) {
          if (!last) return;
          *response = event.job();
          reactor->Finish(ToGrpcStatus(end));
        });
    if (!watch.ok()) reactor->Finish(ToGrpcStatus(watch.status()));
  });
  return reactor;
}

grpc::ServerUnaryReactor* JobsService::List(grpc::CallbackServerContext* rpc,
                                            const v1::ListJobsRequest* request,
                                            v1::ListJobsResponse* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Jobs/List")) return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(ListJobs(context_, *request, response)));
  return reactor;
}

grpc::ServerUnaryReactor* JobsService::ListMethods(grpc::CallbackServerContext* rpc,
                                                   const v1::ListMethodsRequest* /*request*/,
                                                   v1::ListMethodsResponse* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Jobs/ListMethods")) {
    return refused;
  }
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  *response = server::ListMethods(context_.jobs->methods());
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* JobsService::Get(grpc::CallbackServerContext* rpc,
                                           const v1::GetJobRequest* request, v1::Job* response) {
  if (auto* refused = RefuseUnlessAllowed(context_, rpc, "/reenact.v1.Jobs/Get")) return refused;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(GetJob(context_, *request, response)));
  return reactor;
}

}  // namespace reenact::server
