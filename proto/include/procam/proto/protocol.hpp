// SPDX-License-Identifier: MIT
// procam wire protocol v1: message types, limits, and the one encode/decode
// shared by procamd and every C++ client. The specification is
// proto/PROTOCOL.md; this header follows it and never the other way round.
//
// Contract: nothing here throws (nlohmann::json exceptions are caught inside
// and become Status values) and nothing touches ZeroMQ: these functions work
// on the JSON body frame only. Thread-safety: all functions are reentrant.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"

namespace procam::proto {

// ---- Versions and limits (PROTOCOL.md "Limits") ----------------------------
inline constexpr int kVersion = 1;                       // the version this code speaks
inline constexpr std::string_view kDefaultEndpoint = "tcp://127.0.0.1:5560";
inline constexpr size_t kMaxRequestBytes = size_t{1} << 20;   // whole request body frame
inline constexpr size_t kMaxIdBytes = 128;               // request "id", "scan_id"
inline constexpr size_t kMaxLabelBytes = 256;            // scan "label"
inline constexpr size_t kMaxNameBytes = 64;              // plugin / method names
inline constexpr size_t kMaxFileNameBytes = 255;         // fetch "file"
inline constexpr size_t kMaxClientBytes = 128;           // hello "client"
inline constexpr size_t kMaxParamsBytes = size_t{64} << 10;   // params / rig_options, compact JSON
inline constexpr int kMaxParamsDepth = 16;               // params / rig_options nesting
inline constexpr int kMaxMessageDepth = 32;              // whole request nesting
inline constexpr size_t kMaxScanInputs = 16;             // scan "inputs" entries
inline constexpr uint64_t kDefaultFetchBytes = uint64_t{1} << 20;
inline constexpr uint64_t kMaxFetchBytes = uint64_t{8} << 20;

// Versions this build can speak, ascending. Today {1}.
std::vector<int> supported_versions();

// ---- Requests --------------------------------------------------------------
struct Hello {
  std::vector<int> versions;  // versions the client speaks (non-empty, each >= 1)
  std::string client;         // "name/version", free text; "" when not sent
  bool operator==(const Hello&) const = default;
};
struct ListPlugins {
  bool operator==(const ListPlugins&) const = default;
};
struct DescribeRig {
  bool operator==(const DescribeRig&) const = default;
};
// One scan input (PROTOCOL.md 5.4 "inputs"): output `output` of the finished
// scan `scan_id`.
struct InputRef {
  std::string scan_id;  // 1..128 bytes ("scan" on the wire)
  std::string output;   // an output name, [a-z0-9_]{1,64}
  bool operator==(const InputRef&) const = default;
};

struct Scan {
  std::string plugin, method;
  nlohmann::json params = nlohmann::json::object();       // always an object
  nlohmann::json rig_options = nlohmann::json::object();  // always an object
  bool events = false;
  std::string label;  // "" when not sent
  bool save_frames = false;  // keep the raw frames in the scan folder (frame-r<round>-<index>.png)
  // Input name (as the method declares it, [a-z0-9_]{1,64}) -> an output of a
  // finished scan; at most kMaxScanInputs. Empty: none (omitted on the wire).
  std::map<std::string, InputRef> inputs{};
  bool operator==(const Scan&) const = default;
};
struct StatusQuery {
  std::optional<std::string> scan_id;  // nullopt: daemon status
  bool operator==(const StatusQuery&) const = default;
};
struct ResultQuery {
  std::string scan_id;
  bool operator==(const ResultQuery&) const = default;
};
struct Fetch {
  std::string scan_id, file;
  uint64_t offset = 0;
  uint64_t max_bytes = kDefaultFetchBytes;
  bool operator==(const Fetch&) const = default;
};

// Cancels a queued or running scan (PROTOCOL.md 5.8).
struct Cancel {
  std::string scan_id;
  bool operator==(const Cancel&) const = default;
};
// Liveness check answered at once, even while a scan runs (PROTOCOL.md 5.9).
struct Ping {
  bool operator==(const Ping&) const = default;
};
inline constexpr uint32_t kDefaultListScans = 100;
inline constexpr uint32_t kMaxListScans = 1000;
// The daemon's scans, newest first (PROTOCOL.md 5.10).
struct ListScans {
  std::optional<std::string> state;  // only scans in this state (a scan state name, or "active")
  uint32_t limit = kDefaultListScans;  // 1..kMaxListScans
  bool operator==(const ListScans&) const = default;
};
// The rig_options the rig accepts, with their values (scene names) (5.11).
struct ListRigOptions {
  bool operator==(const ListRigOptions&) const = default;
};

inline constexpr size_t kMinCalibrationScans = 3;
inline constexpr size_t kMaxCalibrationScans = 50;
// Geometric calibration of the rig from finished chessboard scans
// (PROTOCOL.md 5.12): each scan a structured-light/gray rows=true scan with
// saved frames, one board pose each. Runs as a calibration "scan" record.
struct CalibrateGeometry {
  std::vector<std::string> scans;  // kMinCalibrationScans..kMaxCalibrationScans scan ids, no repeats
  int board_cols = 0, board_rows = 0;  // inner corners, 2..100 each (ChArUco: squares - 1)
  double square_mm = 0;                // > 0, <= 1000
  bool events = false;
  std::string label;  // "" when not sent
  // The board's type; for "charuco", board_cols/rows are its squares - 1.
  std::string board_type = "chessboard";  // or "charuco"
  double marker_mm = 0;                   // charuco: marker side, in (0, square_mm)
  std::string dictionary;                 // charuco: OpenCV dictionary name, e.g. "DICT_5X5_100"
  bool operator==(const CalibrateGeometry&) const = default;
};

// The request's "board" object (PROTOCOL.md 5.12): {"type": "chessboard",
// "inner_corners": [c, r], "square_mm": s} or {"type": "charuco", "squares":
// [c + 1, r + 1], "square_mm": s, "marker_mm": m, "dictionary": d}.
nlohmann::json board_json(const CalibrateGeometry& c);

using RequestBody = std::variant<Hello, ListPlugins, DescribeRig, Scan, StatusQuery, ResultQuery,
                                 Fetch, Cancel, Ping, ListScans, ListRigOptions, CalibrateGeometry>;

struct Request {
  std::string id;
  RequestBody body;
  bool operator==(const Request&) const = default;
};

// Wire "type" of a request body: "hello", "list_plugins", "describe_rig",
// "scan", "status", "result", "fetch", "cancel", "ping". Replies to it carry
// the same type.
std::string_view type_name(const RequestBody& body);

// Decodes and fully validates one request body frame (PROTOCOL.md
// "Validation"). On failure returns the error to send back and, when the
// request's "id" was readable and valid, stores it in *id_out (left untouched
// otherwise) so the error reply can echo it. Never throws.
Result<Request> decode_request(std::string_view bytes, std::string* id_out = nullptr);

// Encodes a request (as a client sends it). The result always decodes back to
// an equal Request if the Request satisfies the limits.
std::string encode_request(const Request& request);

// Highest version both sides speak; unsupported_version (listing ours) if none.
Result<int> negotiate_version(const Hello& hello);

// ---- Replies and events (daemon side) --------------------------------------
// {"procam":1,"id":id,"type":type,"ok":true, ...fields}. `fields` must be an
// object (null counts as {}); its procam/id/type/ok keys are overwritten.
// Invalid UTF-8 in strings is replaced (U+FFFD), NaN/inf become null.
std::string encode_reply(const std::string& id, std::string_view type, nlohmann::json fields);

// {"procam":1,"id":id|null,"type":"error","ok":false,"error":{code,message,hint}}.
// For unsupported_version the error object also lists "supported_versions".
// An ok Status (a caller bug) is sent as code "internal".
std::string encode_error(const std::optional<std::string>& id, const Status& error);

// {"procam":1,"type":"event","scan_id":..,"seq":..,"event":..., ...fields}.
std::string encode_event(const std::string& scan_id, uint64_t seq, std::string_view event,
                         nlohmann::json fields);

// The error object {"code","message","hint"} used in error replies, scan
// summaries, manifests and list_plugins "rejected" entries.
nlohmann::json error_to_json(const Status& error);
// The inverse: a failed Status. Unknown codes (from a newer daemon) become
// Code::internal with the wire code kept in the message. nullopt if `error` is
// not such an object (no string code/message, or code "ok").
std::optional<Status> error_from_json(const nlohmann::json& error);

// The Code whose wire name is `name` (code_name inverse); nullopt if none.
std::optional<Code> code_from_name(std::string_view name);

// ---- Decoding what the daemon sends (client side) --------------------------
struct Reply {
  std::string id;        // "" when the daemon sent id null (unreadable request)
  std::string type;      // request type, or "error"
  bool ok = false;
  nlohmann::json body;   // every field except procam/id/type/ok (errors: {"error":{...}})
  Status error;          // ok Status for ok replies
};
struct Event {
  std::string scan_id;
  uint64_t seq = 0;
  std::string event;     // "progress", "state", "log" (others: ignore)
  nlohmann::json body;   // every field except procam/type/scan_id/seq/event
};
struct Incoming {
  std::variant<Reply, Event> message;
};

// Decodes a reply or event body frame. Unknown fields are kept in body, never
// an error (PROTOCOL.md "Compatibility"). Fails with bad_message for anything
// that is not a v1 reply/event, unsupported_version for another "procam".
Result<Incoming> decode_incoming(std::string_view bytes);

// ---- Small helpers ---------------------------------------------------------
// Plugin and method names: 1..64 bytes of [a-z0-9_-].
bool is_valid_name(std::string_view name);
// Output and input names: 1..64 bytes of [a-z0-9_] (they become file names).
bool is_output_name(std::string_view name);

// A plain file name a client may fetch: 1..255 bytes, no '/', no '\\', no
// "..", not starting with '.', no control characters (< 0x20, 0x7f).
bool is_safe_file_name(std::string_view name);

// RFC 3339 UTC timestamp with milliseconds, e.g. "2025-03-01T12:00:00.250Z",
// the form of "created_utc" / "finished_utc".
std::string utc_timestamp(std::chrono::system_clock::time_point t);

}  // namespace procam::proto
