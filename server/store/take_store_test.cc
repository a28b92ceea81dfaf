#include "server/store/take_store.h"

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include "common/io/take.h"
#include "common/testing/test_data.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::ExpectStoredFrameSets;
using testing::MakeFrameSet;
using testing::MakeOpenTake;
using testing::SensorIds;

// Collects what a recorder reports.
class Watcher : public RecorderObserver {
 public:
  void OnDurable(uint64_t durable_sequence) override {
    std::lock_guard<std::mutex> lock(mu_);
    durables_.push_back(durable_sequence);
    changed_.notify_all();
  }
  void OnFinished(const RecordingResult& result) override {
    std::lock_guard<std::mutex> lock(mu_);
    result_ = result;
    changed_.notify_all();
  }
  // True once `sequence` is durable (within 10 s).
  bool WaitDurable(uint64_t sequence) {
    std::unique_lock<std::mutex> lock(mu_);
    return changed_.wait_for(lock, std::chrono::seconds(10),
                             [&] { return !durables_.empty() && durables_.back() >= sequence; });
  }
  std::optional<RecordingResult> WaitFinished() {
    std::unique_lock<std::mutex> lock(mu_);
    changed_.wait_for(lock, std::chrono::seconds(10), [&] { return result_.has_value(); });
    return result_;
  }
  std::vector<uint64_t> durables() {
    std::lock_guard<std::mutex> lock(mu_);
    return durables_;
  }

 private:
  std::mutex mu_;
  std::condition_variable changed_;
  std::vector<uint64_t> durables_;
  std::optional<RecordingResult> result_;
};

TakeStoreOptions Options(const std::string& dir) {
  TakeStoreOptions options;
  options.data_dir = dir;
  options.catalog_update_period_s = 3600;  // Tests look at state changes only.
  return options;
}

TakeOpenRequest Request(const std::string& id, const std::string& daemon, int sensors) {
  const v1::OpenTake open = MakeOpenTake(id, daemon, sensors);
  return {open.take_id(),
          open.info(),
          {open.sensors().begin(), open.sensors().end()},
          open.daemon_id(),
          /*owner=*/"",
          /*owner_is_admin=*/false};
}

// Enqueues sets [first, last], waiting until each is durable (one chunk each).
void RecordOneByOne(TakeRecorder& recorder, Watcher& watcher, uint64_t first, uint64_t last,
                    int sensors) {
  for (uint64_t s = first; s <= last; ++s) {
    ASSERT_TRUE(recorder.Enqueue(MakeFrameSet(s, SensorIds(sensors))).ok());
    ASSERT_TRUE(watcher.WaitDurable(s)) << "set " << s;
  }
}

