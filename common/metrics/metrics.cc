#include "common/metrics/metrics.h"

#include <sys/resource.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace reenact::metrics {
namespace {

bool IsMetricName(std::string_view name) {
  if (name.empty()) return false;
  for (size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    const bool letter = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':';
    if (!letter && !(i > 0 && c >= '0' && c <= '9')) return false;
  }
  return true;
}

bool IsLabelName(std::string_view name) {
  if (name.empty() || name.substr(0, 2) == "__") return false;  // "__" is Prometheus'.
  for (size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    const bool letter = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
    if (!letter && !(i > 0 && c >= '0' && c <= '9')) return false;
  }
  return true;
}

bool AreLabelsValid(const Labels& labels) {
  for (const auto& [name, value] : labels) {
    if (!IsLabelName(name)) return false;
  }
  return true;
}

// HELP text escapes backslash and newline; label values also the double
// quote (the exposition format's two escaping rules).
std::string Escape(std::string_view text, bool quote) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (quote && c == '"') {
      out += "\\\"";
    } else {
      out.push_back(c);
    }
  }
  return out;
}

// Integers as integers (byte counts stay exact and readable), other values
// in the shortest form that reads back the same; the format's spellings of
// the non-finite values.
std::string FormatValue(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  if (value == std::floor(value) && std::fabs(value) < 9.007199254740992e15) {
    return absl::StrCat(static_cast<int64_t>(value));
  }
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

const char* TypeName(Type type) {
  switch (type) {
    case Type::kCounter:
      return "counter";
    case Type::kHistogram:
      return "histogram";
    case Type::kGauge:
      break;
  }
  return "gauge";
}

std::vector<double> IncreasingFinite(const std::vector<double>& bounds) {
  std::vector<double> out;
  for (const double bound : bounds) {
    if (std::isfinite(bound) && (out.empty() || bound > out.back())) out.push_back(bound);
  }
  return out;
}

}  // namespace

void Counter::Increment(double by) {
  if (!(by >= 0)) return;  // Also drops NaN.
  value_.fetch_add(by, std::memory_order_relaxed);
}

void Gauge::Add(double delta) { value_.fetch_add(delta, std::memory_order_relaxed); }

Histogram::Histogram(const std::vector<double>& upper_bounds)
    : upper_bounds_(IncreasingFinite(upper_bounds)),
      buckets_(std::make_unique<std::atomic<uint64_t>[]>(upper_bounds_.size() + 1)) {}

void Histogram::Observe(double value) {
  if (std::isnan(value)) return;
  const size_t bucket = static_cast<size_t>(
      std::lower_bound(upper_bounds_.begin(), upper_bounds_.end(), value) - upper_bounds_.begin());
  buckets_[bucket].fetch_add(1, std::memory_order_relaxed);
  sum_.fetch_add(value, std::memory_order_relaxed);
}

Histogram::Counts Histogram::Read() const {
  Counts counts;
  counts.upper_bounds = upper_bounds_;
  uint64_t total = 0;
  for (size_t i = 0; i <= upper_bounds_.size(); ++i) {
    total += buckets_[i].load(std::memory_order_relaxed);
    counts.cumulative.push_back(total);
  }
  counts.sum = sum_.load(std::memory_order_relaxed);
  return counts;
}

const std::vector<double>& RequestSecondsBounds() {
  static const auto* const bounds = new std::vector<double>{
      0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60};
  return *bounds;
}

const std::vector<double>& JobSecondsBounds() {
  static const auto* const bounds =
      new std::vector<double>{1, 5, 10, 30, 60, 120, 300, 600, 1200, 1800, 3600, 7200, 14400};
  return *bounds;
}

Snapshot::Family* Snapshot::FamilyFor(Type type, std::string_view name, std::string_view help,
                                      const Labels& labels) {
  if (!IsMetricName(name) || !AreLabelsValid(labels)) return nullptr;
  auto it = families_.find(name);
  if (it == families_.end()) {
    it = families_.emplace(std::string(name), Family{type, std::string(help), {}}).first;
  }
  return &it->second;
}

void Snapshot::Add(Type type, std::string_view name, std::string_view help, const Labels& labels,
                   double value) {
  if (Family* family = FamilyFor(type, name, help, labels)) {
    family->samples.push_back({"", labels, value});
  }
}

