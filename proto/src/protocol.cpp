// SPDX-License-Identifier: MIT
// procam wire protocol v1: strict request decoding, reply/event encoding and
// client-side decoding (proto/PROTOCOL.md is the specification).
#include "procam/proto/protocol.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cstdio>
#include <ctime>
#include <exception>
#include <initializer_list>
#include <set>
#include <utility>

namespace procam::proto {
namespace {

using json = nlohmann::json;

// In RequestBody's variant order.
constexpr std::array<std::string_view, 12> kTypes = {
    "hello", "list_plugins", "describe_rig", "scan", "status", "result", "fetch", "cancel", "ping",
    "list_scans", "list_rig_options", "calibrate_geometry"};

constexpr const char* kSpecHint = "see proto/PROTOCOL.md";

// Serialise without ever throwing on bad UTF-8 (replaced by U+FFFD).
std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

std::string join(const std::vector<std::string>& parts, std::string_view sep) {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) {
    if (i) out += sep;
    out += parts[i];
  }
  return out;
}

std::string versions_text() {
  std::vector<std::string> v;
  for (int x : supported_versions()) v.push_back(std::to_string(x));
  return "[" + join(v, ", ") + "]";
}

// ---- Strict parsing ---------------------------------------------------------

struct ParseAbort {
  Code code;
  std::string message;
};

// nlohmann's parse_error text without the "[json.exception.parse_error.101] " tag.
std::string parse_error_text(const char* what) {
  std::string s = what;
  if (auto p = s.find("] "); p != std::string::npos && s.rfind("[json.exception", 0) == 0)
    s.erase(0, p + 2);
  return s;
}

// Parses JSON, rejecting nesting deeper than max_depth (too_large) and
// duplicate object keys (bad_message). The parser is iterative and the depth
// check runs while parsing, so hostile input cannot exhaust the stack.
Result<json> parse_strict(std::string_view bytes, int max_depth) {
  std::vector<std::set<std::string>> keys;
  auto callback = [&](int depth, json::parse_event_t event, json& parsed) -> bool {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        if (depth + 1 > max_depth)
          throw ParseAbort{Code::too_large, "JSON nesting deeper than " +
                                                std::to_string(max_depth) + " levels"};
        if (event == json::parse_event_t::object_start) keys.emplace_back();
        break;
      case json::parse_event_t::key:
        if (!keys.empty() && !keys.back().insert(parsed.get<std::string>()).second)
          throw ParseAbort{Code::bad_message,
                           "duplicate key '" + parsed.get<std::string>() + "' in a JSON object"};
        break;
      case json::parse_event_t::object_end:
        if (!keys.empty()) keys.pop_back();
        break;
      default:
        break;
    }
    return true;
  };
  try {
    return json::parse(bytes.begin(), bytes.end(), callback, /*allow_exceptions=*/true,
                       /*ignore_comments=*/false);
  } catch (const ParseAbort& a) {
    return Error(a.code, a.message, kSpecHint);
  } catch (const json::exception& e) {
    return Error(Code::bad_message, "not valid UTF-8 JSON: " + parse_error_text(e.what()),
                 "a message body is one frame holding one JSON object; " + std::string(kSpecHint));
  }
}

int depth_of(const json& j) {
  if (!j.is_structured()) return 0;
  int d = 0;
  for (const auto& e : j) d = std::max(d, depth_of(e));
  return d + 1;
}

// ---- Field access with errors that name the field ----------------------------

class Fields {
public:
  Fields(const json& obj, std::string_view type) : obj_(obj), type_(type) {}

  // Every key must be a common field or one of `allowed`.
  Status only(std::initializer_list<std::string_view> allowed) const {
    for (const auto& [key, value] : obj_.items()) {
      if (key == "procam" || key == "id" || key == "type") continue;
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
      std::vector<std::string> names = {"procam", "id", "type"};
      for (auto a : allowed) names.emplace_back(a);
      return Error(Code::bad_message,
                   "unknown field '" + key + "' in " + std::string(type_) + " request",
                   "allowed fields: " + join(names, ", ") + " (names are case-sensitive)");
    }
    return {};
  }

  const json* find(const char* name) const {
    auto it = obj_.find(name);
    return it == obj_.end() ? nullptr : &*it;
  }

  Status missing(const char* name) const {
    return Error(Code::bad_message,
                 "missing field '" + std::string(name) + "' in " + std::string(type_) + " request",
                 kSpecHint);
  }

  Status wrong_type(const char* name, const char* expected, const json& got) const {
    return Error(Code::bad_message,
                 "field '" + std::string(name) + "' must be " + expected + ", got " +
                     got.type_name(),
                 kSpecHint);
  }

  // A string of 1..max bytes (0..max when allow_empty). Over max: too_large.
  Result<std::optional<std::string>> string(const char* name, bool required, size_t max,
                                            bool allow_empty = false) const {
    const json* v = find(name);
    if (!v) {
      if (required) return missing(name);
      return std::optional<std::string>{};
    }
    if (!v->is_string()) return wrong_type(name, "a string", *v);
    const auto& s = v->get_ref<const std::string&>();
    if (s.empty() && !allow_empty)
      return Error(Code::bad_message, "field '" + std::string(name) + "' must not be empty",
                   kSpecHint);
    if (s.size() > max)
      return Error(Code::too_large,
                   "field '" + std::string(name) + "' is " + std::to_string(s.size()) +
                       " bytes; the limit is " + std::to_string(max),
                   kSpecHint);
    return std::optional<std::string>{s};
  }

