#include "server/worker/worker_protocol.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_join.h"
#include "common/base/json_text.h"

namespace reenact::server {
namespace {

// Longest stage name kept.
constexpr size_t kMaxStageChars = 64;

std::string Truncate(std::string text, size_t max_chars) {
  if (text.size() > max_chars) text = text.substr(0, max_chars) + "...";
  return text;
}

// Whether `spec` lists `key` as an option only a live follow reads.
bool IsLiveOnly(const methods::MethodSpec* spec, const std::string& key) {
  if (spec == nullptr) return false;
  for (const methods::OptionSpec& option : spec->options) {
    if (option.name == key) return option.live_only;
  }
  return false;
}

std::string OptionsJson(const std::map<std::string, std::string>& options) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, value] : options) j[key] = value;
  return JsonText(j);
}

}  // namespace

std::map<std::string, std::string> WorkerOptions(
    const methods::MethodSpec* spec,
    const google::protobuf::Map<std::string, std::string>& options) {
  std::map<std::string, std::string> worker;
  for (const auto& [key, value] : options) {
    if (!IsLiveOnly(spec, key)) worker.emplace(key, value);
  }
  return worker;
}

std::vector<std::string> WorkerArgs(const v1::Job& job, const methods::MethodSpec* spec,
                                    const WorkerInvocation& invocation) {
  std::vector<std::string> args = {invocation.worker_path,
                                   "--take",
                                   invocation.take_path,
                                   "--method",
                                   job.method(),
                                   "--options-json",
                                   OptionsJson(WorkerOptions(spec, job.options())),
                                   "--out",
                                   invocation.out_path,
                                   "--reenactment-id",
                                   invocation.reenactment_id,
                                   "--take-id",
                                   job.take_id(),
                                   "--job-id",
                                   job.job_id()};
  if (!invocation.asset_roots.empty()) {
    args.insert(args.end(), {"--assets", absl::StrJoin(invocation.asset_roots, ",")});
  }
  if (!invocation.part.empty()) {
    args.insert(args.end(), {"--part", invocation.part});
    if (invocation.part != "prepare") {
      args.insert(args.end(), {"--segments", std::to_string(job.segments())});
    }
    if (!invocation.input_paths.empty()) {
      args.insert(args.end(), {"--prepared", invocation.input_paths.front()});
    }
    if (invocation.input_paths.size() > 1) {
      args.insert(args.end(),
                  {"--segment-files", absl::StrJoin(invocation.input_paths.begin() + 1,
                                                    invocation.input_paths.end(), ",")});
    }
  }
  if (invocation.memory_limit_mb > 0) {
    args.insert(args.end(), {"--memory-limit-mb", std::to_string(invocation.memory_limit_mb)});
  }
  return args;
}

bool ApplyWorkerLine(const std::string& line, WorkerReport& report,
                     std::vector<std::string>* logs) {
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) {
    report.last_log = Truncate(line, kMaxWorkerLogLineChars);
    logs->push_back(report.last_log);
    return false;
  }
  if (auto it = j.find("log"); it != j.end() && it->is_string()) {
    report.last_log = Truncate(it->get<std::string>(), kMaxWorkerLogLineChars);
    logs->push_back(report.last_log);
  }
  if (auto it = j.find("error"); it != j.end() && it->is_string()) {
    report.error = Truncate(it->get<std::string>(), kMaxWorkerLogLineChars);
    logs->push_back("error: " + report.error);
  }
  if (auto it = j.find("result"); it != j.end()) {
    logs->push_back(Truncate("result: " + it->dump(), kMaxWorkerLogLineChars));
    if (it->is_object()) {
      const auto count = [&](const char* key) -> int64_t {
        const auto v = it->find(key);
        return v != it->end() && v->is_number_integer() ? v->get<int64_t>() : 0;
      };
      report.result_frames = count("frames");
      report.result_keyframes = count("keyframes");
      if (const auto figures = it->find("figures"); figures != it->end() && figures->is_object()) {
        for (const auto& [name, value] : figures->items()) {
          if (value.is_number() && report.result_figures.size() < 64) {
            report.result_figures[name.substr(0, 64)] = value.get<double>();
          }
        }
      }
    }
  }
  v1::JobProgress& p = report.progress;
  bool progress = false;
  if (auto it = j.find("stage"); it != j.end() && it->is_string()) {
    p.set_stage(Truncate(it->get<std::string>(), kMaxStageChars));
    progress = true;
  }
  if (auto it = j.find("fraction"); it != j.end() && it->is_number()) {
    const double f = it->get<double>();
    if (std::isfinite(f)) p.set_fraction(std::clamp(f, 0.0, 1.0));
    progress = true;
  }
  if (auto it = j.find("frames_done"); it != j.end() && it->is_number_integer()) {
    p.set_frames_done(it->get<int64_t>());
  }
  if (auto it = j.find("frames_total"); it != j.end() && it->is_number_integer()) {
    p.set_frames_total(it->get<int64_t>());
  }
  return progress;
}

bool ApplyWorkerLines(std::string& pending, WorkerReport& report, std::vector<std::string>* logs) {
  bool changed = false;
  size_t start = 0;
  while (true) {
    size_t end = pending.find('\n', start);
    if (end == std::string::npos) {
      if (pending.size() - start < kMaxPendingBytes) break;
      end = pending.size();
    }
    std::string line = pending.substr(start, end - start);
    start = std::min(end + 1, pending.size());
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && ApplyWorkerLine(line, report, logs)) changed = true;
  }
  pending.erase(0, start);
  return changed;
}

WorkerOutputReader::WorkerOutputReader(std::string path, v1::JobProgress progress)
    : path_(std::move(path)) {
  report_.progress = std::move(progress);
}

bool WorkerOutputReader::Read(std::vector<std::string>* logs) {
  std::ifstream in(path_, std::ios::binary);
  if (!in) return false;
  in.seekg(offset_);
  std::string fresh((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  offset_ += static_cast<int64_t>(fresh.size());
  pending_ += fresh;
  return ApplyWorkerLines(pending_, report_, logs);
}

std::string LastLogLine(std::string tail, const std::string& last_log) {
  while (!tail.empty() && (tail.back() == '\n' || tail.back() == '\r' || tail.back() == ' ')) {
    tail.pop_back();
  }
  if (const size_t nl = tail.rfind('\n'); nl != std::string::npos) tail = tail.substr(nl + 1);
  if (tail.empty()) tail = last_log;
  if (tail.empty()) return "(none)";
  return Truncate(tail, kMaxQuotedLogChars);
}

std::string LastWorkerLog(const std::string& log_path, int64_t attempt_offset,
                          const std::string& last_log) {
  std::ifstream in(log_path, std::ios::binary);
  std::string tail;
  if (in) {
    in.seekg(0, std::ios::end);
    const int64_t size = static_cast<int64_t>(in.tellg());
    const int64_t from = std::max(attempt_offset, size - kLogTailBytes);
    if (size > from) {
      in.seekg(from);
      tail.resize(static_cast<size_t>(size - from));
      in.read(tail.data(), static_cast<std::streamsize>(tail.size()));
    }
  }
  return LastLogLine(std::move(tail), last_log);
}

}  // namespace reenact::server
