#include "common/metrics/metrics.h"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/metrics/http_exposer.h"
#include "common/metrics/testing/scrape.h"

namespace reenact::metrics {
namespace {

using ::testing::HasSubstr;
using testing::HttpRequest;
using testing::ParseExposition;

TEST(Metrics, ExpositionParsesWithEscapedLabelsAndHelp) {
  Registry registry;
  registry.GetCounter("reenact_things_total", "Things.\nSecond line \\ of help.").Increment(3);
  registry.GetCounter("reenact_refusals_total", "Refusals.", {{"reason", "a \"quoted\"\nvalue\\"}})
      .Increment();
  registry.GetGauge("reenact_level", "A level.", {{"a", "1"}, {"b", "2"}}).Set(-2.5);
  registry.AddCollector([](Snapshot& out) {
    out.AddGauge("reenact_scraped", "Read at scrape time.", {{"state", "queued"}}, 4);
    out.AddGauge("reenact_scraped", "Read at scrape time.", {{"state", "running"}}, 1);
    out.AddGauge("reenact_big", "Bytes.", {}, 123456789012.0);
    out.AddGauge("reenact_nan", "Not a number.", {}, std::nan(""));
    out.AddGauge("bad-name", "Never exposed.", {}, 1);
  });
  const std::string text = registry.Expose();
  auto samples = ParseExposition(text);
  ASSERT_TRUE(samples.ok()) << samples.status() << "\n" << text;
  EXPECT_EQ(samples->at("reenact_things_total"), 3);
  EXPECT_EQ(samples->at("reenact_refusals_total{reason=\"a \\\"quoted\\\"\\nvalue\\\\\"}"), 1);
  EXPECT_EQ(samples->at("reenact_level{a=\"1\",b=\"2\"}"), -2.5);
  EXPECT_EQ(samples->at("reenact_scraped{state=\"queued\"}"), 4);
  EXPECT_EQ(samples->at("reenact_scraped{state=\"running\"}"), 1);
  EXPECT_TRUE(std::isnan(samples->at("reenact_nan")));
  EXPECT_EQ(samples->size(), 7u) << text;
  EXPECT_THAT(text, HasSubstr("reenact_big 123456789012\n"));  // Integers stay exact.
  EXPECT_THAT(text, HasSubstr("# HELP reenact_things_total Things.\\nSecond line \\\\ of help.\n"));
  EXPECT_THAT(text, HasSubstr("# TYPE reenact_things_total counter\n"));
  EXPECT_THAT(text, HasSubstr("# TYPE reenact_level gauge\n"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("bad-name")));
}

TEST(Metrics, HistogramsExposeCumulativeBucketsSumAndCount) {
  Registry registry;
  Histogram& latency = registry.GetHistogram("reenact_test_seconds", "Test latencies.",
                                             {{"method", "/a.B/C"}}, {0.01, 0.1, 1});
  EXPECT_EQ(&latency, &registry.GetHistogram("reenact_test_seconds", "Test latencies.",
                                             {{"method", "/a.B/C"}}, {5}));
  for (const double seconds : {0.005, 0.01, 0.05, 0.5, 0.7, 3.0, std::nan("")}) {
    latency.Observe(seconds);
  }
  const std::string text = registry.Expose();
  auto samples = ParseExposition(text);
  ASSERT_TRUE(samples.ok()) << samples.status() << "\n" << text;
  const std::string method = "method=\"/a.B/C\"";
  EXPECT_EQ(samples->at("reenact_test_seconds_bucket{" + method + ",le=\"0.01\"}"), 2);
  EXPECT_EQ(samples->at("reenact_test_seconds_bucket{" + method + ",le=\"0.1\"}"), 3);
  EXPECT_EQ(samples->at("reenact_test_seconds_bucket{" + method + ",le=\"1\"}"), 5);
  EXPECT_EQ(samples->at("reenact_test_seconds_bucket{" + method + ",le=\"+Inf\"}"), 6);
  EXPECT_EQ(samples->at("reenact_test_seconds_count{" + method + "}"), 6);
  EXPECT_NEAR(samples->at("reenact_test_seconds_sum{" + method + "}"), 4.265, 1e-9);
  EXPECT_EQ(samples->size(), 6u) << text;
  EXPECT_THAT(text, HasSubstr("# TYPE reenact_test_seconds histogram\n"));
}

TEST(Metrics, ConcurrentObservationsAreAllCounted) {
  Registry registry;
  Histogram& histogram = registry.GetHistogram("h_seconds", "H.", {}, RequestSecondsBounds());
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&histogram, t] {
      for (int i = 0; i < 10000; ++i) histogram.Observe(0.001 * (t + 1));
    });
  }
  for (std::thread& thread : threads) thread.join();
  const Histogram::Counts counts = histogram.Read();
  EXPECT_EQ(counts.cumulative.back(), 40000u);
  EXPECT_NEAR(counts.sum, 10000 * (0.001 + 0.002 + 0.003 + 0.004), 1e-6);
  EXPECT_EQ(counts.cumulative.front(), 10000u);  // Those <= 1 ms.
}