TEST(TakeStore, RecordsCompletesAndReadsBack) {
  const std::string dir = reenact::testing::MakeTempDir("store_record");
  auto store = TakeStore::Open(Options(dir));
  ASSERT_TRUE(store.ok()) << store.status();
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("take-a", "daemon-1", 2), &watcher);
  ASSERT_TRUE(opened.ok()) << opened.status();
  EXPECT_FALSE(opened->resumed);
  EXPECT_EQ(opened->durable_sequence, 0u);
  ASSERT_NE(opened->recorder, nullptr);
  EXPECT_EQ((*store)->GetTake("take-a")->state(), v1::TAKE_STATE_RECORDING);
  constexpr uint64_t kSets = 25;
  for (uint64_t s = 1; s <= kSets; ++s) {
    ASSERT_TRUE(opened->recorder->Enqueue(MakeFrameSet(s, SensorIds(2))).ok());
  }
  ASSERT_TRUE(watcher.WaitDurable(kSets));
  const std::vector<uint64_t> durables = watcher.durables();
  for (size_t i = 1; i < durables.size(); ++i) EXPECT_GT(durables[i], durables[i - 1]);
  const RecorderStats stats = opened->recorder->stats();
  EXPECT_EQ(stats.frame_sets, static_cast<int64_t>(kSets));
  EXPECT_EQ(stats.batches, static_cast<int64_t>(durables.size()));
  // Live progress while recording.
  EXPECT_EQ((*store)->GetTake("take-a")->durable_sequence(), kSets);

  opened->recorder->Finish(true, kSets, absl::OkStatus());
  const auto result = watcher.WaitFinished();
  ASSERT_TRUE(result.has_value());
  EXPECT_TRUE(result->reason.ok()) << result->reason;
  EXPECT_EQ(result->row.take.state(), v1::TAKE_STATE_COMPLETE);
  auto take = (*store)->GetTake("take-a");
  ASSERT_TRUE(take.ok());
  EXPECT_EQ(take->state(), v1::TAKE_STATE_COMPLETE);
  EXPECT_EQ(take->durable_sequence(), kSets);
  EXPECT_EQ(take->frame_set_count(), static_cast<int64_t>(kSets));
  EXPECT_EQ(take->duration_ns(), static_cast<int64_t>(kSets - 1) * testing::kPeriodNs);
  ASSERT_EQ(take->sensors_size(), 2);
  for (const v1::TakeSensor& s : take->sensors()) EXPECT_EQ(s.frame_count(), 25);
  const std::string path = dir + "/takes/take-a.mcap";
  EXPECT_EQ(take->size_bytes(), static_cast<int64_t>(fs::file_size(path)));
  ExpectStoredFrameSets(path, SensorIds(2), kSets);
}

TEST(TakeStore, EnqueueRefusesOutOfOrderSequences) {
  auto store = TakeStore::Open(Options(reenact::testing::MakeTempDir("store_order")));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("t", "d", 1), &watcher);
  ASSERT_TRUE(opened.ok());
  TakeRecorder& recorder = *opened->recorder;
  ASSERT_TRUE(recorder.Enqueue(MakeFrameSet(1, SensorIds(1))).ok());
  ASSERT_TRUE(recorder.Enqueue(MakeFrameSet(2, SensorIds(1))).ok());
  for (const auto& [sequence, kind] : std::vector<std::pair<uint64_t, std::string>>{
           {4, "a gap"}, {2, "a duplicate"}, {1, "a step back"}}) {
    const absl::Status status = recorder.Enqueue(MakeFrameSet(sequence, SensorIds(1)));
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(status.message().find(kind), std::string::npos) << status;
    EXPECT_NE(status.message().find("expected 3"), std::string::npos) << status;
  }
  recorder.Finish(false, 0, absl::CancelledError("test over"));
  const auto result = watcher.WaitFinished();
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->row.take.durable_sequence(), 2u);
  EXPECT_EQ(result->reason.code(), absl::StatusCode::kCancelled);
}