void Snapshot::AddHistogram(std::string_view name, std::string_view help, const Labels& labels,
                            const Histogram::Counts& counts) {
  Family* family = FamilyFor(Type::kHistogram, name, help, labels);
  if (family == nullptr || family->type != Type::kHistogram || counts.cumulative.empty()) return;
  for (size_t i = 0; i < counts.cumulative.size(); ++i) {
    Labels with_bound = labels;
    with_bound.emplace_back(
        "le", i < counts.upper_bounds.size() ? FormatValue(counts.upper_bounds[i]) : "+Inf");
    family->samples.push_back(
        {"_bucket", std::move(with_bound), static_cast<double>(counts.cumulative[i])});
  }
  family->samples.push_back({"_sum", labels, counts.sum});
  family->samples.push_back({"_count", labels, static_cast<double>(counts.cumulative.back())});
}

std::string Snapshot::Expose() const {
  std::string out;
  for (const auto& [name, family] : families_) {
    absl::StrAppend(&out, "# HELP ", name, " ", Escape(family.help, /*quote=*/false), "\n");
    absl::StrAppend(&out, "# TYPE ", name, " ", TypeName(family.type), "\n");
    for (const auto& [suffix, labels, value] : family.samples) {
      absl::StrAppend(&out, name, suffix);
      if (!labels.empty()) {
        out.push_back('{');
        for (size_t i = 0; i < labels.size(); ++i) {
          absl::StrAppend(&out, i > 0 ? "," : "", labels[i].first, "=\"",
                          Escape(labels[i].second, /*quote=*/true), "\"");
        }
        out.push_back('}');
      }
      absl::StrAppend(&out, " ", FormatValue(value), "\n");
    }
  }
  return out;
}

Registry::Entry& Registry::GetLocked(Type type, std::string_view name, std::string_view help,
                                     const Labels& labels) {
  Key key{std::string(name), labels};
  auto it = entries_.find(key);
  if (it == entries_.end()) {
    Entry entry{type, std::string(help), nullptr, nullptr, nullptr};
    // Both kinds exist for every entry, so that a name asked for as both
    // still hands out a live object; only the first kind is exposed.
    entry.counter = std::make_unique<Counter>();
    entry.gauge = std::make_unique<Gauge>();
    it = entries_.emplace(std::move(key), std::move(entry)).first;
  }
  return it->second;
}

Counter& Registry::GetCounter(std::string_view name, std::string_view help, const Labels& labels) {
  std::lock_guard<std::mutex> lock(mu_);
  return *GetLocked(Type::kCounter, name, help, labels).counter;
}

Gauge& Registry::GetGauge(std::string_view name, std::string_view help, const Labels& labels) {
  std::lock_guard<std::mutex> lock(mu_);
  return *GetLocked(Type::kGauge, name, help, labels).gauge;
}

Histogram& Registry::GetHistogram(std::string_view name, std::string_view help,
                                  const Labels& labels, const std::vector<double>& upper_bounds) {
  std::lock_guard<std::mutex> lock(mu_);
  Entry& entry = GetLocked(Type::kHistogram, name, help, labels);
  if (entry.histogram == nullptr) entry.histogram = std::make_unique<Histogram>(upper_bounds);
  return *entry.histogram;
}

int Registry::AddCollector(std::function<void(Snapshot&)> collect) {
  std::lock_guard<std::mutex> lock(collectors_mu_);
  const int id = next_collector_id_++;
  collectors_.emplace(id, std::move(collect));
  return id;
}

void Registry::RemoveCollector(int id) {
  std::lock_guard<std::mutex> lock(collectors_mu_);
  collectors_.erase(id);
}

void Registry::CollectInto(Snapshot& out) const {
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [key, entry] : entries_) {
      if (entry.type == Type::kHistogram) {
        if (entry.histogram != nullptr) {
          out.AddHistogram(key.name, entry.help, key.labels, entry.histogram->Read());
        }
        continue;
      }
      const double value =
          entry.type == Type::kCounter ? entry.counter->value() : entry.gauge->value();
      out.Add(entry.type, key.name, entry.help, key.labels, value);
    }
  }
  std::lock_guard<std::mutex> lock(collectors_mu_);
  for (const auto& [id, collect] : collectors_) collect(out);
}

