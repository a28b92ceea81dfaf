#include "common/rpc/auth.h"

#include <sys/stat.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/testing/test_data.h"

namespace reenact::rpc {
namespace {

TEST(Sha256Hex, MatchesTheStandardsVectors) {
  // FIPS 180-2, appendix B.1, and the empty message.
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(TokenTable, AddedTokensAreFoundAndStoredOnlyAsHashes) {
  const std::string dir = reenact::testing::MakeTempDir("tokens_add");
  const std::string path = dir + "/tokens.json";
  auto coach = AddToken(path, Role::kCoach, "coach-anna");
  ASSERT_TRUE(coach.ok()) << coach.status();
  auto viewer = AddToken(path, Role::kViewer, "tablet-1");
  ASSERT_TRUE(viewer.ok()) << viewer.status();
  EXPECT_NE(*coach, *viewer);
  EXPECT_EQ(coach->size(), 4u + 64u);
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  const std::string text = *ReadFileToString(path);
  EXPECT_EQ(text.find(*coach), std::string::npos);
  EXPECT_NE(text.find(Sha256Hex(*coach)), std::string::npos);

  auto table = TokenTable::Load(path);
  ASSERT_TRUE(table.ok()) << table.status();
  EXPECT_EQ(table->size(), 2u);
  const auto anna = table->Find(*coach);
  ASSERT_TRUE(anna.has_value());
  EXPECT_EQ(anna->name, "coach-anna");
  EXPECT_EQ(anna->role, Role::kCoach);
  EXPECT_EQ(table->Find(*viewer)->role, Role::kViewer);
  EXPECT_FALSE(table->Find("rnt_" + std::string(64, '0')).has_value());
  EXPECT_FALSE(table->Find("").has_value());

  EXPECT_EQ(AddToken(path, Role::kAdmin, "tablet-1").status().code(),
            absl::StatusCode::kAlreadyExists);
  EXPECT_EQ(AddToken(path, Role::kAdmin, "").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(AddToken(path, Role::kAdmin, std::string(65, 'x')).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(TokenTable::Load(path)->size(), 2u);  // Nothing half-added.
}

TEST(TokenTable, RefusesFilesOthersCanReadAndMalformedOnes) {
  const std::string dir = reenact::testing::MakeTempDir("tokens_bad");
  const std::string path = dir + "/tokens.json";
  ASSERT_TRUE(AddToken(path, Role::kAdmin, "root").ok());
  ASSERT_EQ(::chmod(path.c_str(), 0644), 0);
  const auto open = TokenTable::Load(path);
  EXPECT_EQ(open.status().code(), absl::StatusCode::kPermissionDenied);
  EXPECT_NE(open.status().message().find("644"), std::string::npos) << open.status();
  EXPECT_EQ(TokenTable::Load(dir + "/missing.json").status().code(), absl::StatusCode::kNotFound);

  const std::string hash(64, 'a');
  for (const std::string& json : {
           std::string("not json"),
           std::string("[]"),
           std::string(R"({"tokens": {}})"),
           std::string(R"({"tokens": [{"name": "a", "role": "viewer"}]})"),
           R"({"tokens": [{"name": "a", "role": "king", "sha256": ")" + hash + R"("}]})",
           std::string(R"({"tokens": [{"name": "a", "role": "viewer", "sha256": "abc"}]})"),
           R"({"tokens": [{"name": "", "role": "viewer", "sha256": ")" + hash + R"("}]})",
           R"({"tokens": [{"name": "a\n", "role": "viewer", "sha256": ")" + hash + R"("}]})",
           R"({"tokens": [{"name": "a", "role": "viewer", "sha256": ")" + hash +
               R"("}, {"name": "a", "role": "coach", "sha256": ")" + std::string(64, 'b') +
               R"("}]})",
           R"({"tokens": [{"name": "a", "role": "viewer", "sha256": ")" + hash +
               R"("}, {"name": "b", "role": "coach", "sha256": ")" + hash + R"("}]})",
       }) {
    EXPECT_EQ(TokenTable::Parse(json, "t").status().code(), absl::StatusCode::kInvalidArgument)
        << json;
  }
  EXPECT_TRUE(TokenTable::Parse(R"({"tokens": []})", "t").ok());
}

TEST(Authorizer, EachRoleGetsItsAccessesAndNothingElse) {
  const std::string tokens[] = {"tv", "tc", "to", "tw", "ta"};
  std::string json = R"({"tokens": [)";
  const char* roles[] = {"viewer", "capture", "coach", "worker", "admin"};
  for (int i = 0; i < 5; ++i) {
    json += std::string(i ? "," : "") + R"({"name": ")" + roles[i] + R"(", "role": ")" + roles[i] +
            R"(", "sha256": ")" + Sha256Hex(tokens[i]) + R"("})";
  }
  json += "]}";
  auto table = TokenTable::Parse(json, "t");
  ASSERT_TRUE(table.ok()) << table.status();
  const Authorizer auth(*table, {{"/s/Read", kRead},
                                 {"/s/Ingest", kIngest},
                                 {"/s/Manage", kManage},
                                 {"/s/Start", kIngest | kManage},
                                 {"/s/Lease", kWork}});
  // Rows: viewer, capture, coach, worker, admin; columns: Read, Ingest,
  // Manage, Start, Lease, a method missing from the table.
  const bool expected[5][6] = {{true, false, false, false, false, false},
                               {false, true, false, true, false, false},
                               {true, false, true, true, false, false},
                               {false, false, false, false, true, false},
                               {true, true, true, true, true, true}};
  const char* methods[] = {"/s/Read",  "/s/Ingest", "/s/Manage",
                           "/s/Start", "/s/Lease",  "/s/Unknown"};
  for (int r = 0; r < 5; ++r) {
    for (int m = 0; m < 6; ++m) {
      const auto got = auth.Authorize("Bearer " + tokens[r], methods[m]);
      if (expected[r][m]) {
        ASSERT_TRUE(got.ok()) << roles[r] << " " << methods[m] << ": " << got.status();
        EXPECT_EQ(got->name, roles[r]);
      } else {
        EXPECT_EQ(got.status().code(), absl::StatusCode::kPermissionDenied)
            << roles[r] << " " << methods[m];
      }
    }
  }
  EXPECT_EQ(auth.Authorize(std::nullopt, "/s/Read").status().code(),
            absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(auth.Authorize("Basic dXNlcjpwYXNz", "/s/Read").status().code(),
            absl::StatusCode::kUnauthenticated);
  const auto wrong = auth.Authorize("Bearer not-a-token", "/s/Read");
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(wrong.status().message().find("not-a-token"), std::string::npos);
  EXPECT_EQ(auth.refusals(), 5 * 6 - 13 + 3);

  const Authorizer open(std::nullopt, {});
  const auto anonymous = open.Authorize(std::nullopt, "/s/Anything");
  ASSERT_TRUE(anonymous.ok());
  EXPECT_TRUE(anonymous->anonymous());
  EXPECT_TRUE(anonymous->admin());
}

TEST(Role, NamesRoundTrip) {
  for (Role role : {Role::kViewer, Role::kCapture, Role::kCoach, Role::kWorker, Role::kAdmin}) {
    EXPECT_EQ(*ParseRole(RoleName(role)), role);
  }
  EXPECT_EQ(ParseRole("root").status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::rpc
