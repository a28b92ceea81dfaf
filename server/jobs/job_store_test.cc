#include "server/jobs/job_store.h"

#include <string>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "common/testing/test_data.h"

namespace reenact::server {
namespace {

v1::Job NewJob(const std::string& take_id) {
  v1::Job job;
  job.set_take_id(take_id);
  job.set_method("rigid-carved");
  (*job.mutable_options())["voxel_mm"] = "8";
  (*job.mutable_options())["note"] = "quote \" backslash \\ unicode \xc3\xa9";
  return job;
}

std::unique_ptr<Catalog> OpenCatalog(const std::string& path) {
  auto catalog = Catalog::Open(path);
  EXPECT_TRUE(catalog.ok()) << catalog.status();
  return catalog.ok() ? std::move(*catalog) : nullptr;
}

// A version-1 catalog (before the jobs table) with one take in it.
TEST(Catalog, MigratesVersionOneAndKeepsTakes) {
  const std::string path = testing::MakeTempDir("catalog_v1") + "/catalog.sqlite";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  const char* v1_schema = R"sql(
CREATE TABLE takes (
  take_id TEXT PRIMARY KEY NOT NULL, name TEXT NOT NULL,
  state TEXT NOT NULL CHECK (state IN ('recording', 'complete', 'interrupted')),
  daemon_id TEXT NOT NULL, created_unix_ns INTEGER NOT NULL, updated_unix_ns INTEGER NOT NULL,
  durable_sequence INTEGER NOT NULL, frame_set_count INTEGER NOT NULL,
  first_stamp_ns INTEGER NOT NULL, last_stamp_ns INTEGER NOT NULL, duration_ns INTEGER NOT NULL,
  size_bytes INTEGER NOT NULL, path TEXT NOT NULL, generator TEXT NOT NULL,
  synthetic INTEGER NOT NULL, fps REAL NOT NULL);
CREATE TABLE sensors (
  take_id TEXT NOT NULL REFERENCES takes (take_id) ON DELETE CASCADE,
  sensor_id TEXT NOT NULL, model TEXT NOT NULL, frame_count INTEGER NOT NULL,
  lost_stamp_ns INTEGER NOT NULL, lost_reason TEXT NOT NULL, PRIMARY KEY (take_id, sensor_id));
INSERT INTO takes VALUES ('old', 'old take', 'complete', 'd', 1, 2, 3, 3, 0, 0, 0, 99,
                          'takes/old.mcap', 'g', 0, 30.0);
PRAGMA user_version = 1;
)sql";
  ASSERT_EQ(sqlite3_exec(db, v1_schema, nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);

  auto catalog = OpenCatalog(path);
  ASSERT_NE(catalog, nullptr);
  EXPECT_EQ(*catalog->SchemaVersion(), Catalog::kSchemaVersion);
  auto take = catalog->Get("old");
  ASSERT_TRUE(take.ok()) << take.status();
  EXPECT_EQ(take->take.size_bytes(), 99);
  EXPECT_EQ(take->owner, "");  // Takes from before tokens belong to the anonymous caller.
  auto jobs = catalog->ListJobs();
  ASSERT_TRUE(jobs.ok()) << jobs.status();
  EXPECT_TRUE(jobs->empty());
}

TEST(JobStore, InsertGetListAndReopen) {
  const std::string path = testing::MakeTempDir("job_store") + "/catalog.sqlite";
  std::string first_id, second_id;
  {
    auto catalog = OpenCatalog(path);
    auto store = JobStore::Open(catalog.get());
    ASSERT_TRUE(store.ok()) << store.status();
    auto first = (*store)->Insert(NewJob("take-a"));
    ASSERT_TRUE(first.ok()) << first.status();
    EXPECT_TRUE(ValidateJobId(first->job_id()).ok()) << first->job_id();
    EXPECT_EQ(first->job_id().rfind("j-", 0), 0u) << first->job_id();
    EXPECT_EQ(first->state(), v1::JOB_STATE_QUEUED);
    EXPECT_GT(first->submitted_unix_ns(), 0);
    EXPECT_EQ(first->attempts(), 0);
    EXPECT_EQ(first->progress().eta_s(), -1);
    auto second = (*store)->Insert(NewJob("take-b"));
    ASSERT_TRUE(second.ok());
    EXPECT_NE(second->job_id(), first->job_id());
    first_id = first->job_id();
    second_id = second->job_id();
    auto running = (*store)->Mutate(first_id, [](v1::Job& j) {
      j.set_state(v1::JOB_STATE_RUNNING);
      j.set_attempts(1);
      j.set_started_unix_ns(5);
    });
    ASSERT_TRUE(running.ok()) << running.status();
    EXPECT_EQ((*store)->List(v1::JOB_STATE_RUNNING).size(), 1u);
    EXPECT_EQ((*store)->List(v1::JOB_STATE_UNSPECIFIED, "take-b").size(), 1u);
    EXPECT_EQ((*store)->List(v1::JOB_STATE_UNSPECIFIED, "take-c").size(), 0u);
    EXPECT_EQ((*store)->Get("j-nope").status().code(), absl::StatusCode::kNotFound);
    EXPECT_EQ((*store)->Mutate("j-nope", [](v1::Job&) {}).status().code(),
              absl::StatusCode::kNotFound);
  }
  auto catalog = OpenCatalog(path);
  auto store = JobStore::Open(catalog.get());
  ASSERT_TRUE(store.ok());
  auto all = (*store)->List();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].job_id(), second_id);  // Newest first.
  auto first = (*store)->Get(first_id);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(first->state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(first->started_unix_ns(), 5);
  EXPECT_EQ(first->options().at("note"), NewJob("x").options().at("note"));
  EXPECT_EQ(first->options().at("voxel_mm"), "8");
}

TEST(JobStore, ProgressWritesAreThrottled) {
  const std::string path = testing::MakeTempDir("job_store_progress") + "/catalog.sqlite";
  auto catalog = OpenCatalog(path);
  JobStoreOptions options;
  options.progress_write_period_s = 3600;
  auto store = JobStore::Open(catalog.get(), options);
  ASSERT_TRUE(store.ok());
  auto job = (*store)->Insert(NewJob("t"));
  ASSERT_TRUE(job.ok());
  v1::JobProgress progress;
  progress.set_stage("register");
  progress.set_fraction(0.42);
  progress.set_frames_done(120);
  progress.set_frames_total(300);
  progress.set_eta_s(12.5);
  auto updated = (*store)->UpdateProgress(job->job_id(), progress);
  ASSERT_TRUE(updated.ok());
  EXPECT_EQ(updated->progress().frames_done(), 120);
  // In memory at once, in the catalog not yet.
  EXPECT_EQ((*store)->Get(job->job_id())->progress().stage(), "register");
  EXPECT_EQ(catalog->GetJob(job->job_id())->progress().fraction(), 0.0);
  // A state change writes everything.
  ASSERT_TRUE(
      (*store)->Mutate(job->job_id(), [](v1::Job& j) { j.set_state(v1::JOB_STATE_RUNNING); }).ok());
  const v1::Job stored = *catalog->GetJob(job->job_id());
  EXPECT_EQ(stored.progress().stage(), "register");
  EXPECT_DOUBLE_EQ(stored.progress().fraction(), 0.42);
  EXPECT_EQ(stored.progress().frames_total(), 300);
  EXPECT_DOUBLE_EQ(stored.progress().eta_s(), 12.5);

  // With no throttle every progress is written.
  auto eager_store = JobStore::Open(catalog.get(), JobStoreOptions{.progress_write_period_s = 0});
  ASSERT_TRUE(eager_store.ok());
  progress.set_fraction(0.5);
  ASSERT_TRUE((*eager_store)->UpdateProgress(job->job_id(), progress).ok());
  EXPECT_DOUBLE_EQ(catalog->GetJob(job->job_id())->progress().fraction(), 0.5);
}

TEST(JobStore, RequeueUnfinishedKeepsAttemptsAndGivesUp) {
  const std::string path = testing::MakeTempDir("job_store_requeue") + "/catalog.sqlite";
  auto catalog = OpenCatalog(path);
  auto store = JobStore::Open(catalog.get(), JobStoreOptions{.max_attempts = 2});
  ASSERT_TRUE(store.ok());
  auto set_running = [&](int attempts) {
    auto job = (*store)->Insert(NewJob("t"));
    EXPECT_TRUE(job.ok());
    EXPECT_TRUE((*store)
                    ->Mutate(job->job_id(),
                             [&](v1::Job& j) {
                               j.set_state(v1::JOB_STATE_RUNNING);
                               j.set_attempts(attempts);
                               BeginAttempt(j, "node7/pid 42");
                             })
                    .ok());
    return job->job_id();
  };
  const std::string once = set_running(1);
  const std::string twice = set_running(2);
  auto done = (*store)->Insert(NewJob("t"));
  ASSERT_TRUE((*store)
                  ->Mutate(done->job_id(), [](v1::Job& j) { j.set_state(v1::JOB_STATE_SUCCEEDED); })
                  .ok());
  auto requeued = (*store)->RequeueUnfinished();
  ASSERT_TRUE(requeued.ok()) << requeued.status();
  ASSERT_EQ(requeued->size(), 1u);
  EXPECT_EQ((*requeued)[0], once);
  EXPECT_EQ((*store)->Get(once)->state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ((*store)->Get(once)->attempts(), 1);
  EXPECT_EQ(catalog->GetJob(once)->state(), v1::JOB_STATE_QUEUED);
  // The attempt's end is in its history, in the catalog too.
  const absl::StatusOr<v1::Job> stored = catalog->GetJob(once);
  ASSERT_EQ(stored->attempt_history_size(), 1);
  EXPECT_EQ(stored->attempt_history(0).number(), 1);
  EXPECT_EQ(stored->attempt_history(0).worker(), "node7/pid 42");
  EXPECT_EQ(stored->attempt_history(0).outcome(), "server stopped");
  EXPECT_GT(stored->attempt_history(0).ended_unix_ns(), 0);
  EXPECT_EQ((*store)->Get(twice)->state(), v1::JOB_STATE_FAILED);
  EXPECT_NE((*store)->Get(twice)->error().find("2 times"), std::string::npos);
  EXPECT_EQ((*store)->Get(done->job_id())->state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ((*store)->Queued().size(), 1u);
}

TEST(JobStore, ValidatesIds) {
  EXPECT_TRUE(ValidateJobId("j-20260101-120000-ab12").ok());
  EXPECT_FALSE(ValidateJobId("").ok());
  EXPECT_FALSE(ValidateJobId("a/b").ok());
  EXPECT_FALSE(ValidateJobId(std::string(65, 'a')).ok());
}

}  // namespace
}  // namespace reenact::server