TEST(Metrics, SameNameAndLabelsIsTheSameCounter) {
  Registry registry;
  Counter& a = registry.GetCounter("x_total", "X.", {{"k", "v"}});
  Counter& b = registry.GetCounter("x_total", "X.", {{"k", "v"}});
  Counter& c = registry.GetCounter("x_total", "X.", {{"k", "w"}});
  EXPECT_EQ(&a, &b);
  EXPECT_NE(&a, &c);
  a.Increment(2);
  b.Increment();
  a.Increment(-5);  // Counters never go down.
  EXPECT_EQ(a.value(), 3);
  EXPECT_EQ(c.value(), 0);
}

TEST(Metrics, ConcurrentIncrementsAreAllCounted) {
  Registry registry;
  Counter& counter = registry.GetCounter("n_total", "N.");
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&counter] {
      for (int i = 0; i < 10000; ++i) counter.Increment();
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(counter.value(), 40000);
}

TEST(Metrics, RemovedCollectorRunsNoMore) {
  Registry registry;
  const int id =
      registry.AddCollector([](Snapshot& out) { out.AddGauge("reenact_gone", "Gone.", {}, 1); });
  EXPECT_THAT(registry.Expose(), HasSubstr("reenact_gone 1"));
  registry.RemoveCollector(id);
  EXPECT_THAT(registry.Expose(), ::testing::Not(HasSubstr("reenact_gone")));
}

TEST(Metrics, ProcessFiguresAreThere) {
  Snapshot snapshot;
  AddProcessMetrics(snapshot);
  auto samples = ParseExposition(snapshot.Expose());
  ASSERT_TRUE(samples.ok()) << samples.status();
  EXPECT_GT(samples->at("process_resident_memory_bytes"), 1 << 20);
  EXPECT_GT(samples->at("process_start_time_seconds"), 1.6e9);
  EXPECT_NEAR(
      samples->at("process_start_time_seconds"),
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(),
      3600.0);
  // Spin a little so that the CPU time is measurably above zero.
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(50);
  volatile double spin = 0;
  while (std::chrono::steady_clock::now() < until) spin = spin + 1;
  Snapshot later;
  AddProcessMetrics(later);
  auto after = ParseExposition(later.Expose());
  ASSERT_TRUE(after.ok()) << after.status();
  EXPECT_GT(after->at("process_cpu_seconds_total"), 0.0);
  EXPECT_GE(after->at("process_cpu_seconds_total"), samples->at("process_cpu_seconds_total"));
  // Three more descriptors open are three more counted.
  const double open_before = after->at("process_open_fds");
  EXPECT_GE(open_before, 3);  // stdin, stdout, stderr at least.
  int pipes[2];
  ASSERT_EQ(::pipe(pipes), 0);
  const int third = ::dup(pipes[0]);
  Snapshot with_pipes;
  AddProcessMetrics(with_pipes);
  auto opened = ParseExposition(with_pipes.Expose());
  ::close(pipes[0]);
  ::close(pipes[1]);
  ::close(third);
  ASSERT_TRUE(opened.ok()) << opened.status();
  EXPECT_EQ(opened->at("process_open_fds"), open_before + 3);
  EXPECT_GE(opened->at("process_max_fds"), opened->at("process_open_fds"));
  EXPECT_EQ(opened->at("reenact_build_info{version=\"" REENACT_VERSION "\"}"), 1);
  EXPECT_GT(FreeDiskBytes("/tmp"), 0);
  EXPECT_EQ(FreeDiskBytes("/no/such/folder"), -1);
}

