// The HTTP front over loopback: a Server with reenactments, the front on
// 127.0.0.1:0, and a Beast client: the JSON API, the glTF with its ETag and
// ranges, errors, tokens and roles, the app's files, TLS, the live follow as
// a WebSocket, and the connection cap.
#include "server/http/http_front.h"
#include "server/jobs/testing/fake_worker_methods.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <openssl/ssl.h>
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/subprocess.h"
#include "common/io/gltf_export.h"
#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/rpc/auth.h"
#include "common/testing/test_data.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "server/live/live_hub.h"
#include "server/server.h"
#include "server/testing/test_server.h"

namespace reenact::server::http {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = beast::http;
namespace websocket = beast::websocket;
namespace ssl = asio::ssl;
using tcp = asio::ip::tcp;
using json = nlohmann::json;
using server::testing::IngestClient;
using server::testing::MakeFrameSet;
using server::testing::MakeOpenTake;
using server::testing::SensorIds;
using server::testing::TestServer;

struct Reply {
  int status = 0;
  std::map<std::string, std::string> headers;
  std::string body;
  bool failed = false;  // The connection failed (refused, closed early).
  json Json() const { return json::parse(body, nullptr, false); }
  std::string Header(const std::string& name) const {
    const auto it = headers.find(name);
    return it == headers.end() ? "" : it->second;
  }
};

// One request on a fresh connection; `ca` set: over TLS trusting it.
Reply Request(int port, const std::string& target,
              const std::vector<std::pair<std::string, std::string>>& headers = {},
              bhttp::verb verb = bhttp::verb::get, const std::string& ca = "") {
  asio::io_context io;
  Reply reply;
  bhttp::request<bhttp::string_body> request{verb, target, 11};
  request.set(bhttp::field::host, "127.0.0.1");
  for (const auto& [name, value] : headers) request.set(name, value);
  request.prepare_payload();
  bhttp::response_parser<bhttp::string_body> parser;
  parser.body_limit(256 << 20);
  if (verb == bhttp::verb::head) parser.skip(true);
  beast::flat_buffer buffer;
  beast::error_code error;
  tcp::socket socket(io);
  socket.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)),
                 error);
  if (ca.empty()) {
    if (!error) bhttp::write(socket, request, error);
    if (!error) bhttp::read(socket, buffer, parser, error);
  } else {
    ssl::context context(ssl::context::tls_client);
    context.load_verify_file(ca);
    context.set_verify_mode(ssl::verify_peer);
    beast::ssl_stream<tcp::socket> stream(std::move(socket), context);
    if (!error) stream.handshake(ssl::stream_base::client, error);
    if (!error) bhttp::write(stream, request, error);
    if (!error) bhttp::read(stream, buffer, parser, error);
  }
  if (error) {
    reply.failed = true;
    return reply;
  }
  const auto& response = parser.get();
  reply.status = static_cast<int>(response.result_int());
  for (const auto& field : response) {
    reply.headers[std::string(field.name_string())] = std::string(field.value());
  }
  reply.body = response.body();
  return reply;
}

// What a WebSocket follow delivered.
struct FollowReply {
  std::vector<json> texts;
  std::vector<std::string> binaries;
  int close_code = 0;
  bool upgraded = false;
};

FollowReply FollowOverWebSocket(int port, const std::string& target,
                                const std::string& origin = "") {
  FollowReply out;
  asio::io_context io;
  websocket::stream<tcp::socket> socket(io);
  beast::error_code error;
  socket.next_layer().connect(
      tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)), error);
  if (!origin.empty()) {
    socket.set_option(websocket::stream_base::decorator(
        [origin](websocket::request_type& request) { request.set(bhttp::field::origin, origin); }));
  }
  if (!error) socket.handshake("127.0.0.1:" + std::to_string(port), target, error);
  if (error) return out;
  out.upgraded = true;
  for (;;) {
    beast::flat_buffer buffer;
    socket.read(buffer, error);
    if (error) break;
    std::string payload = beast::buffers_to_string(buffer.data());
    if (socket.got_text()) {
      out.texts.push_back(json::parse(payload, nullptr, false));
    } else {
      out.binaries.push_back(std::move(payload));
    }
  }
  out.close_code = socket.reason().code;
  return out;
}

// A follower that poses a real body mesh: the mesh at the first set, then a
// frame with 25 rotations and joints per set.
class BodyFollower final : public LiveFollower {
 public:
  // The test body's mesh, built once (building the model takes seconds
  // under a sanitizer; a fit that slow would skip frame sets).
  static const v1::BodyMesh& Mesh() {
    static const v1::BodyMesh* const mesh =
        new v1::BodyMesh(reenact::testing::MakeTestBodyReenactment(1).body.front());
    return *mesh;
  }

