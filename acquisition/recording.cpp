#include "acquisition/recording.h"

#include <sqlite3.h>
#include <unistd.h>
#include <zlib.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "acquisition/format_error.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little, "the payload codec assumes a little-endian host");

// The schema of docs/recordings.md. Poses are 16 REAL columns (not JSON) so that they round-trip bit for bit
// and can be queried with the stock sqlite3 tool.
constexpr const char* kSchema = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE device(id INTEGER PRIMARY KEY CHECK (id = 1), description TEXT NOT NULL, calibration TEXT NOT NULL);
CREATE TABLE streams(id INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE,
                     kind TEXT NOT NULL CHECK (kind IN ('points', 'depth', 'profile')),
                     encoding TEXT NOT NULL, units TEXT NOT NULL);
CREATE TABLE frames(id INTEGER PRIMARY KEY, stream INTEGER NOT NULL REFERENCES streams(id), timestamp_ns INTEGER,
                    view INTEGER NOT NULL, compression TEXT NOT NULL, payload BLOB NOT NULL);
CREATE INDEX frames_by_view ON frames(stream, view);
CREATE TABLE poses(frame INTEGER PRIMARY KEY REFERENCES frames(id),
                   m00 REAL NOT NULL, m01 REAL NOT NULL, m02 REAL NOT NULL, m03 REAL NOT NULL,
                   m10 REAL NOT NULL, m11 REAL NOT NULL, m12 REAL NOT NULL, m13 REAL NOT NULL,
                   m20 REAL NOT NULL, m21 REAL NOT NULL, m22 REAL NOT NULL, m23 REAL NOT NULL,
                   m30 REAL NOT NULL, m31 REAL NOT NULL, m32 REAL NOT NULL, m33 REAL NOT NULL,
                   turntable_angle_rad REAL);
)sql";

constexpr std::array<const char*, 5> kTables = {"meta", "device", "streams", "frames", "poses"};

// SQLite's message, with the reason of an I/O failure (a full disk, a file-size limit, a device gone): "disk
// I/O error" alone does not tell the user what to do. SQLite keeps the operating system's error only for some
// failures (a write that hits a full disk or a file-size limit is reported as a short write, errno 0).
std::string SqliteProblem(sqlite3* db) {
  std::string text = sqlite3_errmsg(db);
  const int system_error = sqlite3_system_errno(db);
  const int extended = sqlite3_extended_errcode(db);
  if (system_error != 0 && ((extended & 0xff) == SQLITE_IOERR || (extended & 0xff) == SQLITE_CANTOPEN)) {
    text += " (" + std::string(std::strerror(system_error)) + ")";
  } else if (extended == SQLITE_IOERR_WRITE || extended == SQLITE_IOERR_FSYNC || extended == SQLITE_FULL) {
    text += " (writing failed: the disk is full, a file-size limit was reached or the device is gone)";
  }
  return text;
}

struct Connection {
  sqlite3* db = nullptr;
  std::string file;
  ~Connection() {
    if (db) sqlite3_close_v2(db);
  }
  [[noreturn]] void Fail(const std::string& what) const {
    throw FormatError(file, "", what + ": " + (db ? SqliteProblem(db) : std::string("out of memory")));
  }
  void Exec(const char* sql) const {
    char* message = nullptr;
    if (sqlite3_exec(db, sql, nullptr, nullptr, &message) != SQLITE_OK) {
      std::string text = message ? message : sqlite3_errmsg(db);
      sqlite3_free(message);
      if ((sqlite3_errcode(db) & 0xff) == SQLITE_IOERR || sqlite3_errcode(db) == SQLITE_FULL)
        text = SqliteProblem(db);
      throw FormatError(file, "", text);
    }
  }
};