  // A plugin or method name: string, 1..64 bytes of [a-z0-9_-].
  Result<std::string> name(const char* field) const {
    auto s = string(field, true, kMaxNameBytes);
    PROCAM_TRY(s);
    if (!is_valid_name(**s))
      return Error(Code::invalid_argument,
                   "field '" + std::string(field) + "' has characters outside [a-z0-9_-]: '" +
                       **s + "'",
                   "names are lower-case; list them with a list_plugins request");
    return std::move(**s);
  }

  Result<std::optional<bool>> boolean(const char* name) const {
    const json* v = find(name);
    if (!v) return std::optional<bool>{};
    if (!v->is_boolean()) return wrong_type(name, "true or false", *v);
    return std::optional<bool>{v->get<bool>()};
  }

  // A non-negative JSON integer (no fraction, no exponent).
  Result<std::optional<uint64_t>> unsigned_int(const char* name) const {
    const json* v = find(name);
    if (!v) return std::optional<uint64_t>{};
    if (!v->is_number_integer()) return wrong_type(name, "an integer", *v);
    if (!v->is_number_unsigned())
      return Error(Code::invalid_argument, "field '" + std::string(name) + "' must be >= 0",
                   kSpecHint);
    return std::optional<uint64_t>{v->get<uint64_t>()};
  }

  // An object of at most 64 KiB (compact JSON) nested at most 16 deep.
  Result<json> small_object(const char* name) const {
    const json* v = find(name);
    if (!v) return json::object();
    if (!v->is_object()) return wrong_type(name, "an object", *v);
    if (int d = depth_of(*v); d > kMaxParamsDepth)
      return Error(Code::too_large,
                   "field '" + std::string(name) + "' is nested " + std::to_string(d) +
                       " levels deep; the limit is " + std::to_string(kMaxParamsDepth),
                   kSpecHint);
    if (size_t n = dump(*v).size(); n > kMaxParamsBytes)
      return Error(Code::too_large,
                   "field '" + std::string(name) + "' is " + std::to_string(n) +
                       " bytes as compact JSON; the limit is " + std::to_string(kMaxParamsBytes),
                   kSpecHint);
    return *v;
  }

private:
  const json& obj_;
  std::string_view type_;
};

Result<RequestBody> decode_hello(const Fields& f) {
  PROCAM_TRY(f.only({"versions", "client"}));
  Hello h;
  const json* v = f.find("versions");
  if (!v) return f.missing("versions");
  if (!v->is_array()) return f.wrong_type("versions", "an array of integers", *v);
  if (v->empty())
    return Error(Code::invalid_argument, "field 'versions' must not be empty",
                 "list the protocol versions the client speaks, e.g. [1]");
  if (v->size() > 64)
    return Error(Code::too_large, "field 'versions' has more than 64 entries", kSpecHint);
  for (const auto& e : *v) {
    if (!e.is_number_integer()) return f.wrong_type("versions", "an array of integers", *v);
    if (!e.is_number_unsigned() || e.get<uint64_t>() < 1 || e.get<uint64_t>() > INT_MAX)
      return Error(Code::invalid_argument,
                   "field 'versions' holds " + dump(e) + "; versions are integers >= 1",
                   kSpecHint);
    h.versions.push_back(static_cast<int>(e.get<uint64_t>()));
  }
  auto client = f.string("client", false, kMaxClientBytes, true);
  PROCAM_TRY(client);
  h.client = client->value_or("");
  return RequestBody{std::move(h)};
}