  absl::StatusOr<LiveFit> Push(const v1::FrameSet& set) override {
    LiveFit fit;
    if (pushed_ == 0) fit.mesh = Mesh();
    fit.frame.emplace();
    fit.frame->set_frame_index(pushed_++);
    fit.frame->set_stamp_ns(set.stamp_ns());
    fit.frame->mutable_body()->set_valid(true);
    for (int j = 0; j < 25; ++j) {
      v1::Quaternion* q = fit.frame->mutable_body()->add_local_rotations();
      q->set_w(1.0);
      fit.frame->add_joints_in_world_m()->set_y(0.04 * j);
    }
    fit.frame->mutable_body()->mutable_root_translation_m()->set_x(0.5);
    fit.fit_ms = 1.0;
    return fit;
  }

 private:
  int pushed_ = 0;
};

class HttpFrontTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = reenact::testing::MakeTempDir("http_front_test"); }
  void TearDown() override {
    Stop();
    std::filesystem::remove_all(dir_);
  }
  void Stop() {
    if (t_ != nullptr) t_->server->Shutdown();
    front_.reset();
    t_.reset();
  }

  // A server (live jobs of method body follow with BodyFollower) and its
  // front; `web_root` empty: no app.
  void Start(ServerOptions options = {}, HttpFrontOptions front = {}) {
    options.jobs.worker_path = REENACT_FAKE_WORKER;
    options.jobs.methods = FakeWorkerMethods();
    options.jobs.concurrency = 1;
    options.jobs.poll_period_s = 0.02;
    options.live.factory = [](const std::string&, const v1::TakeInfo&,
                              const std::vector<v1::SensorCalibration>&,
                              const std::map<std::string, std::string>&)
        -> absl::StatusOr<std::unique_ptr<LiveFollower>> {
      return std::make_unique<BodyFollower>();
    };
    t_ = TestServer::Start(dir_ + "/data", options);
    ASSERT_NE(t_, nullptr);
    front.address = "127.0.0.1:0";
    front.tls = options.tls;
    auto started = HttpFront::Start(front, HttpBackendOf(t_->server.get()));
    ASSERT_TRUE(started.ok()) << started.status();
    front_ = std::move(*started);
    port_ = front_->port();
  }

  // Writes `data` into the server's store.
  void AddReenactment(const ReenactmentData& data) {
    ReenactmentStore& store = t_->server->reenactments();
    const std::string& id = data.info.reenactment_id();
    ASSERT_TRUE(WriteReenactmentFile(data, store.PathFor(id)).ok());
    ASSERT_TRUE(store.Add(id).ok());
  }

  // Reenactments.Delete, as a client would.
  void DeleteReenactment(const std::string& id) {
    grpc::ClientContext context;
    v1::DeleteReenactmentRequest request;
    request.set_reenactment_id(id);
    v1::DeleteReenactmentResponse deleted;
    ASSERT_TRUE(v1::Reenactments::NewStub(t_->channel)->Delete(&context, request, &deleted).ok());
  }

  std::string dir_;
  std::unique_ptr<TestServer> t_;
  std::unique_ptr<HttpFront> front_;
  int port_ = 0;
};

ReenactmentData RigidReenactment(const std::string& id, int64_t created_unix_ns) {
  reenact::testing::TestReenactmentOptions options;
  options.id = id;
  ReenactmentData data = reenact::testing::MakeTestReenactment(options);
  data.info.set_created_unix_ns(created_unix_ns);
  return data;
}

