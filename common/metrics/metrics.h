// Counters, gauges and histograms of a Reenact process, in the Prometheus text
// exposition format (version 0.0.4) that common/metrics/http_exposer.h
// serves on --metrics HOST:PORT.
//
// Two kinds of figures:
//   - events counted where they happen (frame sets ingested, refusals):
//     DefaultRegistry().GetCounter(name, help, labels).Increment(); the
//     returned reference lives as long as the registry, so hot paths look a
//     counter up once and keep it;
//   - durations (an RPC, a job): GetHistogram(name, help, labels, bounds)
//     .Observe(seconds), exposed as cumulative buckets, sum and count;
//   - states read at scrape time (jobs by state, disk free, a daemon's
//     sensors): a collector function adds them to the Snapshot being built,
//     so they are never stale and cost nothing between scrapes.
//
// Names follow Prometheus' rules ([a-zA-Z_:][a-zA-Z0-9_:]*, labels
// [a-zA-Z_][a-zA-Z0-9_]*); counters end in _total. A sample with a bad
// name is a programming error; it is left out of the exposition rather than
// make the whole text unparseable for the scraper.
//
// Thread-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace reenact::metrics {

// Label name -> value, in the order written.
using Labels = std::vector<std::pair<std::string, std::string>>;

enum class Type { kCounter, kGauge, kHistogram };

class Counter {
 public:
  // `by` must not be negative (counters only go up).
  void Increment(double by = 1.0);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0.0};
};

class Gauge {
 public:
  void Set(double value) { value_.store(value, std::memory_order_relaxed); }
  void Add(double delta);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0.0};
};

// Observations counted in buckets by upper bound (Prometheus' histogram:
// bucket i counts the values <= bounds[i]; one more bucket, +Inf, counts
// all), with their sum. Observe is lock-free.
class Histogram {
 public:
  // `upper_bounds`: finite, strictly increasing (others are dropped).
  explicit Histogram(const std::vector<double>& upper_bounds);

  // NaN is dropped.
  void Observe(double value);

  struct Counts {
    std::vector<double> upper_bounds;
    // Per bound, the observations <= it; then the total (le="+Inf").
    std::vector<uint64_t> cumulative;
    double sum = 0.0;
  };
  Counts Read() const;

 private:
  const std::vector<double> upper_bounds_;
  // Per bound and one past the last: the observations in that bucket alone.
  std::unique_ptr<std::atomic<uint64_t>[]> buckets_;
  std::atomic<double> sum_{0.0};
};

// Bucket bounds in seconds for request latencies (1 ms .. 60 s) and for job
// durations (1 s .. 4 h).
const std::vector<double>& RequestSecondsBounds();
const std::vector<double>& JobSecondsBounds();

// The samples of one scrape, grouped by family.
class Snapshot {
 public:
  // Adds one sample; a second sample of a family keeps the family's first
  // type and help.
  void Add(Type type, std::string_view name, std::string_view help, const Labels& labels,
           double value);
  void AddCounter(std::string_view name, std::string_view help, const Labels& labels,
                  double value) {
    Add(Type::kCounter, name, help, labels, value);
  }
  void AddGauge(std::string_view name, std::string_view help, const Labels& labels, double value) {
    Add(Type::kGauge, name, help, labels, value);
  }
  // The series name_bucket{...,le="B"} per bound and +Inf, name_sum and
  // name_count of one histogram.
  void AddHistogram(std::string_view name, std::string_view help, const Labels& labels,
                    const Histogram::Counts& counts);

  // The text exposition: per family (sorted by name) "# HELP", "# TYPE" and
  // one "name{label="value",...} value" line per sample.
  std::string Expose() const;

 private:
  struct Sample {
    std::string suffix;  // "_bucket", "_sum", "_count"; empty for the rest.
    Labels labels;
    double value = 0.0;
  };
  struct Family {
    Type type = Type::kGauge;
    std::string help;
    std::vector<Sample> samples;
  };
  Family* FamilyFor(Type type, std::string_view name, std::string_view help, const Labels& labels);
  std::map<std::string, Family, std::less<>> families_;
};

// The Content-Type of Expose()'s text.
inline constexpr char kContentType[] = "text/plain; version=0.0.4; charset=utf-8";

class Registry {
 public:
  Registry() = default;
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  // The counter or gauge of `name` with `labels`, made on first use; the
  // same object for the same name and labels.
  Counter& GetCounter(std::string_view name, std::string_view help, const Labels& labels = {});
  Gauge& GetGauge(std::string_view name, std::string_view help, const Labels& labels = {});
  // `upper_bounds` count on the first call for a name and labels only.
  Histogram& GetHistogram(std::string_view name, std::string_view help, const Labels& labels,
                          const std::vector<double>& upper_bounds);

  // `collect` runs at every scrape (on the scraping thread) and adds samples
  // of states read then. Returns an id for RemoveCollector.
  int AddCollector(std::function<void(Snapshot&)> collect);
  // Once it returns, the collector runs no more.
  void RemoveCollector(int id);

  // Every counter and gauge, then every collector's samples, into `out`.
  void CollectInto(Snapshot& out) const;
  std::string Expose() const;

 private:
  struct Key {
    std::string name;
    Labels labels;
    auto operator<=>(const Key&) const = default;
  };
  struct Entry {
    Type type;
    std::string help;
    std::unique_ptr<Counter> counter;
    std::unique_ptr<Gauge> gauge;
    std::unique_ptr<Histogram> histogram;  // Histograms only.
  };
  Entry& GetLocked(Type type, std::string_view name, std::string_view help, const Labels& labels);

  mutable std::mutex mu_;
  std::map<Key, Entry> entries_;
  // Held while collectors run, so that RemoveCollector waits for a scrape in
  // progress.
  mutable std::mutex collectors_mu_;
  std::map<int, std::function<void(Snapshot&)>> collectors_;
  int next_collector_id_ = 1;
};

// The process's registry: counters of events deep in the libraries
// (refusals, ingest) land here without being passed around.
Registry& DefaultRegistry();

// The figures every Prometheus target has, from /proc/self:
// process_resident_memory_bytes, process_virtual_memory_bytes,
// process_start_time_seconds, process_cpu_seconds_total (user + system),
// process_open_fds and process_max_fds (the soft RLIMIT_NOFILE); and
// reenact_build_info{version} 1, the project version the program was built
// from.
void AddProcessMetrics(Snapshot& out);

// The free bytes of the file system holding `path` for an unprivileged
// writer (statvfs f_bavail * f_frsize); -1 when it cannot be read.
double FreeDiskBytes(const std::string& path);

}  // namespace reenact::metrics