// scan "inputs": {"<input name>": {"scan": "<scan id>", "output": "<output name>"}, ...}
Result<std::map<std::string, InputRef>> decode_inputs(const Fields& f) {
  std::map<std::string, InputRef> out;
  const json* v = f.find("inputs");
  if (!v) return out;
  if (!v->is_object()) return f.wrong_type("inputs", "an object", *v);
  if (v->size() > kMaxScanInputs)
    return Error(Code::too_large,
                 "field 'inputs' has " + std::to_string(v->size()) + " entries; the limit is " +
                     std::to_string(kMaxScanInputs),
                 kSpecHint);
  const std::string form = "each input is \"<name>\": {\"scan\": \"<scan id>\", \"output\": \"<output name>\"}";
  for (const auto& [name, ref] : v->items()) {
    const std::string at = "inputs." + name;
    if (name.size() > kMaxNameBytes)
      return Error(Code::too_large, "input name '" + name.substr(0, 16) + "...' is longer than 64 bytes", kSpecHint);
    if (!is_output_name(name))
      return Error(Code::invalid_argument, "input name '" + name + "' has characters outside [a-z0-9_]",
                   "input names are the method's, e.g. depth_mm; list_plugins shows each method's inputs");
    if (!ref.is_object())
      return Error(Code::bad_message, "field '" + at + "' must be an object, got " + ref.type_name(), form);
    for (const auto& [key, value] : ref.items())
      if (key != "scan" && key != "output")
        return Error(Code::bad_message, "unknown field '" + at + "." + key + "'", form);
    const auto scan = ref.find("scan");
    const auto output = ref.find("output");
    if (scan == ref.end() || output == ref.end())
      return Error(Code::bad_message, "field '" + at + "' needs 'scan' and 'output'", form);
    if (!scan->is_string() || !output->is_string())
      return Error(Code::bad_message, "'" + at + ".scan' and '" + at + ".output' must be strings", form);
    InputRef r{scan->get<std::string>(), output->get<std::string>()};
    if (r.scan_id.empty())
      return Error(Code::bad_message, "field '" + at + ".scan' must not be empty", form);
    if (r.scan_id.size() > kMaxIdBytes)
      return Error(Code::too_large, "field '" + at + ".scan' is longer than 128 bytes", kSpecHint);
    if (r.output.size() > kMaxNameBytes)
      return Error(Code::too_large, "field '" + at + ".output' is longer than 64 bytes", kSpecHint);
    if (!is_output_name(r.output))
      return Error(Code::invalid_argument, "field '" + at + ".output' has characters outside [a-z0-9_]: '" + r.output + "'",
                   "name an output listed in that scan's manifest, e.g. depth_mm");
    out.emplace(name, std::move(r));
  }
  return out;
}

Result<RequestBody> decode_scan(const Fields& f) {
  PROCAM_TRY(f.only({"plugin", "method", "params", "rig_options", "events", "label", "save_frames", "inputs"}));
  Scan s;
  auto plugin = f.name("plugin");
  PROCAM_TRY(plugin);
  s.plugin = std::move(*plugin);
  auto method = f.name("method");
  PROCAM_TRY(method);
  s.method = std::move(*method);
  auto params = f.small_object("params");
  PROCAM_TRY(params);
  s.params = std::move(*params);
  auto rig_options = f.small_object("rig_options");
  PROCAM_TRY(rig_options);
  s.rig_options = std::move(*rig_options);
  auto events = f.boolean("events");
  PROCAM_TRY(events);
  s.events = events->value_or(false);
  auto label = f.string("label", false, kMaxLabelBytes, true);
  PROCAM_TRY(label);
  s.label = label->value_or("");
  auto save_frames = f.boolean("save_frames");
  PROCAM_TRY(save_frames);
  s.save_frames = save_frames->value_or(false);
  auto inputs = decode_inputs(f);
  PROCAM_TRY(inputs);
  s.inputs = std::move(*inputs);
  return RequestBody{std::move(s)};
}

Result<RequestBody> decode_status(const Fields& f) {
  PROCAM_TRY(f.only({"scan_id"}));
  auto scan_id = f.string("scan_id", false, kMaxIdBytes);
  PROCAM_TRY(scan_id);
  return RequestBody{StatusQuery{std::move(*scan_id)}};
}

Result<RequestBody> decode_result(const Fields& f) {
  PROCAM_TRY(f.only({"scan_id"}));
  auto scan_id = f.string("scan_id", true, kMaxIdBytes);
  PROCAM_TRY(scan_id);
  return RequestBody{ResultQuery{std::move(**scan_id)}};
}

Result<RequestBody> decode_cancel(const Fields& f) {
  PROCAM_TRY(f.only({"scan_id"}));
  auto scan_id = f.string("scan_id", true, kMaxIdBytes);
  PROCAM_TRY(scan_id);
  return RequestBody{Cancel{std::move(**scan_id)}};
}

Result<RequestBody> decode_fetch(const Fields& f) {
  PROCAM_TRY(f.only({"scan_id", "file", "offset", "max_bytes"}));
  Fetch r;
  auto scan_id = f.string("scan_id", true, kMaxIdBytes);
  PROCAM_TRY(scan_id);
  r.scan_id = std::move(**scan_id);
  auto file = f.string("file", true, kMaxFileNameBytes);
  PROCAM_TRY(file);
  r.file = std::move(**file);
  if (!is_safe_file_name(r.file))
    return Error(Code::invalid_argument,
                 "field 'file' must be a plain file name from the manifest's \"files\" list, got '" +
                     r.file + "'",
                 "no '/', '\\', '..', leading '.' or control characters");
  auto offset = f.unsigned_int("offset");
  PROCAM_TRY(offset);
  r.offset = offset->value_or(0);
  auto max_bytes = f.unsigned_int("max_bytes");
  PROCAM_TRY(max_bytes);
  r.max_bytes = max_bytes->value_or(kDefaultFetchBytes);
  if (r.max_bytes < 1 || r.max_bytes > kMaxFetchBytes)
    return Error(Code::invalid_argument,
                 "field 'max_bytes' is " + std::to_string(r.max_bytes) + "; it must be 1.." +
                     std::to_string(kMaxFetchBytes),
                 "omit it for the default of 1 MiB");
  return RequestBody{std::move(r)};
}