TEST(TakeStore, ResumesInterruptedTakeInPlace) {
  const std::string dir = reenact::testing::MakeTempDir("store_resume");
  auto store = TakeStore::Open(Options(dir));
  ASSERT_TRUE(store.ok());
  {
    Watcher watcher;
    auto opened = (*store)->OpenTake(Request("t", "daemon-1", 2), &watcher);
    ASSERT_TRUE(opened.ok());
    for (uint64_t s = 1; s <= 10; ++s) {
      ASSERT_TRUE(opened->recorder->Enqueue(MakeFrameSet(s, SensorIds(2))).ok());
    }
    opened->recorder->Finish(false, 0, absl::AbortedError("stream gone"));
    const auto result = watcher.WaitFinished();
    ASSERT_TRUE(result.has_value());
    EXPECT_EQ(result->row.take.state(), v1::TAKE_STATE_INTERRUPTED);
    EXPECT_EQ(result->reason.code(), absl::StatusCode::kAborted);
    EXPECT_EQ(result->row.take.durable_sequence(), 10u);
  }
  EXPECT_EQ((*store)->GetTake("t")->state(), v1::TAKE_STATE_INTERRUPTED);
  // The interrupted file is finished and valid on its own.
  ExpectStoredFrameSets(dir + "/takes/t.mcap", SensorIds(2), 10);
  Watcher other;
  EXPECT_EQ((*store)->OpenTake(Request("t", "daemon-2", 2), &other).status().code(),
            absl::StatusCode::kPermissionDenied);
  EXPECT_EQ((*store)->OpenTake(Request("t", "daemon-1", 3), &other).status().code(),
            absl::StatusCode::kInvalidArgument);

  Watcher watcher;
  auto resumed = (*store)->OpenTake(Request("t", "daemon-1", 2), &watcher);
  ASSERT_TRUE(resumed.ok()) << resumed.status();
  EXPECT_TRUE(resumed->resumed);
  EXPECT_EQ(resumed->durable_sequence, 10u);
  EXPECT_EQ((*store)->OpenTake(Request("t", "daemon-1", 2), &other).status().code(),
            absl::StatusCode::kAborted);
  for (uint64_t s = 11; s <= 16; ++s) {
    ASSERT_TRUE(resumed->recorder->Enqueue(MakeFrameSet(s, SensorIds(2))).ok());
  }
  resumed->recorder->Finish(true, 16, absl::OkStatus());
  const auto result = watcher.WaitFinished();
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->row.take.state(), v1::TAKE_STATE_COMPLETE);
  EXPECT_EQ(result->row.take.frame_set_count(), 16);
  ExpectStoredFrameSets(dir + "/takes/t.mcap", SensorIds(2), 16);

  // A complete take opens without a recorder (for a repeated CloseTake).
  auto complete = (*store)->OpenTake(Request("t", "daemon-1", 2), &other);
  ASSERT_TRUE(complete.ok());
  EXPECT_EQ(complete->recorder, nullptr);
  EXPECT_EQ(complete->durable_sequence, 16u);
}

// Copies a live data folder (catalog with its WAL, take files) as a crash
// would leave it.
void CopyDataFolder(const std::string& from, const std::string& to) {
  fs::remove_all(to);
  fs::create_directories(to + "/takes");
  for (const char* name : {"catalog.sqlite", "catalog.sqlite-wal"}) {
    if (fs::exists(from + "/" + name)) fs::copy_file(from + "/" + name, to + "/" + name);
  }
  for (const auto& entry : fs::directory_iterator(from + "/takes")) {
    fs::copy_file(entry.path(), to + "/takes/" + entry.path().filename().string());
  }
}