TEST_F(HttpFrontTest, ListsReenactmentsNewestFirstInPages) {
  ASSERT_NO_FATAL_FAILURE(Start());
  ASSERT_NO_FATAL_FAILURE(AddReenactment(RigidReenactment("r-20260101-120000-aaaa", 1000)));
  ASSERT_NO_FATAL_FAILURE(AddReenactment(RigidReenactment("r-20260101-120000-bbbb", 3000)));
  ReenactmentData body = reenact::testing::MakeTestBodyReenactment(30);
  body.info.set_created_unix_ns(2000);
  ASSERT_NO_FATAL_FAILURE(AddReenactment(body));

  const Reply first = Request(port_, "/api/v1/reenactments?page_size=2");
  ASSERT_EQ(first.status, 200) << first.body;
  EXPECT_EQ(first.Header("Content-Type"), "application/json");
  const json page = first.Json();
  ASSERT_TRUE(page.is_array()) << first.body;
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0]["id"], "r-20260101-120000-bbbb");
  EXPECT_EQ(page[0]["kind"], "rigid");
  EXPECT_EQ(page[0]["parts"], 3);
  EXPECT_EQ(page[0]["frames"], 5);
  EXPECT_EQ(page[0]["created_unix_ns"], 3000);
  EXPECT_EQ(page[1]["id"], body.info.reenactment_id());
  EXPECT_EQ(page[1]["kind"], "body");
  EXPECT_EQ(page[1]["method"], "body");
  EXPECT_EQ(page[1]["frames"], 30);
  const double fps = body.info.fps();
  EXPECT_NEAR(page[1]["duration_s"].get<double>(), 30 / fps, 1e-9);
  for (const char* key : {"take_id", "take_name", "fps", "file_bytes"}) {
    EXPECT_TRUE(page[1].contains(key)) << key;
  }
  const std::string token = first.Header("X-Next-Page-Token");
  ASSERT_FALSE(token.empty());
  const Reply second = Request(port_, "/api/v1/reenactments?page_size=2&page_token=" + token);
  ASSERT_EQ(second.status, 200) << second.body;
  ASSERT_EQ(second.Json().size(), 1u);
  EXPECT_EQ(second.Json()[0]["id"], "r-20260101-120000-aaaa");
  EXPECT_TRUE(second.Header("X-Next-Page-Token").empty());

  const Reply one = Request(port_, "/api/v1/reenactments/r-20260101-120000-aaaa");
  ASSERT_EQ(one.status, 200) << one.body;
  EXPECT_EQ(one.Json()["frames"], 5);
}

TEST_F(HttpFrontTest, ModelIsTheExportedGlbWithEtagRangesAndGoesWithTheReenactment) {
  ASSERT_NO_FATAL_FAILURE(Start());
  const ReenactmentData body = reenact::testing::MakeTestBodyReenactment(30);
  ASSERT_NO_FATAL_FAILURE(AddReenactment(body));
  const std::string id = body.info.reenactment_id();
  const std::string path = "/api/v1/reenactments/" + id + "/model.glb";
  absl::StatusOr<std::string> expected = ExportReenactmentGlb(reenact::testing::ToPlain(body));
  ASSERT_TRUE(expected.ok()) << expected.status();

  const Reply glb = Request(port_, path);
  ASSERT_EQ(glb.status, 200) << glb.body;
  EXPECT_EQ(glb.Header("Content-Type"), "model/gltf-binary");
  EXPECT_EQ(glb.Header("Accept-Ranges"), "bytes");
  EXPECT_TRUE(glb.body == *expected) << glb.body.size() << " bytes vs " << expected->size();
  const std::string etag = glb.Header("ETag");
  ASSERT_GE(etag.size(), 3u);
  const std::string cached = t_->server->reenactments().DerivedPathFor(id, ".glb");
  EXPECT_TRUE(std::filesystem::exists(cached));

  // Again: the same bytes and tag; a client that has them gets 304.
  const Reply again = Request(port_, path);
  EXPECT_EQ(again.Header("ETag"), etag);
  EXPECT_TRUE(again.body == *expected);
  EXPECT_EQ(Request(port_, path, {{"If-None-Match", etag}}).status, 304);

  // A resumed download: the tail from byte 1000.
  const Reply tail = Request(port_, path, {{"Range", "bytes=1000-"}});
  ASSERT_EQ(tail.status, 206);
  EXPECT_EQ(tail.Header("Content-Range"),
            absl::StrCat("bytes 1000-", expected->size() - 1, "/", expected->size()));
  EXPECT_TRUE(tail.body == expected->substr(1000));
  const Reply middle = Request(port_, path, {{"Range", "bytes=10-19"}});
  EXPECT_EQ(middle.status, 206);
  EXPECT_TRUE(middle.body == expected->substr(10, 10));
  const Reply suffix = Request(port_, path, {{"Range", "bytes=-4"}});
  EXPECT_TRUE(suffix.body == expected->substr(expected->size() - 4));
  // If-Range with another tag: the whole file.
  EXPECT_EQ(Request(port_, path, {{"Range", "bytes=10-19"}, {"If-Range", "\"other\""}}).status,
            200);
  const Reply beyond = Request(port_, path, {{"Range", absl::StrCat("bytes=", 1 << 30, "-")}});
  EXPECT_EQ(beyond.status, 416);
  EXPECT_EQ(beyond.Header("Content-Range"), absl::StrCat("bytes */", expected->size()));
  const Reply head = Request(port_, path, {}, bhttp::verb::head);
  EXPECT_EQ(head.status, 200);
  EXPECT_EQ(head.Header("Content-Length"), std::to_string(expected->size()));

  // Deleted: the glb goes with it.
  ASSERT_NO_FATAL_FAILURE(DeleteReenactment(id));
  EXPECT_FALSE(std::filesystem::exists(cached));
  EXPECT_EQ(Request(port_, path).status, 404);
}

