#include "server/store/catalog.h"

#include <sqlite3.h>

#include <iterator>
#include <optional>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/json_text.h"
#include "common/base/status_macros.h"

namespace reenact::server {
namespace {

// Schema steps: kMigrations[v] takes a catalog from version v to v + 1.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE takes (
  take_id TEXT PRIMARY KEY NOT NULL,
  name TEXT NOT NULL,
  state TEXT NOT NULL CHECK (state IN ('recording', 'complete', 'interrupted')),
  daemon_id TEXT NOT NULL,
  created_unix_ns INTEGER NOT NULL,
  updated_unix_ns INTEGER NOT NULL,
  durable_sequence INTEGER NOT NULL,
  frame_set_count INTEGER NOT NULL,
  first_stamp_ns INTEGER NOT NULL,
  last_stamp_ns INTEGER NOT NULL,
  duration_ns INTEGER NOT NULL,
  size_bytes INTEGER NOT NULL,
  path TEXT NOT NULL,
  generator TEXT NOT NULL,
  synthetic INTEGER NOT NULL,
  fps REAL NOT NULL);
CREATE INDEX takes_by_created ON takes (created_unix_ns);
CREATE INDEX takes_by_state ON takes (state);
CREATE TABLE sensors (
  take_id TEXT NOT NULL REFERENCES takes (take_id) ON DELETE CASCADE,
  sensor_id TEXT NOT NULL,
  model TEXT NOT NULL,
  frame_count INTEGER NOT NULL,
  lost_stamp_ns INTEGER NOT NULL,
  lost_reason TEXT NOT NULL,
  PRIMARY KEY (take_id, sensor_id));
)sql",
    // Version 2: the job queue (server/jobs/job_store.h).
    R"sql(
CREATE TABLE jobs (
  job_id TEXT PRIMARY KEY NOT NULL,
  take_id TEXT NOT NULL,
  method TEXT NOT NULL,
  options_json TEXT NOT NULL,
  state TEXT NOT NULL
    CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
  stage TEXT NOT NULL,
  fraction REAL NOT NULL,
  frames_done INTEGER NOT NULL,
  frames_total INTEGER NOT NULL,
  eta_s REAL NOT NULL,
  submitted_unix_ns INTEGER NOT NULL,
  started_unix_ns INTEGER NOT NULL,
  finished_unix_ns INTEGER NOT NULL,
  reenactment_id TEXT NOT NULL,
  error TEXT NOT NULL,
  attempts INTEGER NOT NULL);
CREATE INDEX jobs_by_submitted ON jobs (submitted_unix_ns);
CREATE INDEX jobs_by_state ON jobs (state);
)sql",
    // Version 3: the credential that created a take (common/rpc/auth.h);
    // takes from before tokens belong to the anonymous caller.
    R"sql(
ALTER TABLE takes ADD COLUMN owner TEXT NOT NULL DEFAULT '';
)sql",
    // Version 4: each job's attempts, where they ran and how they ended
    // (a JSON list, AttemptsToJson).
    R"sql(
ALTER TABLE jobs ADD COLUMN attempts_json TEXT NOT NULL DEFAULT '[]';
)sql",
    // Version 5: segmented jobs, one take split across several workers: the
    // number of segments and the job's parts (a JSON list, PartsToJson).
    R"sql(
ALTER TABLE jobs ADD COLUMN segments INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN parts_json TEXT NOT NULL DEFAULT '[]';
)sql",
    // Version 6: the credential that submitted each job (Job.submitted_by);
    // jobs from before belong to the anonymous caller.
    R"sql(
ALTER TABLE jobs ADD COLUMN submitted_by TEXT NOT NULL DEFAULT '';
)sql",
};
static_assert(std::size(kMigrations) == Catalog::kSchemaVersion);

// A job's options as a JSON object of strings, and back (a malformed text
// gives no options rather than failing the whole listing).
std::string OptionsToJson(const google::protobuf::Map<std::string, std::string>& options) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, value] : options) j[key] = value;
  return JsonText(j);
}