TEST(TakeStore, RecoversTakesCutByACrashAndResumesThem) {
  const std::string live = reenact::testing::MakeTempDir("store_crash_live");
  auto store = TakeStore::Open(Options(live));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("cut", "daemon-1", 2), &watcher);
  ASSERT_TRUE(opened.ok());
  RecordOneByOne(*opened->recorder, watcher, 1, 12, 2);
  const std::string take_file = live + "/takes/cut.mcap";
  // Chunk k holds frame set k (each was fsync'ed alone); find where they lie.
  std::vector<McapChunkInfo> chunks;
  {
    auto reader = McapReader::Open(take_file);
    ASSERT_TRUE(reader.ok());
    chunks = (*reader)->chunks();
  }
  ASSERT_EQ(chunks.size(), 13u);  // Info and calibrations, then one per set.
  const uint64_t size = fs::file_size(take_file);
  struct Cut {
    uint64_t size;
    uint64_t durable;
  };
  const std::vector<Cut> cuts = {
      {size, 12},                                                   // Process killed, file whole.
      {size - 5, 11},                                               // Torn message index.
      {chunks[12].chunk_offset + chunks[12].chunk_length / 2, 11},  // Torn chunk.
      {chunks[10].chunk_offset + 20, 9},                            // Torn earlier chunk.
  };
  for (const Cut& cut : cuts) {
    SCOPED_TRACE("cut at " + std::to_string(cut.size) + " of " + std::to_string(size));
    const std::string crashed = reenact::testing::MakeTempDir("store_crash_copy");
    CopyDataFolder(live, crashed);
    fs::resize_file(crashed + "/takes/cut.mcap", cut.size);
    std::vector<RecoveredTake> recovered;
    auto restarted = TakeStore::Open(Options(crashed), &recovered);
    ASSERT_TRUE(restarted.ok()) << restarted.status();
    ASSERT_EQ(recovered.size(), 1u);
    EXPECT_EQ(recovered[0].take_id, "cut");
    EXPECT_EQ(recovered[0].durable_sequence, cut.durable);
    EXPECT_TRUE(recovered[0].problem.empty()) << recovered[0].problem;
    auto take = (*restarted)->GetTake("cut");
    ASSERT_TRUE(take.ok());
    EXPECT_EQ(take->state(), v1::TAKE_STATE_INTERRUPTED);
    EXPECT_EQ(take->durable_sequence(), cut.durable);
    EXPECT_EQ(take->frame_set_count(), static_cast<int64_t>(cut.durable));
    EXPECT_EQ(take->sensors(0).frame_count(), static_cast<int64_t>(cut.durable));
    ExpectStoredFrameSets(crashed + "/takes/cut.mcap", SensorIds(2), cut.durable);

    Watcher resume_watcher;
    auto resumed = (*restarted)->OpenTake(Request("cut", "daemon-1", 2), &resume_watcher);
    ASSERT_TRUE(resumed.ok()) << resumed.status();
    EXPECT_TRUE(resumed->resumed);
    ASSERT_EQ(resumed->durable_sequence, cut.durable);
    for (uint64_t s = cut.durable + 1; s <= 15; ++s) {
      ASSERT_TRUE(resumed->recorder->Enqueue(MakeFrameSet(s, SensorIds(2))).ok());
    }
    resumed->recorder->Finish(true, 15, absl::OkStatus());
    ASSERT_TRUE(resume_watcher.WaitFinished().has_value());
    EXPECT_EQ((*restarted)->GetTake("cut")->state(), v1::TAKE_STATE_COMPLETE);
    ExpectStoredFrameSets(crashed + "/takes/cut.mcap", SensorIds(2), 15);
  }
  opened->recorder->Finish(false, 0, absl::CancelledError("test over"));
  watcher.WaitFinished();
}

TEST(TakeStore, UnreadableFileIsSetAsideAndTheTakeStartsOver) {
  const std::string live = reenact::testing::MakeTempDir("store_unreadable_live");
  auto store = TakeStore::Open(Options(live));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("gone", "daemon-1", 1), &watcher);
  ASSERT_TRUE(opened.ok());
  RecordOneByOne(*opened->recorder, watcher, 1, 3, 1);
  const std::string crashed = reenact::testing::MakeTempDir("store_unreadable_copy");
  CopyDataFolder(live, crashed);
  fs::resize_file(crashed + "/takes/gone.mcap", 20);  // Not even the header survived.
  std::vector<RecoveredTake> recovered;
  auto restarted = TakeStore::Open(Options(crashed), &recovered);
  ASSERT_TRUE(restarted.ok());
  ASSERT_EQ(recovered.size(), 1u);
  EXPECT_EQ(recovered[0].durable_sequence, 0u);
  EXPECT_NE(recovered[0].problem.find("moved to"), std::string::npos) << recovered[0].problem;
  Watcher again;
  auto resumed = (*restarted)->OpenTake(Request("gone", "daemon-1", 1), &again);
  ASSERT_TRUE(resumed.ok()) << resumed.status();
  EXPECT_EQ(resumed->durable_sequence, 0u);
  for (uint64_t s = 1; s <= 4; ++s) {
    ASSERT_TRUE(resumed->recorder->Enqueue(MakeFrameSet(s, SensorIds(1))).ok());
  }
  resumed->recorder->Finish(true, 4, absl::OkStatus());
  ASSERT_TRUE(again.WaitFinished().has_value());
  ExpectStoredFrameSets(crashed + "/takes/gone.mcap", SensorIds(1), 4);
  opened->recorder->Finish(false, 0, absl::CancelledError("test over"));
  watcher.WaitFinished();
}