Result<RequestBody> decode_list_scans(const Fields& f) {
  PROCAM_TRY(f.only({"state", "limit"}));
  ListScans r;
  auto state = f.string("state", false, 16);
  PROCAM_TRY(state);
  if (*state) {
    static const std::array<std::string_view, 7> kStates = {"queued", "capturing", "decoding", "writing",
                                                             "done",   "failed",    "active"};
    if (std::find(kStates.begin(), kStates.end(), **state) == kStates.end())
      return Error(Code::invalid_argument, "field 'state' is '" + **state + "', not a scan state",
                   "one of queued, capturing, decoding, writing, done, failed, or active (not yet final)");
    r.state = std::move(**state);
  }
  auto limit = f.unsigned_int("limit");
  PROCAM_TRY(limit);
  const uint64_t n = limit->value_or(kDefaultListScans);
  if (n < 1 || n > kMaxListScans)
    return Error(Code::invalid_argument,
                 "field 'limit' is " + std::to_string(n) + "; it must be 1.." + std::to_string(kMaxListScans),
                 "omit it for the newest " + std::to_string(kDefaultListScans));
  r.limit = static_cast<uint32_t>(n);
  return RequestBody{std::move(r)};
}

}  // namespace

json board_json(const CalibrateGeometry& c) {
  if (c.board_type == "charuco")
    return {{"type", "charuco"},
            {"squares", {c.board_cols + 1, c.board_rows + 1}},
            {"square_mm", c.square_mm},
            {"marker_mm", c.marker_mm},
            {"dictionary", c.dictionary}};
  return {{"inner_corners", {c.board_cols, c.board_rows}}, {"square_mm", c.square_mm}};
}