void OptionsFromJson(const std::string& text,
                     google::protobuf::Map<std::string, std::string>* out) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) return;
  for (const auto& [key, value] : j.items()) {
    (*out)[key] = value.is_string() ? value.get<std::string>() : JsonText(value);
  }
}

std::string AttemptsToJson(const google::protobuf::RepeatedPtrField<v1::JobAttempt>& attempts) {
  nlohmann::json j = nlohmann::json::array();
  for (const v1::JobAttempt& a : attempts) {
    j.push_back({{"number", a.number()},
                 {"worker", a.worker()},
                 {"started_unix_ns", a.started_unix_ns()},
                 {"ended_unix_ns", a.ended_unix_ns()},
                 {"outcome", a.outcome()},
                 {"read_bytes", a.read_bytes()}});
  }
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

// Leaves out what is not a list of objects (a row written by hand).
void AttemptsFromJson(const std::string& text,
                      google::protobuf::RepeatedPtrField<v1::JobAttempt>* out) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_array()) return;
  for (const nlohmann::json& a : j) {
    if (!a.is_object()) continue;
    v1::JobAttempt* attempt = out->Add();
    attempt->set_number(a.value("number", 0));
    attempt->set_worker(a.value("worker", ""));
    attempt->set_started_unix_ns(a.value("started_unix_ns", int64_t{0}));
    attempt->set_ended_unix_ns(a.value("ended_unix_ns", int64_t{0}));
    attempt->set_outcome(a.value("outcome", ""));
    attempt->set_read_bytes(a.value("read_bytes", int64_t{0}));
  }
}

std::string PartsToJson(const google::protobuf::RepeatedPtrField<v1::JobPart>& parts) {
  nlohmann::json j = nlohmann::json::array();
  for (const v1::JobPart& p : parts) {
    j.push_back(
        {{"name", p.name()},
         {"state", p.state() == v1::JOB_STATE_UNSPECIFIED ? std::string("waiting")
                                                          : std::string(JobStateName(p.state()))},
         {"attempts", p.attempts()},
         {"attempt_history", nlohmann::json::parse(AttemptsToJson(p.attempt_history()))},
         {"fraction", p.fraction()},
         {"stage", p.stage()},
         {"file_bytes", p.file_bytes()}});
  }
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

// Leaves out what is not a list of objects (a row written by hand).
void PartsFromJson(const std::string& text, google::protobuf::RepeatedPtrField<v1::JobPart>* out) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_array()) return;
  for (const nlohmann::json& p : j) {
    if (!p.is_object()) continue;
    v1::JobPart* part = out->Add();
    part->set_name(p.value("name", ""));
    part->set_state(JobStateFromName(p.value("state", "")).value_or(v1::JOB_STATE_UNSPECIFIED));
    part->set_attempts(p.value("attempts", 0));
    if (const auto history = p.find("attempt_history"); history != p.end()) {
      AttemptsFromJson(history->dump(), part->mutable_attempt_history());
    }
    part->set_fraction(p.value("fraction", 0.0));
    part->set_stage(p.value("stage", ""));
    part->set_file_bytes(p.value("file_bytes", int64_t{0}));
  }
}

