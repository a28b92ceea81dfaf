// The real reenact-server with TLS and tokens, driven by the real `reenact`
// CLI as a user would: tokens minted by `reenact auth add`, the status name
// printed and a non-zero exit for refused calls, and nothing stored lost.
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <signal.h>

#include "common/base/files.h"
#include "common/base/subprocess.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact::testing {
namespace {

std::string Trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

TEST(TrustEndToEnd, TheCliMintsTokensAndTheServerRefusesWhatARoleMayNotDo) {
  const std::string dir = MakeTempDir("trust_e2e");
  ASSERT_EQ(RunCommand(dir, "certs", {"bash", "deploy/make-certs.sh", dir + "/tls"}).exit_code, 0);
  for (const std::string role : {"viewer", "coach", "capture"}) {
    // As `reenact auth add ... > ROLE.token`: the file the token lands in
    // becomes 0600 whatever the umask made it.
    const CommandResult added =
        RunCommand(dir, role,
                   {Bin("reenact"), "auth", "add", "--file", dir + "/tokens.json", "--role", role,
                    "--name", "demo-" + role});
    ASSERT_EQ(added.exit_code, 0) << added.err;
    ASSERT_EQ(Trim(added.out).size(), 68u) << added.out;
    std::filesystem::rename(dir + "/" + role + ".out", dir + "/" + role + ".token");
    EXPECT_EQ(std::filesystem::status(dir + "/" + role + ".token").permissions() &
                  std::filesystem::perms::all,
              std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  }
  // A name that exists already, and a role that does not.
  EXPECT_EQ(RunCommand(dir, "add-again",
                       {Bin("reenact"), "auth", "add", "--file", dir + "/tokens.json", "--role",
                        "coach", "--name", "demo-coach"})
                .exit_code,
            1);
  EXPECT_EQ(RunCommand(dir, "add-king",
                       {Bin("reenact"), "auth", "add", "--file", dir + "/tokens.json", "--role",
                        "king", "--name", "k"})
                .exit_code,
            2);

  SubprocessOptions options;
  options.stderr_path = dir + "/server.err";
  auto server =
      Subprocess::Start({Bin("reenact-server"), "--data", dir + "/data", "--listen", "127.0.0.1:0",
                         "--port-file", dir + "/server.port", "--tls-cert", dir + "/tls/server.pem",
                         "--tls-key", dir + "/tls/server.key", "--auth", dir + "/tokens.json"},
                        options);
  ASSERT_TRUE(server.ok()) << server.status();
  std::string address;
  for (int i = 0; i < 100 && address.empty(); ++i) {
    address = Trim(ReadText(dir + "/server.port"));
    if (address.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_FALSE(address.empty()) << ReadText(dir + "/server.err");
  const std::string ca = dir + "/tls/ca.pem";
  auto reenact = [&](const std::string& name, std::vector<std::string> args) {
    args.insert(args.begin(), Bin("reenact"));
    args.insert(args.end(), {"--server", address});
    return RunCommand(dir, name, args, 60);
  };

  const CommandResult anonymous = reenact("anonymous", {"takes", "list", "--tls-ca", ca});
  EXPECT_EQ(anonymous.exit_code, 1);
  EXPECT_NE(anonymous.err.find("UNAUTHENTICATED"), std::string::npos) << anonymous.err;
  const CommandResult no_ca =
      reenact("no-ca", {"takes", "list", "--token-file", dir + "/coach.token"});
  EXPECT_EQ(no_ca.exit_code, 1);
  EXPECT_NE(no_ca.err.find("UNAVAILABLE"), std::string::npos) << no_ca.err;
  // A token file others may read is refused, before anything is sent.
  ASSERT_TRUE(WriteFileAtomically(dir + "/open.token", ReadText(dir + "/coach.token")).ok());
  std::filesystem::permissions(dir + "/open.token", std::filesystem::perms::owner_read |
                                                        std::filesystem::perms::owner_write |
                                                        std::filesystem::perms::group_read |
                                                        std::filesystem::perms::others_read);
  const CommandResult open_file =
      reenact("open-token", {"takes", "list", "--tls-ca", ca, "--token-file", dir + "/open.token"});
  EXPECT_NE(open_file.exit_code, 0);
  EXPECT_NE(open_file.err.find("chmod 600"), std::string::npos) << open_file.err;
  const CommandResult listed = reenact(
      "coach-list", {"takes", "list", "--tls-ca", ca, "--token-file", dir + "/coach.token"});
  EXPECT_EQ(listed.exit_code, 0) << listed.err;
  const CommandResult denied =
      reenact("viewer-submit", {"jobs", "submit", "--take", "t", "--method", "body", "--tls-ca", ca,
                                "--token-file", dir + "/viewer.token"});
  EXPECT_EQ(denied.exit_code, 1);
  EXPECT_NE(denied.err.find("PERMISSION_DENIED"), std::string::npos) << denied.err;
  // The environment works as the flags do.
  SubprocessOptions env;
  env.env = {{"REENACT_TLS_CA", ca}, {"REENACT_TOKEN", Trim(ReadText(dir + "/viewer.token"))}};
  env.stdout_path = dir + "/env.out";
  env.stderr_path = dir + "/env.err";
  auto by_env = Subprocess::Start({Bin("reenact"), "takes", "list", "--server", address}, env);
  ASSERT_TRUE(by_env.ok());
  EXPECT_EQ((*by_env)->Wait(60)->exit_code, 0) << ReadText(dir + "/env.err");
  // Revoking: `auth list` shows names and roles (never a token), `auth
  // remove` drops the coach, and SIGHUP makes the running server forget it
  // while the viewer still works.
  const CommandResult names = RunCommand(
      dir, "auth-list", {Bin("reenact"), "auth", "list", "--file", dir + "/tokens.json"});
  EXPECT_EQ(names.exit_code, 0) << names.err;
  EXPECT_NE(names.out.find("demo-coach"), std::string::npos) << names.out;
  EXPECT_EQ(names.out.find(Trim(ReadText(dir + "/coach.token"))), std::string::npos);
  const CommandResult removed = RunCommand(
      dir, "auth-remove",
      {Bin("reenact"), "auth", "remove", "--file", dir + "/tokens.json", "--name", "demo-coach"});
  EXPECT_EQ(removed.exit_code, 0) << removed.err;
  ASSERT_TRUE((*server)->Signal(SIGHUP).ok());
  CommandResult revoked;
  for (int i = 0; i < 50; ++i) {
    revoked = reenact("coach-revoked",
                      {"takes", "list", "--tls-ca", ca, "--token-file", dir + "/coach.token"});
    if (revoked.exit_code != 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(revoked.exit_code, 1);
  EXPECT_NE(revoked.err.find("UNAUTHENTICATED"), std::string::npos) << revoked.err;
  EXPECT_TRUE((*server)->Running());
  EXPECT_EQ(reenact("viewer-after",
                    {"takes", "list", "--tls-ca", ca, "--token-file", dir + "/viewer.token"})
                .exit_code,
            0);
  // The server logs refusals without the token.
  ASSERT_TRUE((*server)->Signal(SIGTERM).ok());
  (*server)->Wait(30).IgnoreError();
  const std::string log = ReadText(dir + "/server.err");
  EXPECT_NE(log.find("refused /reenact.v1.Jobs/Submit"), std::string::npos) << log;
  EXPECT_EQ(log.find(Trim(ReadText(dir + "/viewer.token"))), std::string::npos);
  // What the server made is its user's alone: folders 0700, files 0600.
  int checked = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir + "/data")) {
    const auto perms = entry.status().permissions() & std::filesystem::perms::all;
    const auto expected =
        entry.is_directory()
            ? std::filesystem::perms::owner_all
            : (std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
    EXPECT_EQ(perms, expected) << entry.path();
    ++checked;
  }
  EXPECT_GE(checked, 3);
}

TEST(TrustEndToEnd, NonLoopbackWithoutTlsExitsWithAClearMessage) {
  const std::string dir = MakeTempDir("trust_e2e_open");
  const CommandResult refused = RunCommand(
      dir, "open", {Bin("reenact-server"), "--data", dir + "/data", "--listen", "0.0.0.0:0"}, 30);
  EXPECT_EQ(refused.exit_code, 2);  // A usage error: the flags ask for an open server.
  EXPECT_NE(refused.err.find("--insecure"), std::string::npos) << refused.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/data"));  // Nothing was created.
}

}  // namespace
}  // namespace reenact::testing