namespace {

// calibrate_geometry: {"scans": [ids], "board": {"inner_corners": [c, r],
// "square_mm": s} or {"type": "charuco", "squares": [x, y], "square_mm": s,
// "marker_mm": m, "dictionary": d}, "label"?, "events"?}.
Result<RequestBody> decode_calibrate_geometry(const Fields& f) {
  PROCAM_TRY(f.only({"scans", "board", "label", "events"}));
  CalibrateGeometry c;
  const json* scans = f.find("scans");
  if (!scans) return f.missing("scans");
  if (!scans->is_array()) return f.wrong_type("scans", "an array of scan ids", *scans);
  if (scans->size() < kMinCalibrationScans || scans->size() > kMaxCalibrationScans)
    return Error(Code::invalid_argument,
                 "field 'scans' lists " + std::to_string(scans->size()) + " scans; calibration needs " +
                     std::to_string(kMinCalibrationScans) + ".." + std::to_string(kMaxCalibrationScans),
                 "scan the board in at least 3 poses (5-15 recommended), one gray rows=true scan with "
                 "save_frames each");
  for (const json& id : *scans) {
    if (!id.is_string() || id.get_ref<const std::string&>().empty() ||
        id.get_ref<const std::string&>().size() > kMaxIdBytes)
      return Error(Code::bad_message, "field 'scans' must hold scan ids (strings of 1.." +
                                          std::to_string(kMaxIdBytes) + " bytes), got " + dump(id),
                   kSpecHint);
    const std::string& s = id.get_ref<const std::string&>();
    if (std::find(c.scans.begin(), c.scans.end(), s) != c.scans.end())
      return Error(Code::invalid_argument, "field 'scans' lists scan '" + s + "' twice",
                   "each pose counts once; list every scan id once");
    c.scans.push_back(s);
  }
  const json* board = f.find("board");
  if (!board) return f.missing("board");
  if (!board->is_object()) return f.wrong_type("board", "an object", *board);
  const char* board_form =
      "board is {\"inner_corners\": [cols, rows], \"square_mm\": edge} (chessboard, e.g. "
      "{\"inner_corners\": [9, 7], \"square_mm\": 75}) or {\"type\": \"charuco\", \"squares\": [x, y], "
      "\"square_mm\": edge, \"marker_mm\": side, \"dictionary\": \"DICT_5X5_100\"}";
  const json* type = board->contains("type") ? &(*board)["type"] : nullptr;
  if (type && !(type->is_string() && (*type == "chessboard" || *type == "charuco")))
    return Error(Code::invalid_argument, "field 'board.type' must be \"chessboard\" or \"charuco\", got " + dump(*type),
                 board_form);
  const bool charuco = type && *type == "charuco";
  c.board_type = charuco ? "charuco" : "chessboard";
  const char* grid = charuco ? "squares" : "inner_corners";
  for (const auto& [key, value] : board->items())
    if (key != grid && key != "square_mm" && key != "type" &&
        !(charuco && (key == "marker_mm" || key == "dictionary")))
      return Error(Code::bad_message, "unknown field 'board." + key + "'", board_form);
  const json* ic = board->contains(grid) ? &(*board)[grid] : nullptr;
  if (!ic || !ic->is_array() || ic->size() != 2 || !(*ic)[0].is_number_integer() || !(*ic)[1].is_number_integer())
    return Error(Code::bad_message,
                 std::string("field 'board.") + grid + "' must be " + (charuco ? "[x, y]" : "[cols, rows]") +
                     " (two integers)",
                 board_form);
  // ChArUco boards are given by their squares; both are kept as inner corners.
  const int64_t off = charuco ? 1 : 0;
  const int64_t cols = (*ic)[0].get<int64_t>() - off, rows = (*ic)[1].get<int64_t>() - off;
  if (cols < 2 || cols > 100 || rows < 2 || rows > 100)
    return Error(Code::invalid_argument,
                 std::string("field 'board.") + grid + "' is [" + std::to_string(cols + off) + ", " +
                     std::to_string(rows + off) + "]; each count must be " + (charuco ? "3..101" : "2..100"),
                 charuco ? "count the ChArUco board's squares across and down, e.g. [5, 7]"
                         : "count the inner corners: a board of 10 x 8 squares has 9 x 7");
  c.board_cols = static_cast<int>(cols);
  c.board_rows = static_cast<int>(rows);
  const json* sq = board->contains("square_mm") ? &(*board)["square_mm"] : nullptr;
  if (!sq || !sq->is_number()) return Error(Code::bad_message, "field 'board.square_mm' must be a number", board_form);
  c.square_mm = sq->get<double>();
  if (!(c.square_mm > 0 && c.square_mm <= 1000))
    return Error(Code::invalid_argument, "field 'board.square_mm' must be in (0, 1000] mm, got " + dump(*sq),
                 "measure one square's edge of the printed board, in millimetres");
  if (charuco) {
    // The dictionary's name is checked against OpenCV's when the job runs
    // (procam::calibration::check_board); the engine does not link OpenCV.
    const json* mk = board->contains("marker_mm") ? &(*board)["marker_mm"] : nullptr;
    const json* dict = board->contains("dictionary") ? &(*board)["dictionary"] : nullptr;
    if (!mk || !mk->is_number() || !dict || !dict->is_string() || dict->get_ref<const std::string&>().empty() ||
        dict->get_ref<const std::string&>().size() > 64)
      return Error(Code::bad_message, "a ChArUco board needs 'board.marker_mm' (a number) and 'board.dictionary' "
                                      "(an OpenCV dictionary name)",
                   board_form);
    c.marker_mm = mk->get<double>();
    if (!(c.marker_mm > 0 && c.marker_mm < c.square_mm))
      return Error(Code::invalid_argument, "field 'board.marker_mm' must be > 0 and smaller than square_mm, got " +
                                               dump(*mk),
                   "measure one marker's black edge of the printed board, in millimetres");
    c.dictionary = dict->get<std::string>();
  }
  auto label = f.string("label", false, kMaxLabelBytes, true);
  PROCAM_TRY(label);
  c.label = label->value_or("");
  auto events = f.boolean("events");
  PROCAM_TRY(events);
  c.events = events->value_or(false);
  return RequestBody{std::move(c)};
}

// A request too broken to parse may still carry its id: find a top-level-looking
// "id": "<text>" in the raw bytes so the error reply can be correlated. Only a
// plain id (printable ASCII, no escapes, 1..kMaxIdBytes) is taken; anything
// else leaves the id unknown rather than guessing.
std::string salvage_id(std::string_view bytes) {
  static constexpr std::string_view key = "\"id\"";
  for (size_t at = bytes.find(key); at != std::string_view::npos; at = bytes.find(key, at + 1)) {
    size_t i = at + key.size();
    while (i < bytes.size() && (bytes[i] == ' ' || bytes[i] == '\t' || bytes[i] == '\r' || bytes[i] == '\n')) ++i;
    if (i >= bytes.size() || bytes[i] != ':') continue;
    ++i;
    while (i < bytes.size() && (bytes[i] == ' ' || bytes[i] == '\t' || bytes[i] == '\r' || bytes[i] == '\n')) ++i;
    if (i >= bytes.size() || bytes[i] != '"') continue;
    const size_t begin = ++i;
    while (i < bytes.size() && bytes[i] != '"' && bytes[i] != '\\' && bytes[i] >= 0x20 && bytes[i] < 0x7f) ++i;
    if (i >= bytes.size() || bytes[i] != '"') continue;
    const size_t n = i - begin;
    if (n >= 1 && n <= kMaxIdBytes) return std::string(bytes.substr(begin, n));
  }
  return {};
}

Result<Request> decode_request_impl(std::string_view bytes, std::string* id_out) {
  // The spec forbids a byte-order mark (PROTOCOL.md section 3); nlohmann's
  // parser would skip it silently, so check before parsing.
  if (bytes.size() >= 3 && static_cast<unsigned char>(bytes[0]) == 0xEF &&
      static_cast<unsigned char>(bytes[1]) == 0xBB && static_cast<unsigned char>(bytes[2]) == 0xBF) {
    if (id_out) *id_out = salvage_id(bytes);
    return Error(Code::bad_message, "the body starts with a UTF-8 byte-order mark (EF BB BF)",
                 "send plain UTF-8 JSON without a byte-order mark");
  }
  if (bytes.size() > kMaxRequestBytes) {
    if (id_out) *id_out = salvage_id(bytes);  // linear: a byte search for "id"
    return Error(Code::too_large,
                 "request is " + std::to_string(bytes.size()) + " bytes; the limit is " +
                     std::to_string(kMaxRequestBytes),
                 "params and rig_options are limited to 64 KiB each");
  }
  auto parsed = parse_strict(bytes, kMaxMessageDepth);
  if (!parsed) {
    if (id_out) *id_out = salvage_id(bytes);
    return parsed.status();
  }
  const json& obj = *parsed;
  if (!obj.is_object())
    return Error(Code::bad_message,
                 std::string("a request must be a JSON object, got ") + obj.type_name(),
                 kSpecHint);

  // Remember a usable id first so even a version error can be correlated.
  if (auto it = obj.find("id"); it != obj.end() && it->is_string()) {
    const auto& s = it->get_ref<const std::string&>();
    if (!s.empty() && s.size() <= kMaxIdBytes && id_out) *id_out = s;
  }

  auto pv = obj.find("procam");
  if (pv == obj.end())
    return Error(Code::bad_message, "missing field 'procam' (the protocol version)",
                 "every request carries \"procam\": 1");
  if (!pv->is_number_integer())
    return Error(Code::bad_message,
                 std::string("field 'procam' must be an integer, got ") + pv->type_name(),
                 "every request carries \"procam\": 1");
  if (!pv->is_number_unsigned() || pv->get<uint64_t>() != static_cast<uint64_t>(kVersion))
    return Error(Code::unsupported_version,
                 "protocol version " + dump(*pv) + " is not supported",
                 "this daemon speaks versions " + versions_text() + "; send \"procam\": 1");

  const Fields common(obj, "the");
  auto id = common.string("id", true, kMaxIdBytes);
  PROCAM_TRY(id);

  auto tv = obj.find("type");
  if (tv == obj.end()) return common.missing("type");
  if (!tv->is_string()) return common.wrong_type("type", "a string", *tv);
  const auto& type = tv->get_ref<const std::string&>();

  const Fields f(obj, type);
  Result<RequestBody> body = Error(Code::internal, "unreachable");
  if (type == "hello") {
    body = decode_hello(f);
  } else if (type == "list_plugins") {
    Status s = f.only({});
    body = s.ok() ? Result<RequestBody>(RequestBody{ListPlugins{}}) : Result<RequestBody>(s);
  } else if (type == "describe_rig") {
    Status s = f.only({});
    body = s.ok() ? Result<RequestBody>(RequestBody{DescribeRig{}}) : Result<RequestBody>(s);
  } else if (type == "scan") {
    body = decode_scan(f);
  } else if (type == "status") {
    body = decode_status(f);
  } else if (type == "result") {
    body = decode_result(f);
  } else if (type == "fetch") {
    body = decode_fetch(f);
  } else if (type == "cancel") {
    body = decode_cancel(f);
  } else if (type == "ping") {
    Status s = f.only({});
    body = s.ok() ? Result<RequestBody>(RequestBody{Ping{}}) : Result<RequestBody>(s);
  } else if (type == "list_scans") {
    body = decode_list_scans(f);
  } else if (type == "list_rig_options") {
    Status s = f.only({});
    body = s.ok() ? Result<RequestBody>(RequestBody{ListRigOptions{}}) : Result<RequestBody>(s);
  } else if (type == "calibrate_geometry") {
    body = decode_calibrate_geometry(f);
  } else {
    std::vector<std::string> names(kTypes.begin(), kTypes.end());
    return Error(Code::unknown_type, "unknown request type '" + type + "'",
                 "request types: " + join(names, ", "));
  }
  PROCAM_TRY(body);
  return Request{std::move(**id), std::move(*body)};
}

json request_fields(const RequestBody& body) {
  struct Visitor {
    json operator()(const Hello& h) const {
      json j = {{"versions", h.versions}};
      if (!h.client.empty()) j["client"] = h.client;
      return j;
    }
    json operator()(const ListPlugins&) const { return json::object(); }
    json operator()(const DescribeRig&) const { return json::object(); }
    json operator()(const Scan& s) const {
      json j = {{"plugin", s.plugin}, {"method", s.method},
                {"params", s.params.is_null() ? json::object() : s.params}};
      if (!s.rig_options.is_null() && !s.rig_options.empty()) j["rig_options"] = s.rig_options;
      if (s.events) j["events"] = true;
      if (!s.label.empty()) j["label"] = s.label;
      if (s.save_frames) j["save_frames"] = true;
      if (!s.inputs.empty()) {
        json in = json::object();
        for (const auto& [name, ref] : s.inputs) in[name] = {{"scan", ref.scan_id}, {"output", ref.output}};
        j["inputs"] = std::move(in);
      }
      return j;
    }
    json operator()(const StatusQuery& s) const {
      json j = json::object();
      if (s.scan_id) j["scan_id"] = *s.scan_id;
      return j;
    }
    json operator()(const ResultQuery& r) const { return {{"scan_id", r.scan_id}}; }
    json operator()(const Fetch& f) const {
      return {{"scan_id", f.scan_id}, {"file", f.file}, {"offset", f.offset},
              {"max_bytes", f.max_bytes}};
    }
    json operator()(const Cancel& c) const { return {{"scan_id", c.scan_id}}; }
    json operator()(const Ping&) const { return json::object(); }
    json operator()(const ListScans& l) const {
      json j = {{"limit", l.limit}};
      if (l.state) j["state"] = *l.state;
      return j;
    }
    json operator()(const ListRigOptions&) const { return json::object(); }
    json operator()(const CalibrateGeometry& c) const {
      json j = {{"scans", c.scans},
                {"board", board_json(c)}};
      if (c.events) j["events"] = true;
      if (!c.label.empty()) j["label"] = c.label;
      return j;
    }
  };
  return std::visit(Visitor{}, body);
}

// Last-resort body when encoding itself failed (out of memory, caller bug).
std::string fallback_error(std::string_view what) {
  json j = {{"procam", kVersion}, {"id", nullptr}, {"type", "error"}, {"ok", false},
            {"error", {{"code", "internal"},
                       {"message", "failed to encode a message: " + std::string(what)},
                       {"hint", "this is a bug in procam: please report it"}}}};
  try {
    return dump(j);
  } catch (...) {
    return R"({"procam":1,"id":null,"type":"error","ok":false,"error":{"code":"internal","message":"failed to encode a message","hint":""}})";
  }
}

json without(const json& obj, std::initializer_list<const char*> keys) {
  json body = obj;
  for (const char* k : keys) body.erase(k);
  return body;
}

Result<Incoming> decode_incoming_impl(std::string_view bytes) {
  auto parsed = parse_strict(bytes, 256);
  PROCAM_TRY(parsed);
  const json& obj = *parsed;
  if (!obj.is_object())
    return Error(Code::bad_message,
                 std::string("a reply or event must be a JSON object, got ") + obj.type_name());
  auto pv = obj.find("procam");
  if (pv == obj.end() || !pv->is_number_integer())
    return Error(Code::bad_message, "reply without an integer 'procam' field");
  if (!pv->is_number_unsigned() || pv->get<uint64_t>() != static_cast<uint64_t>(kVersion))
    return Error(Code::unsupported_version,
                 "daemon sent protocol version " + dump(*pv) + "; this client speaks " +
                     versions_text());
  auto tv = obj.find("type");
  if (tv == obj.end() || !tv->is_string())
    return Error(Code::bad_message, "reply without a string 'type' field");
  const auto& type = tv->get_ref<const std::string&>();

  if (type == "event") {
    Event e;
    auto sid = obj.find("scan_id");
    auto seq = obj.find("seq");
    auto ev = obj.find("event");
    if (sid == obj.end() || !sid->is_string())
      return Error(Code::bad_message, "event without a string 'scan_id'");
    if (seq == obj.end() || !seq->is_number_unsigned())
      return Error(Code::bad_message, "event without a non-negative integer 'seq'");
    if (ev == obj.end() || !ev->is_string())
      return Error(Code::bad_message, "event without a string 'event'");
    e.scan_id = sid->get<std::string>();
    e.seq = seq->get<uint64_t>();
    e.event = ev->get<std::string>();
    e.body = without(obj, {"procam", "type", "scan_id", "seq", "event"});
    return Incoming{std::move(e)};
  }

  Reply r;
  r.type = type;
  auto okv = obj.find("ok");
  if (okv == obj.end() || !okv->is_boolean())
    return Error(Code::bad_message, "reply without a boolean 'ok' field");
  r.ok = okv->get<bool>();
  auto idv = obj.find("id");
  if (idv == obj.end()) return Error(Code::bad_message, "reply without an 'id' field");
  if (idv->is_string()) {
    r.id = idv->get<std::string>();
  } else if (!(idv->is_null() && !r.ok)) {
    return Error(Code::bad_message, "reply 'id' must be a string (null only in error replies)");
  }
  if (r.ok != (type != "error"))
    return Error(Code::bad_message, "reply has type '" + type + "' but ok " +
                                        (r.ok ? "true" : "false") +
                                        " (error replies have type \"error\" and ok false)");
  if (!r.ok) {
    auto errv = obj.find("error");
    if (errv == obj.end()) return Error(Code::bad_message, "error reply without an 'error' object");
    auto st = error_from_json(*errv);
    if (!st)
      return Error(Code::bad_message,
                   "error reply whose 'error' is not {\"code\": string, \"message\": string, ...}");
    r.error = std::move(*st);
  }
  r.body = without(obj, {"procam", "id", "type", "ok"});
  return Incoming{std::move(r)};
}

}  // namespace