TEST(TakeStore, SensorLostReachesCatalogAndFile) {
  const std::string dir = reenact::testing::MakeTempDir("store_lost");
  auto store = TakeStore::Open(Options(dir));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("t", "d", 2), &watcher);
  ASSERT_TRUE(opened.ok());
  ASSERT_TRUE(opened->recorder->Enqueue(MakeFrameSet(1, SensorIds(2))).ok());
  v1::SensorLostRecord lost;
  lost.set_sensor_id("k1");
  lost.set_stamp_ns(testing::kStartNs + 40'000'000);
  lost.set_reason("device unplugged (045e:02c4)");
  ASSERT_TRUE(opened->recorder->EnqueueSensorLost(lost).ok());
  lost.set_sensor_id("k9");
  EXPECT_EQ(opened->recorder->EnqueueSensorLost(lost).code(), absl::StatusCode::kInvalidArgument);
  v1::FrameSet second = MakeFrameSet(2, {"k0"});
  second.add_missing_sensor_ids("k1");
  ASSERT_TRUE(opened->recorder->Enqueue(second).ok());
  opened->recorder->Finish(true, 2, absl::OkStatus());
  ASSERT_TRUE(watcher.WaitFinished().has_value());
  auto take = (*store)->GetTake("t");
  ASSERT_TRUE(take.ok());
  EXPECT_EQ(take->sensors(1).sensor_id(), "k1");
  EXPECT_EQ(take->sensors(1).lost_stamp_ns(), testing::kStartNs + 40'000'000);
  EXPECT_EQ(take->sensors(1).lost_reason(), "device unplugged (045e:02c4)");
  EXPECT_EQ(take->sensors(0).frame_count(), 2);
  EXPECT_EQ(take->sensors(1).frame_count(), 1);
  auto reader = TakeReader::Open(dir + "/takes/t.mcap");
  ASSERT_TRUE(reader.ok());
  auto records = (*reader)->ReadAll<v1::SensorLostRecord>(kIngestSensorLostTopic);
  ASSERT_TRUE(records.ok());
  ASSERT_EQ(records->size(), 1u);
  EXPECT_EQ(records->front().reason(), "device unplugged (045e:02c4)");
}

TEST(TakeStore, ShutdownInterruptsRecordingsAndRefusesNewTakes) {
  auto store = TakeStore::Open(Options(reenact::testing::MakeTempDir("store_shutdown")));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("t", "d", 1), &watcher);
  ASSERT_TRUE(opened.ok());
  for (uint64_t s = 1; s <= 5; ++s) {
    ASSERT_TRUE(opened->recorder->Enqueue(MakeFrameSet(s, SensorIds(1))).ok());
  }
  (*store)->Shutdown(absl::UnavailableError("going down"));
  const auto result = watcher.WaitFinished();
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->row.take.state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_EQ(result->row.take.durable_sequence(), 5u);  // Everything received is kept.
  EXPECT_EQ(result->reason.code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ((*store)->GetTake("t")->state(), v1::TAKE_STATE_INTERRUPTED);
  Watcher other;
  EXPECT_EQ((*store)->OpenTake(Request("u", "d", 1), &other).status().code(),
            absl::StatusCode::kUnavailable);
}

