#include "common/metrics/metrics.h"

#include <sys/statvfs.h>
#include <unistd.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

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

const char* TypeName(Type type) { return type == Type::kCounter ? "counter" : "gauge"; }

}  // namespace

void Counter::Increment(double by) {
  if (!(by >= 0)) return;  // Also drops NaN.
  value_.fetch_add(by, std::memory_order_relaxed);
}

void Gauge::Add(double delta) { value_.fetch_add(delta, std::memory_order_relaxed); }

void Snapshot::Add(Type type, std::string_view name, std::string_view help, const Labels& labels,
                   double value) {
  if (!IsMetricName(name) || !AreLabelsValid(labels)) return;
  auto it = families_.find(name);
  if (it == families_.end()) {
    it = families_.emplace(std::string(name), Family{type, std::string(help), {}}).first;
  }
  it->second.samples.emplace_back(labels, value);
}

std::string Snapshot::Expose() const {
  std::string out;
  for (const auto& [name, family] : families_) {
    absl::StrAppend(&out, "# HELP ", name, " ", Escape(family.help, /*quote=*/false), "\n");
    absl::StrAppend(&out, "# TYPE ", name, " ", TypeName(family.type), "\n");
    for (const auto& [labels, value] : family.samples) {
      out += name;
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
    Entry entry{type, std::string(help), nullptr, nullptr};
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

void AddProcessMetrics(Snapshot& out) {
  // statm: size resident shared text lib data dt, in pages.
  std::ifstream statm("/proc/self/statm");
  int64_t size_pages = 0;
  int64_t resident_pages = 0;
  if (statm >> size_pages >> resident_pages) {
    out.AddGauge("process_resident_memory_bytes", "Resident memory size in bytes.", {},
                 static_cast<double>(resident_pages) * static_cast<double>(sysconf(_SC_PAGESIZE)));
    out.AddGauge("process_virtual_memory_bytes", "Virtual memory size in bytes.", {},
                 static_cast<double>(size_pages) * static_cast<double>(sysconf(_SC_PAGESIZE)));
  }
  // The process start: field 22 of /proc/self/stat (clock ticks after boot)
  // plus the boot time of /proc/stat.
  std::ifstream stat_file("/proc/self/stat");
  std::string stat((std::istreambuf_iterator<char>(stat_file)), std::istreambuf_iterator<char>());
  const size_t paren = stat.rfind(')');  // The command name may hold spaces.
  std::ifstream boot_file("/proc/stat");
  int64_t boot_time_s = -1;
  for (std::string line; std::getline(boot_file, line);) {
    if (line.rfind("btime ", 0) == 0) boot_time_s = std::stoll(line.substr(6));
  }
  if (paren != std::string::npos && boot_time_s >= 0) {
    std::istringstream fields(stat.substr(paren + 2));
    std::string field;
    // Fields 3..21 come before starttime (field 22).
    for (int i = 3; i <= 21 && fields >> field; ++i) {
    }
    int64_t start_ticks = 0;
    if (fields >> start_ticks) {
      out.AddGauge(
          "process_start_time_seconds", "Start time of the process since unix epoch in seconds.",
          {},
          static_cast<double>(boot_time_s) +
              static_cast<double>(start_ticks) / static_cast<double>(sysconf(_SC_CLK_TCK)));
    }
  }
}

double FreeDiskBytes(const std::string& path) {
  struct statvfs fs {};
  if (::statvfs(path.c_str(), &fs) != 0) return -1;
  return static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize);
}

}  // namespace reenact::metrics