TEST_F(HttpFrontTest, AppearanceVideoIsServedWithRangesAndIsNotFoundWhereThereIsNone) {
  ASSERT_NO_FATAL_FAILURE(Start());
  // A body reenactment with an appearance video of 1.5 MB: more than one
  // of the Fetch stream's pieces. The server keeps the bytes as they are (the
  // clients decode them), so any bytes show how they are served.
  ReenactmentData body = reenact::testing::MakeTestBodyReenactment(30);
  std::string video(1536 * 1024, '\0');
  for (size_t i = 0; i < video.size(); ++i) video[i] = static_cast<char>((i * 2654435761u) >> 13);
  v1::AppearanceVideo& appearance = *body.body.front().mutable_appearance();
  appearance.set_mp4(video);
  appearance.set_size_px(256);
  appearance.set_frame_count(30);
  appearance.set_codec("libx264");
  ASSERT_NO_FATAL_FAILURE(AddReenactment(body));
  const std::string id = body.info.reenactment_id();
  const std::string path = "/api/v1/reenactments/" + id + "/appearance.mp4";

  const Reply whole = Request(port_, path);
  ASSERT_EQ(whole.status, 200) << whole.body.substr(0, 300);
  EXPECT_EQ(whole.Header("Content-Type"), "video/mp4");
  EXPECT_EQ(whole.Header("Accept-Ranges"), "bytes");
  EXPECT_TRUE(whole.body == video) << whole.body.size() << " bytes vs " << video.size();
  const std::string cached = t_->server->reenactments().DerivedPathFor(id, ".appearance.mp4");
  EXPECT_TRUE(std::filesystem::exists(cached));
  // The glb was built by the same fetch, with the static atlas.
  EXPECT_TRUE(std::filesystem::exists(t_->server->reenactments().DerivedPathFor(id, ".glb")));
  const std::string etag = whole.Header("ETag");
  EXPECT_EQ(Request(port_, path, {{"If-None-Match", etag}}).status, 304);
  // What a browser's media stack asks: an open range, then pieces of it.
  const Reply open = Request(port_, path, {{"Range", "bytes=0-"}});
  EXPECT_EQ(open.status, 206);
  EXPECT_EQ(open.Header("Content-Range"),
            absl::StrCat("bytes 0-", video.size() - 1, "/", video.size()));
  const Reply piece = Request(port_, path, {{"Range", "bytes=1048570-1048589"}});
  EXPECT_EQ(piece.status, 206);
  EXPECT_TRUE(piece.body == video.substr(1048570, 20));
  EXPECT_EQ(Request(port_, path, {{"Range", absl::StrCat("bytes=", video.size(), "-")}}).status,
            416);

  // A reenactment without a video (rigid parts): 404 that says why, and
  // its glb is still served.
  const ReenactmentData rigid = reenact::testing::MakeTestReenactment();
  ASSERT_NO_FATAL_FAILURE(AddReenactment(rigid));
  const std::string rigid_path =
      "/api/v1/reenactments/" + rigid.info.reenactment_id() + "/appearance.mp4";
  for (int attempt = 0; attempt < 2; ++attempt) {  // Built, then remembered.
    const Reply none = Request(port_, rigid_path);
    EXPECT_EQ(none.status, 404);
    EXPECT_NE(none.body.find("no appearance video"), std::string::npos) << none.body;
  }
  EXPECT_EQ(
      Request(port_, "/api/v1/reenactments/" + rigid.info.reenactment_id() + "/model.glb").status,
      200);

  // Deleted: the video goes with it.
  ASSERT_NO_FATAL_FAILURE(DeleteReenactment(id));
  EXPECT_FALSE(std::filesystem::exists(cached));
  EXPECT_EQ(Request(port_, path).status, 404);
}