TEST(TakeStore, DeleteAndReadOnlyWhenNotRecording) {
  const std::string dir = reenact::testing::MakeTempDir("store_delete");
  auto store = TakeStore::Open(Options(dir));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("t", "d", 1), &watcher);
  ASSERT_TRUE(opened.ok());
  EXPECT_EQ((*store)->DeleteTake("t").status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ((*store)->TakeFileForReading("t").status().code(),
            absl::StatusCode::kFailedPrecondition);
  opened->recorder->Finish(true, 0, absl::OkStatus());
  ASSERT_TRUE(watcher.WaitFinished().has_value());
  const std::string path = dir + "/takes/t.mcap";
  EXPECT_EQ(*(*store)->TakeFileForReading("t"), path);
  const auto size = static_cast<int64_t>(fs::file_size(path));
  EXPECT_EQ(*(*store)->DeleteTake("t"), size);
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ((*store)->GetTake("t").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ((*store)->DeleteTake("t").status().code(), absl::StatusCode::kNotFound);
}

TEST(TakeStore, OversizedNamesAndNotesAreRefusedAndTheCatalogStillLists) {
  const std::string dir = reenact::testing::MakeTempDir("store_names");
  auto store = TakeStore::Open(Options(dir));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto kept = (*store)->OpenTake(Request("kept", "d", 1), &watcher);
  ASSERT_TRUE(kept.ok()) << kept.status();
  const FrameSetLimits limits;
  for (int field = 0; field < 3; ++field) {
    TakeOpenRequest request = Request("big-" + std::to_string(field), "d", 1);
    const std::string huge(8 << 20, 'n');  // 8 MiB, as nine such names once broke the list.
    if (field == 0) request.info.set_name(huge);
    if (field == 1) request.info.set_notes(huge);
    if (field == 2) request.info.set_motion_source(huge);
    const auto opened = (*store)->OpenTake(request, &watcher);
    EXPECT_EQ(opened.status().code(), absl::StatusCode::kInvalidArgument) << field;
    // The error names the size, never echoes the text.
    EXPECT_NE(opened.status().message().find(std::to_string(8 << 20)), std::string::npos);
    EXPECT_LT(opened.status().message().size(), 200u);
    EXPECT_EQ((*store)->GetTake(request.take_id).status().code(), absl::StatusCode::kNotFound);
  }
  // A frame rate that is not a number (or absurd) is the client's error,
  // named as such, never a catalog constraint with the server's path.
  for (const double fps : {std::nan(""), -1.0, 1e9, std::numeric_limits<double>::infinity()}) {
    TakeOpenRequest request = Request("bad-fps", "d", 1);
    request.info.set_fps(fps);
    const auto opened = (*store)->OpenTake(request, &watcher);
    EXPECT_EQ(opened.status().code(), absl::StatusCode::kInvalidArgument) << fps;
    EXPECT_NE(opened.status().message().find("fps"), std::string::npos) << opened.status();
    EXPECT_EQ(opened.status().message().find(dir), std::string::npos) << opened.status();
  }
  TakeOpenRequest at_limit = Request("at-limit", "d", 1);
  at_limit.info.set_name(std::string(limits.max_name_bytes, 'a'));
  at_limit.info.set_notes(std::string(limits.max_notes_bytes, 'b'));
  Watcher at_limit_watcher;
  auto accepted = (*store)->OpenTake(at_limit, &at_limit_watcher);
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  const auto takes = (*store)->ListTakes(v1::TAKE_STATE_UNSPECIFIED);
  ASSERT_TRUE(takes.ok()) << takes.status();
  EXPECT_EQ(takes->size(), 2u);
  kept->recorder->Finish(true, 0, absl::OkStatus());
  accepted->recorder->Finish(true, 0, absl::OkStatus());
  ASSERT_TRUE(watcher.WaitFinished().has_value());
  ASSERT_TRUE(at_limit_watcher.WaitFinished().has_value());
}

TEST(TakeStore, OneServerPerDataFolder) {
  const std::string dir = reenact::testing::MakeTempDir("store_lock");
  auto first = TakeStore::Open(Options(dir));
  ASSERT_TRUE(first.ok());
  auto second = TakeStore::Open(Options(dir));
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition) << second.status();
  first->reset();
  EXPECT_TRUE(TakeStore::Open(Options(dir)).ok());
}