TEST(HttpExposer, ServesMetricsOverTcpAndNothingElse) {
  Registry registry;
  Counter& scrapes = registry.GetCounter("reenact_test_scrapes_total", "Scrapes.");
  auto exposer = HttpExposer::Start("127.0.0.1:0", [&] {
    scrapes.Increment();
    return registry.Expose();
  });
  ASSERT_TRUE(exposer.ok()) << exposer.status();
  EXPECT_GT((*exposer)->port(), 0);
  EXPECT_EQ((*exposer)->address(), "127.0.0.1:" + std::to_string((*exposer)->port()));
  for (int i = 1; i <= 3; ++i) {
    auto answer = HttpRequest((*exposer)->port(), "/metrics");
    ASSERT_TRUE(answer.ok()) << answer.status();
    EXPECT_EQ(answer->status, 200);
    EXPECT_EQ(answer->headers["content-type"], "text/plain; version=0.0.4; charset=utf-8");
    auto samples = ParseExposition(answer->body);
    ASSERT_TRUE(samples.ok()) << samples.status() << "\n" << answer->body;
    EXPECT_EQ(samples->at("reenact_test_scrapes_total"), i);
  }
  auto query = HttpRequest((*exposer)->port(), "/metrics?name[]=x");
  ASSERT_TRUE(query.ok()) << query.status();
  EXPECT_EQ(query->status, 200);
  for (const char* other : {"/", "/metric", "/metrics/x", "/favicon.ico"}) {
    auto answer = HttpRequest((*exposer)->port(), other);
    ASSERT_TRUE(answer.ok()) << answer.status();
    EXPECT_EQ(answer->status, 404) << other;
  }
  auto post = HttpRequest((*exposer)->port(), "/metrics", "POST");
  ASSERT_TRUE(post.ok()) << post.status();
  EXPECT_EQ(post->status, 404);
  auto head = HttpRequest((*exposer)->port(), "/metrics", "HEAD");
  ASSERT_TRUE(head.ok()) << head.status();
  EXPECT_EQ(head->status, 200);
  const int port = (*exposer)->port();
  (*exposer)->Stop();
  EXPECT_FALSE(HttpRequest(port, "/metrics").ok());  // Nothing listens any more.
}

TEST(HttpExposer, GarbageAndSilentClientsDoNotStopIt) {
  auto exposer = HttpExposer::Start("localhost:0", [] { return std::string("x 1\n"); });
  ASSERT_TRUE(exposer.ok()) << exposer.status();
  // A client that connects and says nothing, and one that sends garbage.
  const int silent = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>((*exposer)->port()));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(silent, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  auto garbage = HttpRequest((*exposer)->port(), "not a target at all", "\x01\x02");
  EXPECT_FALSE(garbage.ok() && garbage->status == 200);
  auto answer = HttpRequest((*exposer)->port(), "/metrics");
  ASSERT_TRUE(answer.ok()) << answer.status();
  EXPECT_EQ(answer->body, "x 1\n");
  ::close(silent);
}

TEST(HttpExposer, BadAddressesAreRefused) {
  EXPECT_TRUE(absl::IsInvalidArgument(HttpExposer::Start("no-port", [] { return ""; }).status()));
  EXPECT_TRUE(
      absl::IsInvalidArgument(HttpExposer::Start("127.0.0.1:99999", [] { return ""; }).status()));
  auto first = HttpExposer::Start("127.0.0.1:0", [] { return ""; });
  ASSERT_TRUE(first.ok());
  const auto taken =
      HttpExposer::Start("127.0.0.1:" + std::to_string((*first)->port()), [] { return ""; });
  EXPECT_TRUE(absl::IsUnavailable(taken.status())) << taken.status();
}

}  // namespace
}  // namespace reenact::metrics