// A prepared statement, finalized on destruction.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql) : db_(db) {
    rc_ = sqlite3_prepare_v2(db, sql.c_str(), static_cast<int>(sql.size()), &stmt_, nullptr);
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  bool ok() const { return rc_ == SQLITE_OK || rc_ == SQLITE_ROW || rc_ == SQLITE_DONE; }
  Statement& Bind(int i, std::string_view text) {
    if (ok()) {
      rc_ =
          sqlite3_bind_text(stmt_, i, text.data(), static_cast<int>(text.size()), SQLITE_TRANSIENT);
    }
    return *this;
  }
  Statement& Bind(int i, int64_t value) {
    if (ok()) rc_ = sqlite3_bind_int64(stmt_, i, value);
    return *this;
  }
  Statement& Bind(int i, double value) {
    if (ok()) rc_ = sqlite3_bind_double(stmt_, i, value);
    return *this;
  }
  // True while rows come; false at the end or on error (see ok()).
  bool Step() {
    if (!ok()) return false;
    rc_ = sqlite3_step(stmt_);
    return rc_ == SQLITE_ROW;
  }
  int64_t Int(int column) const { return sqlite3_column_int64(stmt_, column); }
  double Double(int column) const { return sqlite3_column_double(stmt_, column); }
  std::string Text(int column) const {
    const auto* text = sqlite3_column_text(stmt_, column);
    return text == nullptr ? std::string()
                           : std::string(reinterpret_cast<const char*>(text),
                                         static_cast<size_t>(sqlite3_column_bytes(stmt_, column)));
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  int rc_ = SQLITE_OK;
};

constexpr const char* kTakeColumns =
    "take_id, name, state, daemon_id, created_unix_ns, updated_unix_ns, durable_sequence, "
    "frame_set_count, first_stamp_ns, last_stamp_ns, duration_ns, size_bytes, path, generator, "
    "synthetic, fps, owner";

TakeRow RowFromStatement(const Statement& s) {
  TakeRow row;
  v1::Take& t = row.take;
  t.set_take_id(s.Text(0));
  t.set_name(s.Text(1));
  t.set_state(TakeStateFromName(s.Text(2)).value_or(v1::TAKE_STATE_UNSPECIFIED));
  t.set_daemon_id(s.Text(3));
  t.set_created_unix_ns(s.Int(4));
  t.set_updated_unix_ns(s.Int(5));
  t.set_durable_sequence(static_cast<uint64_t>(s.Int(6)));
  t.set_frame_set_count(s.Int(7));
  row.first_stamp_ns = s.Int(8);
  row.last_stamp_ns = s.Int(9);
  t.set_duration_ns(s.Int(10));
  t.set_size_bytes(s.Int(11));
  row.path = s.Text(12);
  t.set_generator(s.Text(13));
  t.set_synthetic(s.Int(14) != 0);
  t.set_fps(s.Double(15));
  row.owner = s.Text(16);
  return row;
}

constexpr const char* kJobColumns =
    "job_id, take_id, method, options_json, state, stage, fraction, frames_done, frames_total, "
    "eta_s, submitted_unix_ns, started_unix_ns, finished_unix_ns, reenactment_id, error, attempts, "
    "attempts_json, segments, parts_json, submitted_by";

v1::Job JobFromStatement(const Statement& s) {
  v1::Job job;
  job.set_job_id(s.Text(0));
  job.set_take_id(s.Text(1));
  job.set_method(s.Text(2));
  OptionsFromJson(s.Text(3), job.mutable_options());
  job.set_state(JobStateFromName(s.Text(4)).value_or(v1::JOB_STATE_UNSPECIFIED));
  v1::JobProgress* p = job.mutable_progress();
  p->set_stage(s.Text(5));
  p->set_fraction(s.Double(6));
  p->set_frames_done(s.Int(7));
  p->set_frames_total(s.Int(8));
  p->set_eta_s(s.Double(9));
  job.set_submitted_unix_ns(s.Int(10));
  job.set_started_unix_ns(s.Int(11));
  job.set_finished_unix_ns(s.Int(12));
  job.set_reenactment_id(s.Text(13));
  job.set_error(s.Text(14));
  job.set_attempts(static_cast<int32_t>(s.Int(15)));
  AttemptsFromJson(s.Text(16), job.mutable_attempt_history());
  job.set_segments(static_cast<int32_t>(s.Int(17)));
  PartsFromJson(s.Text(18), job.mutable_parts());
  job.set_submitted_by(s.Text(19));
  return job;
}

}  // namespace