std::string Registry::Expose() const {
  Snapshot snapshot;
  CollectInto(snapshot);
  return snapshot.Expose();
}

Registry& DefaultRegistry() {
  static auto* const registry = new Registry;
  return *registry;
}

namespace {

// Fields 3.. of /proc/self/stat (after the command name, which may hold
// spaces and parentheses); empty when it cannot be read.
std::vector<std::string> SelfStatFields() {
  std::ifstream stat_file("/proc/self/stat");
  const std::string stat((std::istreambuf_iterator<char>(stat_file)),
                         std::istreambuf_iterator<char>());
  const size_t paren = stat.rfind(')');
  std::vector<std::string> fields;
  if (paren == std::string::npos) return fields;
  std::istringstream in(stat.substr(paren + 1));
  for (std::string field; in >> field;) fields.push_back(field);
  return fields;
}

int64_t BootTimeSeconds() {
  std::ifstream boot_file("/proc/stat");
  for (std::string line; std::getline(boot_file, line);) {
    int64_t seconds = -1;
    if (line.rfind("btime ", 0) == 0 && absl::SimpleAtoi(line.substr(6), &seconds)) {
      return seconds;
    }
  }
  return -1;
}

void AddMemory(Snapshot& out) {
  // statm: size resident shared text lib data dt, in pages.
  std::ifstream statm("/proc/self/statm");
  int64_t size_pages = 0;
  int64_t resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return;
  const double page_bytes = static_cast<double>(sysconf(_SC_PAGESIZE));
  out.AddGauge("process_resident_memory_bytes", "Resident memory size in bytes.", {},
               static_cast<double>(resident_pages) * page_bytes);
  out.AddGauge("process_virtual_memory_bytes", "Virtual memory size in bytes.", {},
               static_cast<double>(size_pages) * page_bytes);
}

void AddTimes(Snapshot& out) {
  // Field n of proc(5) is fields[n - 3]: utime 14, stime 15, starttime 22,
  // in clock ticks.
  const std::vector<std::string> fields = SelfStatFields();
  const double tick_s = 1.0 / static_cast<double>(sysconf(_SC_CLK_TCK));
  int64_t user_ticks = 0;
  int64_t system_ticks = 0;
  if (fields.size() > 12 && absl::SimpleAtoi(fields[11], &user_ticks) &&
      absl::SimpleAtoi(fields[12], &system_ticks)) {
    out.AddCounter("process_cpu_seconds_total", "Total user and system CPU time spent in seconds.",
                   {}, static_cast<double>(user_ticks + system_ticks) * tick_s);
  }
  const int64_t boot_time_s = BootTimeSeconds();
  int64_t start_ticks = 0;
  if (fields.size() > 19 && boot_time_s >= 0 && absl::SimpleAtoi(fields[19], &start_ticks)) {
    out.AddGauge("process_start_time_seconds",
                 "Start time of the process since unix epoch in seconds.", {},
                 static_cast<double>(boot_time_s) + static_cast<double>(start_ticks) * tick_s);
  }
}

void AddDescriptors(Snapshot& out) {
  std::error_code error;
  int64_t open = 0;
  for (std::filesystem::directory_iterator it("/proc/self/fd", error), end; !error && it != end;
       it.increment(error)) {
    ++open;
  }
  // The iterator's own descriptor is counted too, as Prometheus' clients do.
  if (!error) out.AddGauge("process_open_fds", "Number of open file descriptors.", {}, open);
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) == 0) {
    out.AddGauge("process_max_fds", "Maximum number of open file descriptors.", {},
                 limit.rlim_cur == RLIM_INFINITY ? HUGE_VAL : static_cast<double>(limit.rlim_cur));
  }
}

}  // namespace

void AddProcessMetrics(Snapshot& out) {
  AddMemory(out);
  AddTimes(out);
  AddDescriptors(out);
  out.AddGauge("reenact_build_info", "Always 1; the version label names the build.",
               {{"version", REENACT_VERSION}}, 1);
}

double FreeDiskBytes(const std::string& path) {
  struct statvfs fs {};
  if (::statvfs(path.c_str(), &fs) != 0) return -1;
  return static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize);
}

}  // namespace reenact::metrics