TEST(TakeStore, CatalogFollowsARecordingPeriodically) {
  const std::string dir = reenact::testing::MakeTempDir("store_catalog_period");
  TakeStoreOptions options = Options(dir);
  options.catalog_update_period_s = 0.05;
  auto store = TakeStore::Open(options);
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("t", "d", 1), &watcher);
  ASSERT_TRUE(opened.ok());
  EXPECT_EQ((*store)->catalog().Get("t")->take.durable_sequence(), 0u);
  RecordOneByOne(*opened->recorder, watcher, 1, 5, 1);
  uint64_t in_catalog = 0;
  for (int i = 0; i < 200 && in_catalog < 5; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    in_catalog = (*store)->catalog().Get("t")->take.durable_sequence();
  }
  EXPECT_EQ(in_catalog, 5u);
  EXPECT_EQ((*store)->catalog().Get("t")->take.state(), v1::TAKE_STATE_RECORDING);
  opened->recorder->Finish(true, 5, absl::OkStatus());
  ASSERT_TRUE(watcher.WaitFinished().has_value());
  EXPECT_EQ((*store)->catalog().Get("t")->take.state(), v1::TAKE_STATE_COMPLETE);
}

// A write that fails half-way (here: the file size limit) interrupts the
// take; the file is cut back to its last whole frame set and stays usable.
TEST(TakeStore, WriteFailureInterruptsAndKeepsWholeSets) {
  const std::string dir = reenact::testing::MakeTempDir("store_write_failure");
  auto store = TakeStore::Open(Options(dir));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("t", "d", 1), &watcher);
  ASSERT_TRUE(opened.ok());
  auto big_set = [](uint64_t sequence, size_t bytes) {
    v1::FrameSet set = MakeFrameSet(sequence, SensorIds(1));
    set.mutable_frames(0)->mutable_color()->set_data(
        std::string(bytes, static_cast<char>(sequence)));
    return set;
  };
  for (uint64_t s = 1; s <= 2; ++s) {
    ASSERT_TRUE(opened->recorder->Enqueue(big_set(s, 100'000)).ok());
    ASSERT_TRUE(watcher.WaitDurable(s));
  }
  const std::string path = dir + "/takes/t.mcap";
  rlimit old_limit{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit limit = old_limit;
  limit.rlim_cur = fs::file_size(path) + 150'000;
  const auto old_handler = signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  ASSERT_TRUE(opened->recorder->Enqueue(big_set(3, 400'000)).ok());
  const auto result = watcher.WaitFinished();
  setrlimit(RLIMIT_FSIZE, &old_limit);
  signal(SIGXFSZ, old_handler);
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->row.take.state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_EQ(result->reason.code(), absl::StatusCode::kUnavailable) << result->reason;
  EXPECT_NE(result->reason.message().find("could not store"), std::string::npos);
  EXPECT_EQ(result->row.take.durable_sequence(), 2u);
  EXPECT_EQ(opened->recorder->Enqueue(big_set(4, 10)).code(), absl::StatusCode::kUnavailable);
  auto take = (*store)->GetTake("t");
  ASSERT_TRUE(take.ok());
  EXPECT_EQ(take->state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_EQ(take->durable_sequence(), 2u);
  EXPECT_EQ(take->size_bytes(), static_cast<int64_t>(fs::file_size(path)));
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok());
  EXPECT_TRUE((*reader)->report().indexed);
  auto records = (*reader)->ReadAll<v1::FrameSetRecord>(kIngestFrameSetTopic);
  ASSERT_TRUE(records.ok());
  ASSERT_EQ(records->size(), 2u);
  EXPECT_EQ((*reader)->frame_count(), 2);
  // The daemon resumes once the disk has room again.
  Watcher again;
  auto resumed = (*store)->OpenTake(Request("t", "d", 1), &again);
  ASSERT_TRUE(resumed.ok()) << resumed.status();
  EXPECT_EQ(resumed->durable_sequence, 2u);
  ASSERT_TRUE(resumed->recorder->Enqueue(big_set(3, 1000)).ok());
  resumed->recorder->Finish(true, 3, absl::OkStatus());
  ASSERT_TRUE(again.WaitFinished().has_value());
  EXPECT_EQ((*store)->GetTake("t")->frame_set_count(), 3);
}

// Recovery cost of a take of ~1 MB frame sets (like 2 sensors of 1080p JPEG
// and 512x424 depth) cut mid-chunk; prints the time per MB (not asserted).
TEST(TakeStore, RecoveryOfLargeTake) {
  const std::string live = reenact::testing::MakeTempDir("store_big_live");
  auto store = TakeStore::Open(Options(live));
  ASSERT_TRUE(store.ok());
  Watcher watcher;
  auto opened = (*store)->OpenTake(Request("big", "d", 2), &watcher);
  ASSERT_TRUE(opened.ok());
  std::mt19937 rng(5);
  std::string noise(450'000, '\0');
  for (char& c : noise) c = static_cast<char>(rng());
  constexpr uint64_t kSets = 40;
  auto print_stats = [](const char* what, const RecorderStats& stats) {
    std::printf(
        "%s: %lld sets in %lld batches (max %lld sets), write %.2f ms/set, "
        "fsync %.2f ms/batch (max %.2f ms)\n",
        what, static_cast<long long>(stats.frame_sets), static_cast<long long>(stats.batches),
        static_cast<long long>(stats.max_batch_sets), stats.write_ns * 1e-6 / stats.frame_sets,
        stats.sync_ns * 1e-6 / stats.batches, stats.max_sync_ns * 1e-6);
  };
  for (uint64_t s = 1; s <= kSets; ++s) {
    v1::FrameSet set = MakeFrameSet(s, SensorIds(2));
    for (v1::Frame& f : *set.mutable_frames()) f.mutable_color()->set_data(noise);
    ASSERT_TRUE(opened->recorder->Enqueue(std::move(set)).ok());
    // The first ten one at a time (one fsync each), the rest as fast as possible.
    if (s <= 10) {
      ASSERT_TRUE(watcher.WaitDurable(s));
    }
    if (s == 10) print_stats("ingest, one set per batch", opened->recorder->stats());
  }
  ASSERT_TRUE(watcher.WaitDurable(kSets));
  print_stats("ingest, all", opened->recorder->stats());
  const std::string crashed = reenact::testing::MakeTempDir("store_big_copy");
  CopyDataFolder(live, crashed);
  const uint64_t size = fs::file_size(crashed + "/takes/big.mcap");
  fs::resize_file(crashed + "/takes/big.mcap", size - 100'000);
  std::vector<RecoveredTake> recovered;
  auto restarted = TakeStore::Open(Options(crashed), &recovered);
  ASSERT_TRUE(restarted.ok());
  ASSERT_EQ(recovered.size(), 1u);
  // The cut tears the last chunk; the sets of the chunks before it remain.
  EXPECT_GE(recovered[0].durable_sequence, 1u);
  EXPECT_LT(recovered[0].durable_sequence, kSets);
  std::printf("recovery: %.1f MB in %.1f ms (%.2f ms/MB), %llu bytes cut\n",
              recovered[0].size_bytes / 1e6, recovered[0].elapsed_s * 1e3,
              recovered[0].elapsed_s * 1e3 / (recovered[0].size_bytes / 1e6),
              static_cast<unsigned long long>(recovered[0].dropped_bytes));
  opened->recorder->Finish(false, 0, absl::CancelledError("test over"));
  watcher.WaitFinished();
}

}  // namespace
}  // namespace reenact::server