absl::StatusOr<std::unique_ptr<Catalog>> Catalog::Open(const std::string& path) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(
      path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string message = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    sqlite3_close(db);
    return absl::UnavailableError(absl::StrCat("cannot open catalog ", path, ": ", message));
  }
  std::unique_ptr<Catalog> catalog(new Catalog(path, db));
  sqlite3_busy_timeout(db, 5000);
  RETURN_IF_ERROR(catalog->Exec("PRAGMA foreign_keys = ON; PRAGMA synchronous = FULL;"));
  ASSIGN_OR_RETURN(const std::string mode, [&]() -> absl::StatusOr<std::string> {
    Statement s(db, "PRAGMA journal_mode = WAL");
    if (!s.Step()) return catalog->Error("PRAGMA journal_mode = WAL");
    return s.Text(0);
  }());
  if (mode != "wal") {
    return absl::UnavailableError(
        absl::StrCat("catalog ", path, ": WAL journal refused (journal_mode is ", mode, ")"));
  }
  RETURN_IF_ERROR(catalog->Migrate());
  return catalog;
}

Catalog::~Catalog() { sqlite3_close(db_); }

absl::Status Catalog::Error(const std::string& what) const {
  const int code = sqlite3_errcode(db_);
  const std::string message =
      absl::StrCat("catalog ", path_, ": ", what, ": ", sqlite3_errmsg(db_));
  if (code == SQLITE_NOTADB || code == SQLITE_CORRUPT) return absl::DataLossError(message);
  // The wording of FileError (common/base/files.h), so IsDiskFull knows it.
  if (code == SQLITE_FULL)
    return absl::ResourceExhaustedError(absl::StrCat(message, " (disk full)"));
  return absl::UnavailableError(message);
}

absl::Status Catalog::Exec(const std::string& sql) const {
  char* error = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string message = error != nullptr ? error : "unknown error";
    sqlite3_free(error);
    const int code = sqlite3_errcode(db_);
    const std::string text = absl::StrCat("catalog ", path_, ": ", message);
    if (code == SQLITE_NOTADB || code == SQLITE_CORRUPT) return absl::DataLossError(text);
    return absl::UnavailableError(text);
  }
  return absl::OkStatus();
}

absl::Status Catalog::Migrate() {
  ASSIGN_OR_RETURN(const int version, SchemaVersion());
  if (version > kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat("catalog ", path_, " has schema version ",
                                                      version, ", newer than this server's ",
                                                      kSchemaVersion));
  }
  for (int v = version; v < kSchemaVersion; ++v) {
    RETURN_IF_ERROR(Exec(absl::StrCat("BEGIN IMMEDIATE;", kMigrations[v],
                                      "PRAGMA user_version = ", v + 1, "; COMMIT;")));
  }
  return absl::OkStatus();
}

absl::StatusOr<int> Catalog::SchemaVersion() const {
  std::lock_guard<std::mutex> lock(mu_);
  Statement s(db_, "PRAGMA user_version");
  if (!s.Step()) return Error("PRAGMA user_version");
  return static_cast<int>(s.Int(0));
}

absl::StatusOr<std::string> Catalog::JournalMode() const {
  std::lock_guard<std::mutex> lock(mu_);
  Statement s(db_, "PRAGMA journal_mode");
  if (!s.Step()) return Error("PRAGMA journal_mode");
  return s.Text(0);
}