// A prepared statement, finalized on every path.
class Statement {
 public:
  Statement(const Connection& c, const std::string& sql) : c_(c) {
    if (sqlite3_prepare_v2(c.db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK)
      c.Fail("cannot prepare query");
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Bind(int i, std::int64_t v) { return Check(sqlite3_bind_int64(stmt_, i, v)); }
  Statement& Bind(int i, double v) { return Check(sqlite3_bind_double(stmt_, i, v)); }
  Statement& Bind(int i, const std::string& v) {
    return Check(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
  }
  Statement& Bind(int i, const std::vector<std::uint8_t>& v) {
    // A zero-length blob must still be a BLOB, not NULL: bind a valid pointer.
    static const std::uint8_t empty = 0;
    return Check(sqlite3_bind_blob64(stmt_, i, v.empty() ? &empty : v.data(), v.size(), SQLITE_TRANSIENT));
  }
  Statement& BindNull(int i) { return Check(sqlite3_bind_null(stmt_, i)); }

  // True while there is a row.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    c_.Fail("query failed");
  }
  void Run() {
    while (Step()) {
    }
  }
  bool IsNull(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  int Type(int col) const { return sqlite3_column_type(stmt_, col); }
  std::int64_t Int(int col) const { return sqlite3_column_int64(stmt_, col); }
  double Real(int col) const { return sqlite3_column_double(stmt_, col); }
  std::string Text(int col) const {
    const unsigned char* t = sqlite3_column_text(stmt_, col);
    return t ? std::string(reinterpret_cast<const char*>(t),
                           static_cast<std::size_t>(sqlite3_column_bytes(stmt_, col)))
             : std::string();
  }
  std::vector<std::uint8_t> Blob(int col) const {
    const auto* b = static_cast<const std::uint8_t*>(sqlite3_column_blob(stmt_, col));
    const auto n = static_cast<std::size_t>(sqlite3_column_bytes(stmt_, col));
    return b ? std::vector<std::uint8_t>(b, b + n) : std::vector<std::uint8_t>();
  }

 private:
  Statement& Check(int rc) {
    if (rc != SQLITE_OK) c_.Fail("cannot bind a query parameter");
    return *this;
  }
  const Connection& c_;
  sqlite3_stmt* stmt_ = nullptr;
};

void CheckPose(const Eigen::Matrix4d& m, const std::function<void(const std::string&)>& fail) {
  if (!m.allFinite()) fail("world_T_scan is not finite");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 || r.determinant() < 0 ||
      m.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
    fail("world_T_scan is not a rigid motion (rotation not orthonormal or last row not 0 0 0 1)");
  }
}

bool ValidKind(const std::string& kind) {
  return kind == "points" || kind == "depth" || kind == "profile";
}

}  // namespace

// ---------------------------------------------------------------------------------------------------- writer

struct RecordingWriter::Db : Connection {};

RecordingWriter::RecordingWriter(fs::path path, std::unique_ptr<Db> db)
    : path_(std::move(path)), db_(std::move(db)) {}
RecordingWriter::RecordingWriter(RecordingWriter&&) noexcept = default;
RecordingWriter& RecordingWriter::operator=(RecordingWriter&&) noexcept = default;
RecordingWriter::~RecordingWriter() {
  try {
    Close();
  } catch (...) {  // a destructor must not throw; the data committed so far are safe either way
  }
}

RecordingWriter RecordingWriter::Create(const fs::path& path) {
  const std::string file = path.string();
  if (fs::exists(path)) throw FormatError(file, "", "exists already; a recording is never overwritten");
  auto db = std::make_unique<Db>();
  db->file = file;
  if (sqlite3_open_v2(file.c_str(), &db->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) !=
      SQLITE_OK) {
    // SQLite's own errno is that of its last attempt (a read-only open: "No such file"); the folder says why.
    const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (::access(folder.c_str(), W_OK | X_OK) != 0) {
      const int error = errno;
      throw FormatError(file, "",
                        "cannot create the recording: the folder " + folder.string() + " is not writable (" +
                            std::strerror(error) + ")");
    }
    db->Fail("cannot create the recording");
  }
  // WAL: a commit appends the frame to the log, the database file is untouched until a checkpoint, so a
  // killed writer leaves the file consistent. synchronous=FULL: the log is fsynced at every commit, so a
  // power cut or pulled cable also keeps every committed frame (NORMAL would only be safe against a process
  // crash: the last commits before a power loss could roll back). The price, one fsync per frame, is small at
  // scanner frame rates (docs/recordings.md has the measurement).
  db->Exec("PRAGMA journal_mode=WAL");
  db->Exec("PRAGMA synchronous=FULL");
  db->Exec("PRAGMA foreign_keys=ON");
  db->Exec("BEGIN");
  db->Exec(kSchema);
  Statement(*db, "INSERT INTO meta(key, value) VALUES ('format', ?)")
      .Bind(1, std::string(kRecordingFormat))
      .Run();
  Statement(*db, "INSERT INTO device(id, description, calibration) VALUES (1, '{}', '{}')").Run();
  db->Exec("COMMIT");
  return RecordingWriter(path, std::move(db));
}

RecordingWriter RecordingWriter::OpenForAppend(const fs::path& path) {
  const std::string file = path.string();
  {
    // The reader's checks (SQLite, integrity, tables, format), closed again before writing.
    const RecordingReader reader = RecordingReader::Open(path);
    if (reader.Meta(kStatusMeta).value_or("") == kStatusComplete) {
      throw FormatError(file, "", "the acquisition is complete (meta status 'complete'); nothing to append");
    }
  }
  auto db = std::make_unique<Db>();
  db->file = file;
  if (sqlite3_open_v2(file.c_str(), &db->db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    db->Fail("cannot open the recording for appending");
  }
  // As Create: every appended frame is one fsynced WAL commit.
  db->Exec("PRAGMA journal_mode=WAL");
  db->Exec("PRAGMA synchronous=FULL");
  db->Exec("PRAGMA foreign_keys=ON");
  return RecordingWriter(path, std::move(db));
}

void RecordingWriter::SetMeta(const std::string& key, const std::string& value) {
  if (!db_ || !db_->db) throw std::logic_error("recording closed");
  if (key == "format") throw std::invalid_argument("meta key 'format' is reserved");
  Statement(*db_, "INSERT OR REPLACE INTO meta(key, value) VALUES (?, ?)").Bind(1, key).Bind(2, value).Run();
}

void RecordingWriter::SetDevice(const std::string& description_json, const std::string& calibration_json) {
  if (!db_ || !db_->db) throw std::logic_error("recording closed");
  if (!nlohmann::json::accept(description_json))
    throw std::invalid_argument("device description is not JSON");
  if (!nlohmann::json::accept(calibration_json))
    throw std::invalid_argument("device calibration is not JSON");
  Statement(*db_, "UPDATE device SET description = ?, calibration = ? WHERE id = 1")
      .Bind(1, description_json)
      .Bind(2, calibration_json)
      .Run();
}

std::int64_t RecordingWriter::AddStream(const std::string& name, const std::string& kind,
                                        const std::string& encoding, const std::string& units) {
  if (!db_ || !db_->db) throw std::logic_error("recording closed");
  if (!ValidKind(kind))
    throw std::invalid_argument("stream kind must be points, depth or profile, not " + kind);
  Statement(*db_, "INSERT INTO streams(name, kind, encoding, units) VALUES (?, ?, ?, ?)")
      .Bind(1, name)
      .Bind(2, kind)
      .Bind(3, encoding)
      .Bind(4, units)
      .Run();
  return sqlite3_last_insert_rowid(db_->db);
}

std::int64_t RecordingWriter::AppendFrame(std::int64_t stream, std::int64_t view,
                                          const std::vector<std::uint8_t>& payload,
                                          const std::optional<RigidMotion>& world_T_scan,
                                          std::optional<std::int64_t> timestamp_ns,
                                          std::optional<double> turntable_angle_rad,
                                          const std::string& compression) {
  if (!db_ || !db_->db) throw std::logic_error("recording closed");
  if (compression != kNoCompression && compression != kZlibCompression)
    throw std::invalid_argument("unknown frame compression '" + compression + "' (none or zlib)");
  std::vector<std::uint8_t> stored;
  if (compression == kZlibCompression) {
    const std::uint64_t size = payload.size();
    uLongf bound = compressBound(static_cast<uLong>(payload.size()));
    stored.resize(8 + bound);
    std::memcpy(stored.data(), &size, 8);
    if (compress2(stored.data() + 8, &bound, payload.data(), static_cast<uLong>(payload.size()), 9) != Z_OK)
      throw std::runtime_error("zlib cannot compress the frame");
    stored.resize(8 + bound);
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (world_T_scan) {
    m = world_T_scan->matrix();
    // Checked before anything is written: SQLite would silently store a NaN as NULL.
    CheckPose(m, [](const std::string& problem) { throw std::invalid_argument(problem); });
  }
  if (turntable_angle_rad && !std::isfinite(*turntable_angle_rad)) {
    throw std::invalid_argument("turntable angle is not finite");
  }
  if (turntable_angle_rad && !world_T_scan) throw std::invalid_argument("a turntable angle needs a pose");
  // One transaction per frame: the frame and its pose appear together or not at all.
  db_->Exec("BEGIN IMMEDIATE");
  try {
    Statement insert(
        *db_, "INSERT INTO frames(stream, timestamp_ns, view, compression, payload) VALUES (?, ?, ?, ?, ?)");
    insert.Bind(1, stream);
    if (timestamp_ns) {
      insert.Bind(2, *timestamp_ns);
    } else {
      insert.BindNull(2);
    }
    insert.Bind(3, view)
        .Bind(4, compression)
        .Bind(5, compression == kZlibCompression ? stored : payload)
        .Run();
    const std::int64_t frame = sqlite3_last_insert_rowid(db_->db);
    if (world_T_scan) {
      Statement pose(*db_, "INSERT INTO poses VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
      pose.Bind(1, frame);
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) pose.Bind(2 + 4 * r + c, m(r, c));
      }
      if (turntable_angle_rad) {
        pose.Bind(18, *turntable_angle_rad);
      } else {
        pose.BindNull(18);
      }
      pose.Run();
    }
    db_->Exec("COMMIT");
    return frame;
  } catch (...) {
    sqlite3_exec(db_->db, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void RecordingWriter::Close() {
  if (!db_ || !db_->db) return;
  // Back to a rollback journal: the checkpoint moves every frame into the main file and the -wal/-shm files
  // disappear, so a finished recording is one file (copyable, readable from read-only media). That needs the
  // file to ourselves: while a reader has it open, the switch is refused and the recording stays valid as the
  // file plus its -wal. The connection is closed either way; the caller learns which.
  std::string problem;
  try {
    db_->Exec("PRAGMA wal_checkpoint(TRUNCATE)");
    Statement mode(*db_, "PRAGMA journal_mode=DELETE");
    if (mode.Step() && mode.Text(0) != "delete") problem = "journal mode stayed " + mode.Text(0);
  } catch (const FormatError& e) {
    problem = e.problem();
  }
  const int rc = sqlite3_close_v2(db_->db);
  db_->db = nullptr;
  if (rc != SQLITE_OK) throw FormatError(path_.string(), "", "cannot close the recording");
  if (!problem.empty()) {
    throw FormatError(path_.string(), "",
                      "every frame is committed, but the recording is still in WAL mode (keep its -wal file "
                      "beside it): " +
                          problem);
  }
}

// ---------------------------------------------------------------------------------------------------- reader

struct RecordingReader::Db : Connection {};

RecordingReader::RecordingReader(fs::path path, std::unique_ptr<Db> db)
    : path_(std::move(path)), db_(std::move(db)) {}
RecordingReader::RecordingReader(RecordingReader&&) noexcept = default;
RecordingReader& RecordingReader::operator=(RecordingReader&&) noexcept = default;
RecordingReader::~RecordingReader() = default;

RecordingReader RecordingReader::Open(const fs::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw FormatError(file, "", "no such recording");
  const auto size = fs::file_size(path, ec);
  if (ec) throw FormatError(file, "", "cannot read the file size: " + ec.message());
  std::array<unsigned char, 100> header{};
  {
    std::ifstream in(path, std::ios::binary);
    in.read(reinterpret_cast<char*>(header.data()), header.size());
    if (in.gcount() < static_cast<std::streamsize>(header.size())) {
      throw FormatError(file, "header", "not a SQLite database (shorter than a SQLite header)");
    }
  }
  if (std::memcmp(header.data(), "SQLite format 3", 16) != 0) {
    throw FormatError(file, "header",
                      "not a SQLite database (the first 16 bytes are not \"SQLite format 3\")");
  }
  // The header records the database size in pages; SQLite itself would read a shorter file without complaint
  // until a query reaches a missing page. Only meaningful without a write-ahead log (which may hold pages not
  // yet copied into the file) and when the size field is valid (its change counter matches, offsets 24 and
  // 92).
  const auto be32 = [&](std::size_t o) {
    return (std::uint32_t{header[o]} << 24) | (std::uint32_t{header[o + 1]} << 16) |
           (std::uint32_t{header[o + 2]} << 8) | std::uint32_t{header[o + 3]};
  };
  const std::uint32_t raw_page = (std::uint32_t{header[16]} << 8) | header[17];
  const std::uint64_t page_size = raw_page == 1 ? 65536 : raw_page;
  const std::uint64_t pages = be32(28);
  const bool has_wal = fs::exists(file + "-wal", ec);
  if (!has_wal && pages > 0 && be32(24) == be32(92) && page_size * pages > size) {
    throw FormatError(file, "",
                      "truncated: the header declares " + std::to_string(page_size * pages) +
                          " bytes, the file has " + std::to_string(size));
  }

  auto db = std::make_unique<Db>();
  db->file = file;
  if (sqlite3_open_v2(file.c_str(), &db->db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    db->Fail("cannot open the recording");
  }
  // quick_check: the b-trees' structure, in O(N); reports a truncated or overwritten file that the header
  // checks above cannot see.
  {
    std::string problems;
    int rc = SQLITE_OK;
    sqlite3_stmt* stmt = nullptr;
    rc = sqlite3_prepare_v2(db->db, "PRAGMA quick_check(5)", -1, &stmt, nullptr);
    while (rc == SQLITE_OK || rc == SQLITE_ROW) {
      rc = sqlite3_step(stmt);
      if (rc == SQLITE_ROW) {
        const auto* t = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
        const std::string row = t ? t : "";
        if (row != "ok") problems += (problems.empty() ? "" : "; ") + row;
      }
    }
    const std::string message = sqlite3_errmsg(db->db);
    const int code = sqlite3_errcode(db->db);
    sqlite3_finalize(stmt);
    if (code == SQLITE_NOTADB) throw FormatError(file, "header", "not a SQLite database (" + message + ")");
    if (rc != SQLITE_DONE)
      throw FormatError(file, "", "corrupted or truncated (integrity check: " + message + ")");
    if (!problems.empty())
      throw FormatError(file, "", "corrupted or truncated (integrity check: " + problems + ")");
  }
  for (const char* table : kTables) {
    Statement s(*db, "SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = ?");
    s.Bind(1, std::string(table));
    if (!s.Step() || s.Int(0) != 1) {
      throw FormatError(file, "", std::string("not a scan2model recording: no table '") + table + "'");
    }
  }
  Statement format(*db, "SELECT value FROM meta WHERE key = 'format'");
  if (!format.Step()) throw FormatError(file, "", "not a scan2model recording: meta has no 'format'");
  const std::string version = format.Text(0);
  if (version != kRecordingFormat) {
    throw FormatError(
        file, "",
        "unsupported recording format '" + version + "' (this build reads " + kRecordingFormat + ")");
  }
  return RecordingReader(path, std::move(db));
}

std::optional<std::string> RecordingReader::Meta(const std::string& key) const {
  Statement s(*db_, "SELECT value FROM meta WHERE key = ?");
  s.Bind(1, key);
  if (!s.Step()) return std::nullopt;
  return s.Text(0);
}

std::vector<RecordingStream> RecordingReader::Streams() const {
  std::vector<RecordingStream> out;
  Statement s(*db_, "SELECT id, name, kind, encoding, units FROM streams ORDER BY id");
  while (s.Step()) out.push_back({s.Int(0), s.Text(1), s.Text(2), s.Text(3), s.Text(4)});
  return out;
}

RecordingSummary RecordingReader::Summary() const {
  RecordingSummary summary;
  {
    Statement s(*db_, "SELECT key, value FROM meta ORDER BY key");
    while (s.Step()) summary.meta.emplace_back(s.Text(0), s.Text(1));
  }
  summary.format = *Meta("format");
  {
    Statement s(*db_, "SELECT description, calibration FROM device WHERE id = 1");
    if (s.Step()) {
      summary.device = s.Text(0);
      summary.calibration = s.Text(1);
    }
  }
  summary.streams = Streams();
  for (const RecordingStream& stream : summary.streams) {
    Statement s(*db_, "SELECT count(*), coalesce(sum(length(payload)), 0) FROM frames WHERE stream = ?");
    s.Bind(1, stream.id);
    s.Step();
    summary.frames_per_stream.push_back(s.Int(0));
    summary.payload_bytes_per_stream.push_back(s.Int(1));
  }
  Statement s(*db_, "SELECT count(*) FROM poses");
  s.Step();
  summary.posed_frames = s.Int(0);
  return summary;
}

std::vector<RecordingFrame> RecordingReader::Frames(std::int64_t stream) const {
  return Query(stream, std::nullopt);
}

std::vector<RecordingFrame> RecordingReader::FramesOfView(std::int64_t stream, std::int64_t view) const {
  return Query(stream, view);
}

std::vector<RecordingFrame> RecordingReader::Query(std::int64_t stream,
                                                   std::optional<std::int64_t> view) const {
  std::string sql =
      "SELECT f.id, f.stream, f.timestamp_ns, f.view, f.compression, f.payload, p.frame, p.m00, p.m01, "
      "p.m02, p.m03, "
      "p.m10, p.m11, p.m12, p.m13, p.m20, p.m21, p.m22, p.m23, p.m30, p.m31, p.m32, p.m33, "
      "p.turntable_angle_rad "
      "FROM frames f LEFT JOIN poses p ON p.frame = f.id WHERE f.stream = ?";
  if (view) sql += " AND f.view = ?";
  sql += " ORDER BY f.view, f.id";
  Statement s(*db_, sql);
  s.Bind(1, stream);
  if (view) s.Bind(2, *view);
  std::vector<RecordingFrame> out;
  const std::string file = path_.string();
  while (s.Step()) {
    RecordingFrame f;
    f.id = s.Int(0);
    f.stream = s.Int(1);
    if (!s.IsNull(2)) f.timestamp_ns = s.Int(2);
    f.view = s.Int(3);
    f.compression = s.Text(4);
    f.payload = s.Blob(5);
    const std::string where = "frame " + std::to_string(f.id);
    if (!s.IsNull(6)) {
      Eigen::Matrix4d m;
      for (int k = 0; k < 16; ++k) {
        // A NaN written through SQLite becomes NULL, text stays text: both are a damaged pose.
        const int type = s.Type(7 + k);
        if (type != SQLITE_FLOAT && type != SQLITE_INTEGER) {
          throw FormatError(
              file, where,
              "pose element m" + std::to_string(k / 4) + std::to_string(k % 4) + " is not a number");
        }
        m(k / 4, k % 4) = s.Real(7 + k);
      }
      CheckPose(m, [&](const std::string& problem) { throw FormatError(file, where, problem); });
      // Not re-orthonormalized: a recording's pose is returned bit for bit as written.
      f.world_T_scan = RigidMotion::FromMatrix(m);
      if (!s.IsNull(23)) {
        f.turntable_angle_rad = s.Real(23);
        if (!std::isfinite(*f.turntable_angle_rad))
          throw FormatError(file, where, "turntable angle is not finite");
      }
    }
    out.push_back(std::move(f));
  }
  return out;
}

// ----------------------------------------------------------------------------------------------------
// payloads

std::vector<std::uint8_t> FramePayload(const RecordingFrame& frame, const std::string& file,
                                       const std::string& where) {
  if (frame.compression == kNoCompression) return frame.payload;
  if (frame.compression != kZlibCompression)
    throw FormatError(file, where, "unsupported compression '" + frame.compression + "' (none or zlib)");
  std::uint64_t size = 0;
  if (frame.payload.size() < 8) throw FormatError(file, where, "zlib payload has no size");
  std::memcpy(&size, frame.payload.data(), 8);
  // A damaged size must not allocate the moon: zlib compresses at most about 1032:1.
  if (size > 1100 * static_cast<std::uint64_t>(frame.payload.size()) + 64)
    throw FormatError(file, where,
                      "zlib payload declares " + std::to_string(size) + " bytes, more than it can hold");
  std::vector<std::uint8_t> out(size);
  uLongf length = static_cast<uLongf>(size);
  const int rc =
      uncompress(out.data(), &length, frame.payload.data() + 8, static_cast<uLong>(frame.payload.size() - 8));
  if (rc != Z_OK || length != size)
    throw FormatError(
        file, where,
        std::string("damaged zlib payload (") + (rc == Z_OK ? "size mismatch" : zError(rc)) + ")");
  return out;
}

std::vector<std::uint8_t> EncodePoints(const Eigen::Matrix3Xd& points) {
  const auto n = static_cast<std::uint64_t>(points.cols());
  std::vector<std::uint8_t> out(8 + 24 * n);
  std::memcpy(out.data(), &n, 8);
  // Eigen's default column-major storage is exactly x y z per point.
  if (n > 0) std::memcpy(out.data() + 8, points.data(), 24 * n);
  return out;
}

Eigen::Matrix3Xd DecodePoints(const std::vector<std::uint8_t>& payload, const std::string& file,
                              const std::string& where) {
  if (payload.size() < 8) {
    throw FormatError(file, where,
                      "point payload of " + std::to_string(payload.size()) + " bytes has no count");
  }
  std::uint64_t n = 0;
  std::memcpy(&n, payload.data(), 8);
  // Compared by division, so that a huge corrupt count cannot overflow 24 * n.
  const std::uint64_t body = payload.size() - 8;
  if (body % 24 != 0 || body / 24 != n) {
    throw FormatError(file, where,
                      "point payload declares " + std::to_string(n) + " points (" +
                          "8 + 24 per point bytes) but has " + std::to_string(payload.size()) + " bytes");
  }
  Eigen::Matrix3Xd points(3, static_cast<Eigen::Index>(n));
  if (n > 0) std::memcpy(points.data(), payload.data() + 8, body);
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(points(c, i))) {
        throw FormatError(file, where,
                          "point " + std::to_string(i) + ": " + "xyz"[c] + " is not finite (" +
                              std::to_string(points(c, i)) + ")");
      }
    }
  }
  return points;
}

// ----------------------------------------------------------------------------------------------------
// ScanSet

void WriteRecording(const fs::path& path, const ScanSet& set, const std::string& stream_name) {
  RecordingWriter writer = RecordingWriter::Create(path);
  writer.SetMeta("name", set.name);
  const std::string units = set.scans.empty() ? "unknown" : set.scans.front().units;
  const std::string device = set.scans.empty() ? "" : set.scans.front().metadata.device;
  writer.SetDevice(nlohmann::json{{"name", device}}.dump());
  const std::int64_t stream = writer.AddStream(stream_name, "points", kPointsEncoding, units);
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    const Scan& scan = set.scans[k];
    std::optional<std::int64_t> t;
    if (scan.metadata.timestamp_s) t = std::llround(*scan.metadata.timestamp_s * 1e9);
    writer.AppendFrame(stream, static_cast<std::int64_t>(k), EncodePoints(scan.points), scan.world_T_scan, t,
                       scan.metadata.turntable_angle_rad);
  }
  writer.Close();
}

ScanSet ReadRecording(const fs::path& path, const std::string& stream_name) {
  const std::string file = path.string();
  const RecordingReader reader = RecordingReader::Open(path);
  std::optional<RecordingStream> chosen;
  int points_streams = 0;
  for (const RecordingStream& s : reader.Streams()) {
    if (s.kind == "points") ++points_streams;
    if (stream_name.empty() ? s.kind == "points" : s.name == stream_name) chosen = s;
  }
  if (!stream_name.empty() && !chosen) throw FormatError(file, "", "no stream named '" + stream_name + "'");
  if (stream_name.empty() && points_streams == 0)
    throw FormatError(file, "", "no points stream to read as views");
  if (stream_name.empty() && points_streams > 1) {
    throw FormatError(file, "", std::to_string(points_streams) + " points streams: name the one to read");
  }
  if (chosen->kind != "points" || chosen->encoding != kPointsEncoding) {
    throw FormatError(
        file, "stream '" + chosen->name + "'",
        "holds " + chosen->kind + " encoded as " + chosen->encoding + ", not points as " + kPointsEncoding);
  }
  const std::string device = [&] {
    const nlohmann::json d = nlohmann::json::parse(reader.Summary().device, nullptr, false);
    return d.is_object() && d.contains("name") && d["name"].is_string() ? d["name"].get<std::string>() : "";
  }();
  ScanSet set;
  set.name = reader.Meta("name").value_or("");
  for (RecordingFrame& f : reader.Frames(chosen->id)) {
    const std::string where = "frame " + std::to_string(f.id);
    Scan scan;
    scan.points = DecodePoints(FramePayload(f, file, where), file, where);
    if (scan.empty()) throw FormatError(file, where, "no points");
    scan.units = chosen->units;
    if (f.world_T_scan) scan.world_T_scan = *f.world_T_scan;
    scan.metadata.device = device;
    if (f.timestamp_ns) scan.metadata.timestamp_s = static_cast<double>(*f.timestamp_ns) * 1e-9;
    scan.metadata.turntable_angle_rad = f.turntable_angle_rad;
    scan.metadata.source =
        file + ": stream '" + chosen->name + "', view " + std::to_string(f.view) + ", " + where;
    set.scans.push_back(std::move(scan));
  }
  if (set.scans.empty()) throw FormatError(file, "stream '" + chosen->name + "'", "no frames");
  return set;
}

}  // namespace s2m
