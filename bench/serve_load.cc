// serve_load: reenact-server under load, a benchmark command (not a Google
// Benchmark). It starts the real reenact-server on loopback, stores one take
// for the viewers, then for --seconds (default 60) runs
//   --daemons D (2) ingest streams, each a take of one sensor at --fps (30),
//   --viewers V (20) clients in a loop of Takes.List, Takes.Download of the
//     stored take, and Reenactments.List,
// and reports per operation the calls, errors and latency (p50, p95, p99,
// max), the frame sets the daemons had acknowledged, and the server's peak
// resident memory (VmHWM) and CPU time.
//
//   build/bench/serve_load [--seconds 60] [--viewers 20] [--daemons 2]
//                          [--fps 30] [--json FILE]
#include <sys/types.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "bench/e2e_util.h"
#include "common/base/flags.h"
#include "common/base/subprocess.h"
#include "common/base/time.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "server/testing/test_takes.h"

namespace reenact::bench {
namespace {

namespace fs = std::filesystem;
using server::testing::MakeFrameSet;
using server::testing::MakeOpenTake;

// Latencies of one kind of call, in milliseconds, and its errors.
struct OpStats {
  std::mutex mu;
  std::vector<double> ms;
  int64_t errors = 0;
  std::string first_error;

  void Add(double value_ms, const grpc::Status& status) {
    std::lock_guard<std::mutex> lock(mu);
    if (status.ok()) {
      ms.push_back(value_ms);
    } else {
      ++errors;
      if (first_error.empty()) {
        first_error = absl::StrFormat("%d %s", status.error_code(), status.error_message());
      }
    }
  }
  nlohmann::json Report() {
    std::lock_guard<std::mutex> lock(mu);
    std::sort(ms.begin(), ms.end());
    auto at = [&](double q) {
      return ms.empty() ? 0.0 : ms[std::min(ms.size() - 1, static_cast<size_t>(q * ms.size()))];
    };
    return {{"calls", static_cast<int64_t>(ms.size()) + errors},
            {"errors", errors},
            {"p50_ms", at(0.5)},
            {"p95_ms", at(0.95)},
            {"p99_ms", at(0.99)},
            {"max_ms", ms.empty() ? 0.0 : ms.back()},
            {"first_error", first_error}};
  }
};

double MsSince(int64_t start_ns) { return (SteadyNowNs() - start_ns) / 1e6; }

int64_t PeakRssKb(pid_t pid) {
  const std::string status = ReadText(absl::StrFormat("/proc/%d/status", pid));
  const size_t at = status.find("VmHWM:");
  if (at == std::string::npos) return 0;
  return std::atoll(status.c_str() + at + 6);
}

// One daemon: a take of one sensor, a frame set every 1/fps until `stop`.
void Daemon(std::shared_ptr<grpc::Channel> channel, int index, double fps,
            const std::atomic<bool>& stop, std::atomic<int64_t>& acked, OpStats& errors) {
  auto stub = v1::Ingest::NewStub(channel);
  grpc::ClientContext context;
  auto stream = stub->Ingest(&context);
  v1::IngestRequest open;
  *open.mutable_open() = MakeOpenTake(absl::StrFormat("load-%d", index), "daemon-load", 1);
  stream->Write(open);
  std::thread reader([&] {
    v1::IngestResponse response;
    while (stream->Read(&response)) {
      if (response.has_ack()) {
        acked.fetch_add(1);  // One per durable batch.
      }
    }
  });
  const int64_t period_ns = static_cast<int64_t>(1e9 / fps);
  int64_t next_ns = SteadyNowNs();
  uint64_t sequence = 0;
  while (!stop) {
    v1::IngestRequest request;
    *request.mutable_frame_set() = MakeFrameSet(++sequence, {"k0"});
    if (!stream->Write(request)) break;
    next_ns += period_ns;
    std::this_thread::sleep_for(
        std::chrono::nanoseconds(std::max<int64_t>(0, next_ns - SteadyNowNs())));
  }
  v1::IngestRequest close;
  close.mutable_close()->set_last_sequence(sequence);
  close.mutable_close()->set_reason("benchmark over");
  stream->Write(close);
  stream->WritesDone();
  reader.join();
  errors.Add(0, stream->Finish());
}

void Viewer(std::shared_ptr<grpc::Channel> channel, const std::atomic<bool>& stop, OpStats& list,
            OpStats& download, OpStats& reenactments, std::atomic<int64_t>& downloaded_bytes) {
  auto takes = v1::Takes::NewStub(channel);
  auto reen = v1::Reenactments::NewStub(channel);
  while (!stop) {
    {
      grpc::ClientContext context;
      v1::ListTakesRequest request;
      v1::ListTakesResponse response;
      const int64_t start = SteadyNowNs();
      const grpc::Status status = takes->List(&context, request, &response);
      list.Add(MsSince(start), status);
    }
    {
      grpc::ClientContext context;
      v1::DownloadTakeRequest request;
      request.set_take_id("stored");
      const int64_t start = SteadyNowNs();
      auto reader = takes->Download(&context, request);
      v1::TakeFileChunk chunk;
      while (reader->Read(&chunk))
        downloaded_bytes.fetch_add(static_cast<int64_t>(chunk.data().size()));
      download.Add(MsSince(start), reader->Finish());
    }
    {
      grpc::ClientContext context;
      v1::ListReenactmentsRequest request;
      v1::ListReenactmentsResponse response;
      const int64_t start = SteadyNowNs();
      reenactments.Add(MsSince(start), reen->List(&context, request, &response));
    }
  }
}

int Run(int argc, char** argv) {
  auto flags = Flags::Parse(std::vector<std::string>(argv + 1, argv + argc),
                            {"seconds", "viewers", "daemons", "fps", "json", "work"}, {});
  if (!flags.ok()) {
    std::cerr << "serve_load: " << flags.status().message() << "\n";
    return 2;
  }
  const double seconds = *flags->GetDouble("seconds", 60);
  const int viewers = *flags->GetInt("viewers", 20);
  const int daemons = *flags->GetInt("daemons", 2);
  const double fps = *flags->GetDouble("fps", 30);
  const std::string bin =
      (fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "bin").string();
  const std::string work = flags->GetOr("work", "/tmp/reenact_serve_load");
  fs::remove_all(work);
  fs::create_directories(work);

  SubprocessOptions server_options;
  server_options.stderr_path = work + "/server.log";
  auto server =
      Subprocess::Start({bin + "/reenact-server", "--data", work + "/data", "--listen",
                         "127.0.0.1:0", "--port-file", work + "/server.port", "--jobs", "1"},
                        server_options);
  if (!server.ok()) {
    std::cerr << "serve_load: " << server.status().message() << "\n";
    return 1;
  }
  std::string address;
  for (int i = 0; i < 200 && address.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string text = ReadText(work + "/server.port");
    if (text.find('\n') != std::string::npos) address = text.substr(0, text.find('\n'));
  }
  if (address.empty()) {
    std::cerr << "serve_load: reenact-server did not start; see " << work << "/server.log\n";
    return 1;
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  // Each client its own connection, as separate devices would have.
  auto channel = [&](int i) {
    grpc::ChannelArguments a = args;
    a.SetInt("reenact.client", i);  // Distinct arguments: no shared subchannel.
    return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), a);
  };