absl::Status Catalog::Put(const TakeRow& row) {
  std::lock_guard<std::mutex> lock(mu_);
  const v1::Take& t = row.take;
  RETURN_IF_ERROR(Exec("BEGIN IMMEDIATE"));
  auto fail = [&](const std::string& what) {
    absl::Status status = Error(what);
    Exec("ROLLBACK").IgnoreError();
    return status;
  };
  {
    Statement s(db_, absl::StrCat("INSERT OR REPLACE INTO takes (", kTakeColumns,
                                  ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, "
                                  "?13, ?14, ?15, ?16, ?17)"));
    s.Bind(1, t.take_id())
        .Bind(2, t.name())
        .Bind(3, TakeStateName(t.state()))
        .Bind(4, t.daemon_id())
        .Bind(5, t.created_unix_ns())
        .Bind(6, t.updated_unix_ns())
        .Bind(7, static_cast<int64_t>(t.durable_sequence()))
        .Bind(8, t.frame_set_count())
        .Bind(9, row.first_stamp_ns)
        .Bind(10, row.last_stamp_ns)
        .Bind(11, t.duration_ns())
        .Bind(12, t.size_bytes())
        .Bind(13, row.path)
        .Bind(14, t.generator())
        .Bind(15, int64_t{t.synthetic() ? 1 : 0})
        .Bind(16, t.fps())
        .Bind(17, row.owner);
    s.Step();
    if (!s.ok()) return fail("storing take " + t.take_id());
  }
  {
    // INSERT OR REPLACE deleted the old takes row, and the cascade its sensors.
    Statement s(db_, "DELETE FROM sensors WHERE take_id = ?1");
    s.Bind(1, t.take_id()).Step();
    if (!s.ok()) return fail("clearing sensors of " + t.take_id());
  }
  for (const v1::TakeSensor& sensor : t.sensors()) {
    Statement s(db_,
                "INSERT INTO sensors (take_id, sensor_id, model, frame_count, lost_stamp_ns, "
                "lost_reason) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    s.Bind(1, t.take_id())
        .Bind(2, sensor.sensor_id())
        .Bind(3, sensor.model())
        .Bind(4, sensor.frame_count())
        .Bind(5, sensor.lost_stamp_ns())
        .Bind(6, sensor.lost_reason())
        .Step();
    if (!s.ok()) return fail("storing sensor " + sensor.sensor_id() + " of " + t.take_id());
  }
  return Exec("COMMIT");
}

absl::Status Catalog::LoadSensors(TakeRow* row) const {
  Statement s(db_,
              "SELECT sensor_id, model, frame_count, lost_stamp_ns, lost_reason FROM sensors "
              "WHERE take_id = ?1 ORDER BY sensor_id");
  s.Bind(1, row->take.take_id());
  while (s.Step()) {
    v1::TakeSensor* sensor = row->take.add_sensors();
    sensor->set_sensor_id(s.Text(0));
    sensor->set_model(s.Text(1));
    sensor->set_frame_count(s.Int(2));
    sensor->set_lost_stamp_ns(s.Int(3));
    sensor->set_lost_reason(s.Text(4));
  }
  if (!s.ok()) return Error("reading sensors of " + row->take.take_id());
  return absl::OkStatus();
}

absl::StatusOr<std::vector<TakeRow>> Catalog::Query(const std::string& where,
                                                    std::optional<std::string_view> arg) const {
  std::vector<TakeRow> rows;
  Statement s(db_, absl::StrCat("SELECT ", kTakeColumns, " FROM takes ", where,
                                " ORDER BY created_unix_ns DESC, take_id DESC"));
  if (arg) s.Bind(1, *arg);
  while (s.Step()) rows.push_back(RowFromStatement(s));
  if (!s.ok()) return Error("listing takes");
  for (TakeRow& row : rows) RETURN_IF_ERROR(LoadSensors(&row));
  return rows;
}

absl::StatusOr<TakeRow> Catalog::Get(std::string_view take_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  ASSIGN_OR_RETURN(std::vector<TakeRow> rows, Query("WHERE take_id = ?1", take_id));
  if (rows.empty()) {
    return absl::NotFoundError(absl::StrCat("no take \"", std::string(take_id), "\""));
  }
  return std::move(rows.front());
}

absl::StatusOr<std::vector<TakeRow>> Catalog::List(v1::TakeState state) const {
  std::lock_guard<std::mutex> lock(mu_);
  if (state == v1::TAKE_STATE_UNSPECIFIED) return Query("", std::nullopt);
  return Query("WHERE state = ?1", TakeStateName(state));
}

absl::Status Catalog::Delete(std::string_view take_id) {
  std::lock_guard<std::mutex> lock(mu_);
  Statement s(db_, "DELETE FROM takes WHERE take_id = ?1");
  s.Bind(1, take_id).Step();
  if (!s.ok()) return Error(absl::StrCat("deleting take ", std::string(take_id)));
  if (sqlite3_changes(db_) == 0) {
    return absl::NotFoundError(absl::StrCat("no take \"", std::string(take_id), "\""));
  }
  return absl::OkStatus();
}

absl::Status Catalog::DeleteJob(std::string_view job_id) {
  std::lock_guard<std::mutex> lock(mu_);
  Statement s(db_, "DELETE FROM jobs WHERE job_id = ?1");
  s.Bind(1, job_id).Step();
  if (!s.ok()) return Error(absl::StrCat("deleting job ", std::string(job_id)));
  if (sqlite3_changes(db_) == 0) {
    return absl::NotFoundError(absl::StrCat("no job \"", std::string(job_id), "\""));
  }
  return absl::OkStatus();
}

absl::Status Catalog::PutJob(const v1::Job& job) {
  if (JobStateName(job.state()) == "unspecified") {
    return absl::InvalidArgumentError(
        absl::StrCat("job ", job.job_id(), " has no valid state (", job.state(), ")"));
  }
  std::lock_guard<std::mutex> lock(mu_);
  const v1::JobProgress& p = job.progress();
  Statement s(db_, absl::StrCat("INSERT OR REPLACE INTO jobs (", kJobColumns,
                                ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, "
                                "?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20)"));
  s.Bind(1, job.job_id())
      .Bind(2, job.take_id())
      .Bind(3, job.method())
      .Bind(4, OptionsToJson(job.options()))
      .Bind(5, JobStateName(job.state()))
      .Bind(6, p.stage())
      .Bind(7, p.fraction())
      .Bind(8, p.frames_done())
      .Bind(9, p.frames_total())
      .Bind(10, p.eta_s())
      .Bind(11, job.submitted_unix_ns())
      .Bind(12, job.started_unix_ns())
      .Bind(13, job.finished_unix_ns())
      .Bind(14, job.reenactment_id())
      .Bind(15, job.error())
      .Bind(16, int64_t{job.attempts()})
      .Bind(17, AttemptsToJson(job.attempt_history()))
      .Bind(18, int64_t{job.segments()})
      .Bind(19, PartsToJson(job.parts()))
      .Bind(20, job.submitted_by());
  s.Step();
  if (!s.ok()) return Error("storing job " + job.job_id());
  return absl::OkStatus();
}

absl::StatusOr<std::vector<v1::Job>> Catalog::QueryJobs(const std::string& where,
                                                        std::optional<std::string_view> arg) const {
  std::vector<v1::Job> jobs;
  Statement s(db_, absl::StrCat("SELECT ", kJobColumns, " FROM jobs ", where,
                                " ORDER BY submitted_unix_ns DESC, job_id DESC"));
  if (arg) s.Bind(1, *arg);
  while (s.Step()) jobs.push_back(JobFromStatement(s));
  if (!s.ok()) return Error("listing jobs");
  return jobs;
}

absl::StatusOr<v1::Job> Catalog::GetJob(std::string_view job_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  ASSIGN_OR_RETURN(std::vector<v1::Job> jobs, QueryJobs("WHERE job_id = ?1", job_id));
  if (jobs.empty())
    return absl::NotFoundError(absl::StrCat("no job \"", std::string(job_id), "\""));
  return std::move(jobs.front());
}

absl::StatusOr<std::vector<v1::Job>> Catalog::ListJobs() const {
  std::lock_guard<std::mutex> lock(mu_);
  return QueryJobs("", std::nullopt);
}

}  // namespace reenact::server
