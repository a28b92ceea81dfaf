// A full disk under a running server, on a small tmpfs the test mounts (the
// test is skipped, saying why, where it may not mount: not root, or in a
// container without CAP_SYS_ADMIN).
#include <sys/mount.h>
#include <sys/statvfs.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "server/jobs/testing/fake_worker_methods.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

using testing::IngestClient;
using testing::MakeOpenTake;
using testing::TestServer;

// A tmpfs of `bytes` at `dir`, unmounted when the fixture goes.
class SmallDisk {
 public:
  SmallDisk(const std::string& dir, int64_t bytes) : dir_(dir) {
    std::filesystem::create_directories(dir);
    const std::string size = "size=" + std::to_string(bytes);
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, size.c_str()) == 0) {
      mounted_ = true;
    } else {
      error_ = std::strerror(errno);
    }
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }
  int64_t FreeBytes() const {
    struct statvfs s {};
    if (::statvfs(dir_.c_str(), &s) != 0) return -1;
    return static_cast<int64_t>(s.f_bavail) * static_cast<int64_t>(s.f_frsize);
  }

 private:
  std::string dir_;
  bool mounted_ = false;
  std::string error_;
};

// Fills the disk with a file until writes fail, but for `leave` bytes.
void FillDisk(const std::string& path, int64_t free_bytes, int64_t leave) {
  std::ofstream ballast(path, std::ios::binary);
  const std::string block(64 << 10, 'b');
  for (int64_t written = 0; written + static_cast<int64_t>(block.size()) <= free_bytes - leave;
       written += static_cast<int64_t>(block.size())) {
    ballast.write(block.data(), static_cast<std::streamsize>(block.size()));
  }
}

TEST(DiskFull, IngestFailsClearlyTheTakeIsInterruptedAndDeletingFreesSpace) {
  const std::string dir = reenact::testing::MakeTempDir("disk_full");
  SmallDisk disk(dir + "/mnt", 16 << 20);
  if (!disk.mounted()) {
    GTEST_SKIP() << "SKIPPED: cannot mount a tmpfs for the full-disk test (" << disk.error()
                 << "); run as root to include it";
  }
  ServerOptions options;
  options.jobs.worker_path = REENACT_FAKE_WORKER;
  options.jobs.methods = FakeWorkerMethods();
  options.jobs.concurrency = 1;
  options.jobs.poll_period_s = 0.01;
  auto t = TestServer::Start(dir + "/mnt/data", options);
  ASSERT_NE(t, nullptr);
  {
    IngestClient kept(*t->ingest);
    kept.Open(MakeOpenTake("kept", "daemon-a", 1));
    kept.SendSets(1, 5, 1);
    kept.Close(5);
    ASSERT_TRUE(kept.Finish().ok());
  }
  v1::Take kept_before;
  ASSERT_TRUE(t->GetTake("kept", &kept_before).ok());

  // About 1 MiB left: the take that fills it is big next to what the
  // catalog's journal takes.
  FillDisk(dir + "/mnt/ballast", disk.FreeBytes(), 1 << 20);
  IngestClient filling(*t->ingest);
  filling.Open(MakeOpenTake("filling", "daemon-a", 1));
  uint64_t sent = 0;
  for (uint64_t s = 1; s <= 50000; ++s) {
    if (!filling.SendSets(s, s, 1)) break;
    sent = s;
  }
  const grpc::Status ended = filling.Finish();
  EXPECT_EQ(ended.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << ended.error_message();
  EXPECT_NE(ended.error_message().find("disk"), std::string::npos) << ended.error_message();
  EXPECT_GT(sent, 0u);

  // Listed as what it is: not still recording.
  v1::Take filled;
  ASSERT_TRUE(t->GetTake("filling", &filled).ok());
  EXPECT_EQ(filled.state(), v1::TAKE_STATE_INTERRUPTED);

  // Deleting works on a disk full to the last byte (the catalog cannot
  // even journal the deletion until the file is gone) and gives the space
  // back.
  FillDisk(dir + "/mnt/ballast2", disk.FreeBytes() + (64 << 10), 0);
  const int64_t free_before = disk.FreeBytes();
  EXPECT_LT(free_before, 64 << 10);

  // A job submitted now is refused, saying why, instead of waiting in the
  // queue.
  {
    auto jobs = v1::Jobs::NewStub(t->channel);
    grpc::ClientContext submit_context;
    v1::SubmitJobRequest submit;
    submit.set_take_id("kept");
    submit.set_method("rigid-cylinders");
    v1::Job job;
    const grpc::Status submitted = jobs->Submit(&submit_context, submit, &job);
    EXPECT_EQ(submitted.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(submitted.error_message().find("disk is full"), std::string::npos)
        << submitted.error_message();
    EXPECT_EQ(submitted.error_message().find(dir), std::string::npos) << submitted.error_message();
  }
  grpc::ClientContext context;
  v1::DeleteTakeRequest request;
  request.set_take_id("filling");
  v1::DeleteTakeResponse deleted;
  const grpc::Status deleting = t->takes->Delete(&context, request, &deleted);
  ASSERT_TRUE(deleting.ok()) << deleting.error_message();
  EXPECT_GT(deleted.freed_bytes(), 256 << 10);
  EXPECT_GT(disk.FreeBytes(), free_before + deleted.freed_bytes() / 2);

  // What was stored before is intact.
  v1::Take kept_after;
  ASSERT_TRUE(t->GetTake("kept", &kept_after).ok());
  EXPECT_EQ(kept_after.state(), v1::TAKE_STATE_COMPLETE);
  EXPECT_EQ(kept_after.durable_sequence(), kept_before.durable_sequence());
  EXPECT_TRUE(std::filesystem::exists(t->TakePath("kept")));
  t.reset();
}

}  // namespace
}  // namespace reenact::server