  // The take the viewers download: 300 frame sets (10 s) of one sensor.
  {
    auto stub = v1::Ingest::NewStub(channel(-1));
    grpc::ClientContext context;
    auto stream = stub->Ingest(&context);
    v1::IngestRequest open;
    *open.mutable_open() = MakeOpenTake("stored", "daemon-seed", 1);
    stream->Write(open);
    for (uint64_t s = 1; s <= 300; ++s) {
      v1::IngestRequest request;
      *request.mutable_frame_set() = MakeFrameSet(s, {"k0"});
      stream->Write(request);
    }
    v1::IngestRequest close;
    close.mutable_close()->set_last_sequence(300);
    stream->Write(close);
    stream->WritesDone();
    v1::IngestResponse response;
    while (stream->Read(&response)) {
    }
    if (const grpc::Status status = stream->Finish(); !status.ok()) {
      std::cerr << "serve_load: storing the viewers' take failed: " << status.error_message()
                << "\n";
      return 1;
    }
  }
  const int64_t stored_bytes =
      static_cast<int64_t>(fs::file_size(work + "/data/takes/stored.mcap"));

  std::atomic<bool> stop{false};
  std::atomic<int64_t> acks{0}, downloaded{0};
  OpStats list, download, reenactments, ingest;
  const double cpu_before = ProcessCpuSeconds((*server)->pid());
  const int64_t start_ns = SteadyNowNs();
  std::vector<std::thread> threads;
  for (int d = 0; d < daemons; ++d) {
    threads.emplace_back(Daemon, channel(d), d, fps, std::cref(stop), std::ref(acks),
                         std::ref(ingest));
  }
  for (int v = 0; v < viewers; ++v) {
    threads.emplace_back(Viewer, channel(1000 + v), std::cref(stop), std::ref(list),
                         std::ref(download), std::ref(reenactments), std::ref(downloaded));
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  for (std::thread& t : threads) t.join();
  const double elapsed_s = (SteadyNowNs() - start_ns) / 1e9;
  const double cpu_s = ProcessCpuSeconds((*server)->pid()) - cpu_before;
  const int64_t peak_rss_kb = PeakRssKb((*server)->pid());

  // What the daemons' takes hold, as the server says.
  int64_t frame_sets_stored = 0;
  {
    auto takes = v1::Takes::NewStub(channel(-2));
    grpc::ClientContext context;
    v1::ListTakesResponse response;
    if (takes->List(&context, v1::ListTakesRequest(), &response).ok()) {
      for (const v1::Take& take : response.takes()) {
        if (take.take_id() != "stored")
          frame_sets_stored += static_cast<int64_t>(take.durable_sequence());
      }
    }
  }
  (*server)->Signal(SIGTERM).IgnoreError();
  (*server)->Wait(30).IgnoreError();

  nlohmann::json report = {
      {"seconds", elapsed_s},
      {"viewers", viewers},
      {"daemons", daemons},
      {"fps", fps},
      {"stored_take_bytes", stored_bytes},
      {"takes_list", list.Report()},
      {"takes_download", download.Report()},
      {"reenactments_list", reenactments.Report()},
      {"ingest_stream_errors", ingest.Report()["errors"]},
      {"ingest_acks", acks.load()},
      {"ingest_frame_sets_stored", frame_sets_stored},
      {"ingest_frame_sets_expected", static_cast<int64_t>(daemons * fps * elapsed_s)},
      {"download_mb_per_s", downloaded.load() / elapsed_s / 1e6},
      {"server_peak_rss_mb", peak_rss_kb / 1024.0},
      {"server_cpu_s", cpu_s},
  };
  std::cout << report.dump(2) << "\n";
  if (const auto json = flags->Get("json")) std::ofstream(*json) << report.dump(2) << "\n";
  const int64_t errors = report["takes_list"]["errors"].get<int64_t>() +
                         report["takes_download"]["errors"].get<int64_t>() +
                         report["reenactments_list"]["errors"].get<int64_t>() +
                         report["ingest_stream_errors"].get<int64_t>();
  return errors == 0 ? 0 : 1;
}

}  // namespace
}  // namespace reenact::bench

int main(int argc, char** argv) { return reenact::bench::Run(argc, argv); }