// ---- Public -----------------------------------------------------------------

std::vector<int> supported_versions() { return {kVersion}; }

std::string_view type_name(const RequestBody& body) {
  return kTypes.at(body.index());
}

Result<Request> decode_request(std::string_view bytes, std::string* id_out) {
  try {
    return decode_request_impl(bytes, id_out);
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("decoding a request failed: ") + e.what(),
                 "this is a bug in procam: please report it");
  } catch (...) {
    return Error(Code::internal, "decoding a request failed", "this is a bug in procam");
  }
}

std::string encode_request(const Request& request) {
  try {
    json j = request_fields(request.body);
    j["procam"] = kVersion;
    j["id"] = request.id;
    j["type"] = std::string(type_name(request.body));
    return dump(j);
  } catch (const std::exception& e) {
    return fallback_error(e.what());
  }
}

Result<int> negotiate_version(const Hello& hello) {
  int best = 0;
  for (int ours : supported_versions())
    if (std::find(hello.versions.begin(), hello.versions.end(), ours) != hello.versions.end())
      best = std::max(best, ours);
  if (best > 0) return best;
  std::vector<std::string> theirs;
  for (int v : hello.versions) theirs.push_back(std::to_string(v));
  return Error(Code::unsupported_version,
               "no common protocol version: client speaks [" + join(theirs, ", ") +
                   "], daemon speaks " + versions_text(),
               "use a client built for protocol version " + versions_text());
}