TEST_F(HttpFrontTest, ErrorsAreJsonWithTheStatusName) {
  ASSERT_NO_FATAL_FAILURE(Start());
  const auto expect_error = [&](const std::string& target, int status, const std::string& code,
                                bhttp::verb verb = bhttp::verb::get) {
    const Reply reply = Request(port_, target, {}, verb);
    EXPECT_EQ(reply.status, status) << target << ": " << reply.body;
    const json body = reply.Json();
    ASSERT_TRUE(body.is_object()) << target << ": " << reply.body;
    EXPECT_EQ(body["error"]["code"], code) << target;
    EXPECT_FALSE(body["error"]["message"].get<std::string>().empty()) << target;
  };
  expect_error("/api/v1/reenactments/r-20990101-000000-none", 404, "NOT_FOUND");
  expect_error("/api/v1/reenactments/r-20990101-000000-none/model.glb", 404, "NOT_FOUND");
  expect_error("/api/v1/reenactments/bad%20id", 400, "INVALID_ARGUMENT");
  expect_error("/api/v1/reenactments/bad%20id/model.glb", 400, "INVALID_ARGUMENT");
  expect_error("/api/v1/reenactments?page_size=many", 400, "INVALID_ARGUMENT");
  expect_error("/api/v1/jobs?live=maybe", 400, "INVALID_ARGUMENT");
  expect_error("/api/v1/nothing", 404, "NOT_FOUND");
  expect_error("/api/v1/reenactments/%zz", 400, "INVALID_ARGUMENT");
  expect_error("/api/v1/reenactments", 405, "UNIMPLEMENTED", bhttp::verb::post);
  expect_error("/api/v1/jobs/j-1/follow", 400, "INVALID_ARGUMENT");
  // No app: the page says how to build it.
  const Reply app = Request(port_, "/");
  EXPECT_EQ(app.status, 503);
  EXPECT_NE(app.body.find("build"), std::string::npos) << app.body;
  // Requests with a body or huge headers are refused, not read.
  EXPECT_EQ(Request(port_, "/api/v1/info", {{"X-Big", std::string(20000, 'x')}}).status, 431);
}

TEST_F(HttpFrontTest, TargetsThatAreNotUtf8GetJsonErrorsAndTheServerStaysUp) {
  // An app root, so that a path outside the API is answered "no such file".
  const std::string web = dir_ + "/web";
  std::filesystem::create_directories(web);
  std::ofstream(web + "/index.html") << "<!doctype html><title>app</title>";
  HttpFrontOptions front;
  front.web_root = web;
  ASSERT_NO_FATAL_FAILURE(Start({}, front));
  const std::string kReplacement = "\xEF\xBF\xBD";  // U+FFFD in UTF-8.
  for (const auto& [target, status] :
       std::vector<std::pair<std::string, int>>{{"/%ff", 404},
                                                {"/%c0%ae/index.html", 404},
                                                {"/api/v1/%ff", 400},
                                                {"/api/v1/jobs/%ff/follow", 400},
                                                {"/api/v1/reenactments?page_size=%ff", 400},
                                                {"/api/v1/jobs?live=%c0%ae", 400},
                                                {"/api/v1/reenactments/%fe%ff/model.glb", 400}}) {
    const Reply reply = Request(port_, target);
    ASSERT_FALSE(reply.failed) << target << ": the server did not answer";
    EXPECT_EQ(reply.status, status) << target << ": " << reply.body;
    const json body = reply.Json();
    ASSERT_TRUE(body.is_object()) << target << ": " << reply.body;
    EXPECT_NE(body["error"]["message"].get<std::string>().find(kReplacement), std::string::npos)
        << target << ": " << reply.body;
  }
  // A raw byte that is not UTF-8 in the target: refused or answered, never
  // the end of the server.
  const Reply raw = Request(port_, "/\xff\xfe");
  if (!raw.failed) {
    EXPECT_GE(raw.status, 400) << raw.body;
  }
  EXPECT_EQ(Request(port_, "/api/v1/info").status, 200);
}