std::string encode_reply(const std::string& id, std::string_view type, nlohmann::json fields) {
  try {
    if (fields.is_null()) fields = json::object();
    if (!fields.is_object())
      return encode_error(id, Error(Code::internal, "reply fields for '" + std::string(type) +
                                                        "' are not a JSON object"));
    fields["procam"] = kVersion;
    fields["id"] = id;
    fields["type"] = std::string(type);
    fields["ok"] = true;
    return dump(fields);
  } catch (const std::exception& e) {
    return fallback_error(e.what());
  }
}

nlohmann::json error_to_json(const Status& error) {
  const Code code = error.ok() ? Code::internal : error.code();
  json j = {{"code", code_name(code)},
            {"message", error.ok() ? std::string("an error was reported without a cause")
                                   : error.message()},
            {"hint", error.hint()}};
  if (code == Code::unsupported_version) j["supported_versions"] = supported_versions();
  return j;
}

std::optional<Status> error_from_json(const nlohmann::json& error) {
  try {
    if (!error.is_object()) return std::nullopt;
    auto c = error.find("code");
    auto m = error.find("message");
    if (c == error.end() || !c->is_string() || m == error.end() || !m->is_string())
      return std::nullopt;
    std::string hint;
    if (auto h = error.find("hint"); h != error.end() && h->is_string()) hint = h->get<std::string>();
    const auto& name = c->get_ref<const std::string&>();
    const auto code = code_from_name(name);
    if (code == Code::ok) return std::nullopt;
    if (!code) return Status(Code::internal, "[" + name + "] " + m->get<std::string>(), hint);
    return Status(*code, m->get<std::string>(), hint);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::optional<Code> code_from_name(std::string_view name) {
  static constexpr std::array kAll = {
      Code::ok,           Code::invalid_argument, Code::not_found,   Code::unavailable,
      Code::failed_precondition, Code::io_error,  Code::corrupt_data, Code::abi_mismatch,
      Code::plugin_error, Code::timeout,          Code::cancelled,   Code::internal,
      Code::bad_message,  Code::unsupported_version, Code::unknown_type, Code::too_large};
  for (Code c : kAll)
    if (name == code_name(c)) return c;
  return std::nullopt;
}

std::string encode_error(const std::optional<std::string>& id, const Status& error) {
  try {
    json j = {{"procam", kVersion}, {"type", "error"}, {"ok", false},
              {"error", error_to_json(error)}};
    j["id"] = id ? json(*id) : json(nullptr);
    return dump(j);
  } catch (const std::exception& e) {
    return fallback_error(e.what());
  }
}

std::string encode_event(const std::string& scan_id, uint64_t seq, std::string_view event,
                         nlohmann::json fields) {
  try {
    if (fields.is_null()) fields = json::object();
    if (!fields.is_object()) fields = json{{"value", std::move(fields)}};
    fields["procam"] = kVersion;
    fields["type"] = "event";
    fields["scan_id"] = scan_id;
    fields["seq"] = seq;
    fields["event"] = std::string(event);
    return dump(fields);
  } catch (const std::exception& e) {
    return fallback_error(e.what());
  }
}

Result<Incoming> decode_incoming(std::string_view bytes) {
  try {
    return decode_incoming_impl(bytes);
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("decoding a reply failed: ") + e.what());
  } catch (...) {
    return Error(Code::internal, "decoding a reply failed");
  }
}

bool is_valid_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxNameBytes) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

bool is_output_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxNameBytes) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

bool is_safe_file_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxFileNameBytes) return false;
  if (name.front() == '.') return false;
  if (name.find("..") != std::string_view::npos) return false;
  return std::none_of(name.begin(), name.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return c == '/' || c == '\\' || u < 0x20 || u == 0x7f;
  });
}

std::string utc_timestamp(std::chrono::system_clock::time_point t) {
  using namespace std::chrono;
  const auto ms = floor<milliseconds>(t.time_since_epoch()).count();
  const auto secs = static_cast<std::time_t>(ms >= 0 ? ms / 1000 : (ms - 999) / 1000);
  const auto frac = static_cast<int>(ms - static_cast<long long>(secs) * 1000);
  std::tm tm{};
  if (!gmtime_r(&secs, &tm)) return "1970-01-01T00:00:00.000Z";
  char buf[40];
  const size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  std::snprintf(buf + n, sizeof buf - n, ".%03dZ", frac);
  return buf;
}

}  // namespace procam::proto