TEST_F(HttpFrontTest, ServesTheAppFilesAndNothingOutsideThem) {
  const std::string web = dir_ + "/web";
  std::filesystem::create_directories(web + "/assets");
  std::ofstream(web + "/index.html") << "<!doctype html><title>reenact</title>";
  std::ofstream(web + "/assets/app.js") << "console.log(1);";
  std::ofstream(dir_ + "/secret.txt") << "not for the web";
  std::filesystem::create_symlink(dir_ + "/secret.txt", web + "/secret.txt");
  HttpFrontOptions front;
  front.web_root = web;
  ASSERT_NO_FATAL_FAILURE(Start({}, front));

  const Reply index = Request(port_, "/");
  ASSERT_EQ(index.status, 200);
  EXPECT_EQ(index.body, "<!doctype html><title>reenact</title>");
  EXPECT_EQ(index.Header("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(index.Header("Content-Security-Policy").find("default-src 'self'"), std::string::npos);
  EXPECT_EQ(Request(port_, "/?reenactment=r-1&t=1").body, index.body);
  const Reply script = Request(port_, "/assets/app.js");
  EXPECT_EQ(script.status, 200);
  EXPECT_EQ(script.Header("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_EQ(Request(port_, "/assets/app.js", {{"If-None-Match", script.Header("ETag")}}).status,
            304);
  for (const std::string target : {"/secret.txt", "/../secret.txt", "/assets/..%2F..%2Fsecret.txt",
                                   "/%2e%2e/secret.txt", "/assets", "/missing.js"}) {
    const Reply reply = Request(port_, target);
    EXPECT_EQ(reply.status, 404) << target << ": " << reply.body;
    EXPECT_EQ(reply.body.find("not for the web"), std::string::npos) << target;
  }
}

TEST_F(HttpFrontTest, TokensAndRolesAreTheGrpcOnesOverTls) {
  const std::string certs = dir_ + "/certs";
  auto made = Subprocess::Start({"bash", "deploy/make-certs.sh", certs});
  ASSERT_TRUE(made.ok()) << made.status();
  ASSERT_EQ((*made)->Wait(60)->exit_code, 0);
  const absl::StatusOr<std::string> viewer =
      rpc::AddToken(dir_ + "/tokens.json", rpc::Role::kViewer, "tablet");
  const absl::StatusOr<std::string> capture =
      rpc::AddToken(dir_ + "/tokens.json", rpc::Role::kCapture, "daemon");
  ASSERT_TRUE(viewer.ok() && capture.ok());
  ServerOptions options;
  options.tls = {certs + "/server.pem", certs + "/server.key", ""};
  options.auth_file = dir_ + "/tokens.json";
  ASSERT_NO_FATAL_FAILURE(Start(options));
  EXPECT_EQ(front_->url(), absl::StrCat("https://127.0.0.1:", port_, "/"));
  ASSERT_NO_FATAL_FAILURE(AddReenactment(RigidReenactment("r-20260101-120000-aaaa", 1000)));
  const std::string ca = certs + "/ca.pem";
  const std::string list = "/api/v1/reenactments";

  const Reply anonymous = Request(port_, list, {}, bhttp::verb::get, ca);
  EXPECT_EQ(anonymous.status, 401) << anonymous.body;
  EXPECT_EQ(anonymous.Json()["error"]["code"], "UNAUTHENTICATED");
  EXPECT_NE(anonymous.Header("WWW-Authenticate").find("Bearer"), std::string::npos);
  EXPECT_EQ(
      Request(port_, list, {{"Authorization", "Bearer not-a-token"}}, bhttp::verb::get, ca).status,
      401);
  const Reply read =
      Request(port_, list, {{"Authorization", "Bearer " + *viewer}}, bhttp::verb::get, ca);
  EXPECT_EQ(read.status, 200) << read.body;
  EXPECT_EQ(read.Json().size(), 1u);
  EXPECT_EQ(Request(port_, list + "?access_token=" + *viewer, {}, bhttp::verb::get, ca).status,
            200);
  const Reply capture_reads =
      Request(port_, list, {{"Authorization", "Bearer " + *capture}}, bhttp::verb::get, ca);
  EXPECT_EQ(capture_reads.status, 403) << capture_reads.body;
  EXPECT_EQ(capture_reads.Json()["error"]["code"], "PERMISSION_DENIED");
  const Reply info = Request(port_, "/api/v1/info", {}, bhttp::verb::get, ca);
  EXPECT_EQ(info.Json()["auth"], true);
  EXPECT_EQ(info.Json()["tls"], true);
  EXPECT_EQ(info.Header("Strict-Transport-Security"), "max-age=31536000");
  // With tokens, the token decides, whatever the Host.
  EXPECT_EQ(
      Request(port_, "/api/v1/info", {{"Host", "studio.example"}}, bhttp::verb::get, ca).status,
      200);
  // TLS 1.2 with a CBC suite is refused; an AEAD suite is served.
  for (const auto& [suites, served] : std::vector<std::pair<std::string, bool>>{
           {"ECDHE-ECDSA-AES128-SHA:ECDHE-ECDSA-AES256-SHA:ECDHE-ECDSA-AES128-SHA256", false},
           {"ECDHE-ECDSA-AES128-GCM-SHA256", true}}) {
    asio::io_context io;
    ssl::context context(ssl::context::tlsv12_client);
    context.load_verify_file(ca);
    SSL_CTX_set_max_proto_version(context.native_handle(), TLS1_2_VERSION);
    ASSERT_EQ(SSL_CTX_set_cipher_list(context.native_handle(), suites.c_str()), 1);
    beast::ssl_stream<tcp::socket> stream(io, context);
    beast::error_code error;
    stream.next_layer().connect(
        tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port_)), error);
    ASSERT_FALSE(error);
    stream.handshake(ssl::stream_base::client, error);
    EXPECT_EQ(!error, served) << suites << ": " << error.message();
  }
  // Plain HTTP on the TLS port gets no answer.
  EXPECT_TRUE(Request(port_, list).failed || Request(port_, list).status == 0);
}

TEST_F(HttpFrontTest, FollowRelaysALiveJobOverAWebSocket) {
  BodyFollower::Mesh();
  ASSERT_NO_FATAL_FAILURE(Start());
  IngestClient ingest(*t_->ingest);
  ASSERT_TRUE(ingest.Open(MakeOpenTake("take-1", "daemon-a", 1)));
  ASSERT_TRUE(ingest.ReadOpened().has_value());
  grpc::ClientContext context;
  v1::SubmitJobRequest submit;
  submit.set_take_id("take-1");
  submit.set_method("body");
  submit.set_live(true);
  v1::Job job;
  ASSERT_TRUE(v1::Jobs::NewStub(t_->channel)->Submit(&context, submit, &job).ok());

  const Reply live = Request(port_, "/api/v1/jobs?live=1");
  ASSERT_EQ(live.status, 200) << live.body;
  ASSERT_EQ(live.Json().size(), 1u) << live.body;
  EXPECT_EQ(live.Json()[0]["id"], job.job_id());
  EXPECT_EQ(live.Json()[0]["live"], true);
  EXPECT_EQ(live.Json()[0]["state"], "running");

  constexpr uint64_t kSets = 10;
  FollowReply follow;
  std::thread reader(
      [&] { follow = FollowOverWebSocket(port_, "/api/v1/jobs/" + job.job_id() + "/follow"); });
  // Frame sets once the socket is subscribed: the follow starts with the
  // mesh of the first set, so the sets go in after a pause.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  for (uint64_t s = 1; s <= kSets; ++s) {
    ASSERT_TRUE(ingest.SendSet(MakeFrameSet(s, SensorIds(1))));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(ingest.WaitAck(kSets));
  ASSERT_TRUE(ingest.Close(kSets));
  ASSERT_TRUE(ingest.Finish().ok());
  reader.join();

  ASSERT_TRUE(follow.upgraded);
  ASSERT_GE(follow.texts.size(), 3u);
  EXPECT_EQ(follow.texts.front()["type"], "mesh") << follow.texts.front().dump();
  ASSERT_EQ(follow.binaries.size(), 1u);
  const std::string& glb = follow.binaries.front();
  EXPECT_EQ(follow.texts.front()["bytes"], glb.size());
  ASSERT_GE(glb.size(), 20u);
  EXPECT_EQ(glb.substr(0, 4), "glTF");
  EXPECT_NE(glb.find("\"skins\""), std::string::npos);
  EXPECT_NE(glb.find("\"SpineBase\""), std::string::npos);
  int frames = 0;
  for (size_t i = 1; i + 1 < follow.texts.size(); ++i) {
    const json& frame = follow.texts[i];
    ASSERT_EQ(frame["type"], "frame") << frame.dump();
    EXPECT_EQ(frame["local_rotations"].size(), 25u);
    EXPECT_EQ(frame["joints_m"].size(), 25u);
    EXPECT_GT(frame["arrived_unix_ns"].get<int64_t>(), 0);
    EXPECT_GE(frame["published_unix_ns"].get<int64_t>(), frame["arrived_unix_ns"].get<int64_t>());
    EXPECT_GE(frame["sent_unix_ns"].get<int64_t>(), frame["published_unix_ns"].get<int64_t>());
    // The root joint's rest position plus the fitted translation (x + 0.5).
    EXPECT_GT(frame["root_position_m"][0].get<double>(), 0.4);
    ++frames;
  }
  const json& end = follow.texts.back();
  EXPECT_EQ(end["type"], "end") << end.dump();
  EXPECT_EQ(end["reason"], "take_complete");
  // Subscribed before the first set: every fitted frame reached the socket
  // (a fit that falls behind skips sets, so not necessarily all 10).
  EXPECT_GE(frames, 1);
  EXPECT_EQ(end["frames_followed"].get<int>(), frames) << end.dump();
  EXPECT_EQ(end["frames_received"].get<int>(), static_cast<int>(kSets)) << end.dump();
  EXPECT_EQ(follow.close_code, 1000);

  // Refusals come before any socket is accepted, as plain HTTP answers.
  const auto upgrade = [&](const std::string& target, const std::string& origin) {
    std::vector<std::pair<std::string, std::string>> headers = {
        {"Connection", "Upgrade"},
        {"Upgrade", "websocket"},
        {"Sec-WebSocket-Version", "13"},
        {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}};
    if (!origin.empty()) headers.emplace_back("Origin", origin);
    return Request(port_, target, headers);
  };
  // An unknown job: 404.
  const Reply unknown = upgrade("/api/v1/jobs/j-20990101-000000-none/follow", "");
  EXPECT_EQ(unknown.status, 404) << unknown.body;
  EXPECT_EQ(unknown.Json()["error"]["code"], "NOT_FOUND");
  // A page of another origin may not follow a job, even one that exists.
  const Reply elsewhere =
      upgrade("/api/v1/jobs/" + job.job_id() + "/follow", "http://evil.example");
  EXPECT_EQ(elsewhere.status, 403) << elsewhere.body;
  EXPECT_EQ(elsewhere.Json()["error"]["code"], "PERMISSION_DENIED");
  const FollowReply same_origin =
      FollowOverWebSocket(port_, "/api/v1/jobs/" + job.job_id() + "/follow",
                          "http://127.0.0.1:" + std::to_string(port_));
  EXPECT_TRUE(same_origin.upgraded);
}

TEST_F(HttpFrontTest, WithoutTokensOnlyRequestsAddressedToThisMachineAreServed) {
  ASSERT_NO_FATAL_FAILURE(Start());
  // DNS rebinding: a page of evil.example whose name now points here.
  const Reply rebound = Request(port_, "/api/v1/reenactments", {{"Host", "evil.example"}});
  EXPECT_EQ(rebound.status, 421) << rebound.body;
  EXPECT_EQ(rebound.Json()["error"]["code"], "PERMISSION_DENIED");
  EXPECT_EQ(Request(port_, "/api/v1/info", {{"Host", "localhost:" + std::to_string(port_)}}).status,
            200);
  EXPECT_EQ(Request(port_, "/api/v1/info", {{"Host", "[::1]:8080"}}).status, 200);
  // A tablet on the network that uses the machine's address (no name to
  // rebind).
  EXPECT_EQ(Request(port_, "/api/v1/info", {{"Host", "192.168.1.20:8443"}}).status, 200);
  // Plain HTTP: no HSTS.
  EXPECT_EQ(Request(port_, "/api/v1/info").Header("Strict-Transport-Security"), "");
}

TEST_F(HttpFrontTest, OneClientCannotTakeEverySlotAndRefusalsAreLoggedSparingly) {
  HttpFrontOptions front;
  front.max_connections = 8;
  front.max_connections_per_client = 2;
  ASSERT_NO_FATAL_FAILURE(Start({}, front));
  asio::io_context io;
  const tcp::endpoint endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port_));
  // Two idle connections from 127.0.0.1 fill its share.
  tcp::socket first(io), second(io);
  first.connect(endpoint);
  second.connect(endpoint);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ::testing::internal::CaptureStderr();
  int refused = 0;
  for (int i = 0; i < 20; ++i) refused += Request(port_, "/api/v1/info").failed ? 1 : 0;
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(refused, 20);
  // One line for the twenty refusals (one per kRefusalLogPeriodS).
  size_t lines = 0;
  for (size_t at = log.find("limit_hit"); at != std::string::npos;
       at = log.find("limit_hit", at + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, 1u) << log;
  EXPECT_NE(log.find("http_connections_per_client"), std::string::npos) << log;
  // Another client (another loopback address) is served.
  tcp::socket other(io);
  beast::error_code error;
  other.open(tcp::v4(), error);
  ASSERT_FALSE(error) << error.message();
  other.bind(tcp::endpoint(asio::ip::make_address("127.0.0.2"), 0), error);
  ASSERT_FALSE(error) << error.message();
  other.connect(endpoint, error);
  ASSERT_FALSE(error) << error.message();
  bhttp::request<bhttp::empty_body> request{bhttp::verb::get, "/api/v1/info", 11};
  request.set(bhttp::field::host, "127.0.0.1");
  bhttp::write(other, request, error);
  ASSERT_FALSE(error) << error.message();
  beast::flat_buffer buffer;
  bhttp::response<bhttp::string_body> response;
  bhttp::read(other, buffer, response, error);
  ASSERT_FALSE(error) << error.message();
  EXPECT_EQ(response.result_int(), 200u);
}

TEST_F(HttpFrontTest, ConnectionsPastTheCapAreClosedAndStopEndsIdleOnes) {
  HttpFrontOptions front;
  front.max_connections = 2;
  ASSERT_NO_FATAL_FAILURE(Start({}, front));
  asio::io_context io;
  const tcp::endpoint endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port_));
  tcp::socket first(io), second(io);
  first.connect(endpoint);
  second.connect(endpoint);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // The third gets no answer; once one closes, a new one is served.
  const Reply refused = Request(port_, "/api/v1/info");
  EXPECT_TRUE(refused.failed) << refused.status;
  first.close();
  Reply served;
  for (int i = 0; i < 50 && served.status != 200; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    served = Request(port_, "/api/v1/info");
  }
  EXPECT_EQ(served.status, 200);
  const auto started = std::chrono::steady_clock::now();
  front_->Stop();
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(5));
}

}  // namespace
}  // namespace reenact::server::http
