// SPDX-License-Identifier: MIT
// Tests of procam::proto: round trips, every validation rule, hostile input,
// reply/event encoding, and the examples of PROTOCOL.md against the decoder.
#include "procam/proto/protocol.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <set>
#include <sstream>

namespace procam::proto {
namespace {

using json = nlohmann::json;

// A valid scan request as JSON, to be modified by tests.
json scan_json() {
  return {{"procam", 1}, {"id", "r1"}, {"type", "scan"}, {"plugin", "structured-light"},
          {"method", "gray"}};
}

std::string nested_object(int depth) {  // {"a":{"a":...{}}} with `depth` objects
  std::string s;
  for (int i = 1; i < depth; ++i) s += "{\"a\":";
  s += "{}";
  for (int i = 1; i < depth; ++i) s += "}";
  return s;
}

// Expects decoding to fail with `code` and a message containing `needle`;
// returns the id the decoder reported ("<none>" when it set none).
std::string expect_error(std::string_view bytes, Code code, std::string_view needle) {
  std::string id = "<none>";
  auto r = decode_request(bytes, &id);
  EXPECT_FALSE(r.ok()) << "accepted: " << bytes.substr(0, 200);
  if (r.ok()) return id;
  EXPECT_EQ(r.status().code(), code) << r.status().to_string();
  EXPECT_NE(r.status().message().find(needle), std::string::npos)
      << "message '" << r.status().message() << "' does not mention '" << needle << "'";
  return id;
}
std::string expect_error_j(const json& j, Code code, std::string_view needle) {
  return expect_error(j.dump(), code, needle);
}

// ---- Round trips --------------------------------------------------------------

TEST(ProtoRequest, EveryTypeRoundTrips) {
  Scan scan;
  scan.plugin = "structured-light";
  scan.method = "gray_xor-02";
  scan.params = {{"bits", 10}, {"nested", {{"list", {1, 2.5, "x", nullptr}}}}};
  scan.rig_options = {{"scene", "tilted-box"}};
  scan.events = true;
  scan.label = "bench \xC3\xA9t\xC3\xA9 test";  // UTF-8
  scan.inputs = {{"depth_mm", {"20250301T120000Z-0001", "depth_mm"}}, {"ref_px", {"s2", "proj_col_px"}}};
  Fetch fetch{"20250301T120000Z-0001", "depth_mm.exr", 3u << 20, 8u << 20};
  const std::vector<Request> requests = {
      {"1", Hello{{1, 7}, "cli/0.1"}},
      {"h", Hello{{1}, ""}},
      {"2", ListPlugins{}},
      {"3", DescribeRig{}},
      {"4", scan},
      {"4b", Scan{"p", "m", json::object(), json::object(), false, "", false, {}}},
      {"5", StatusQuery{}},
      {"6", StatusQuery{"scan-1"}},
      {"7", ResultQuery{"scan-1"}},
      {"8", fetch},
      {"9", Fetch{"s", "f.ply"}},
      {"10", Cancel{"scan-1"}},
      {"11", Ping{}},
      {"12", ListScans{}},
      {"13", ListScans{"active", 5}},
      {"14", ListRigOptions{}},
      {"15", CalibrateGeometry{{"s1", "s2", "s3"}, 9, 7, 75.0, true, "desk rig", "chessboard", 0, ""}},
      {"16", CalibrateGeometry{{"a", "b", "c", "d"}, 2, 100, 0.5, false, "", "chessboard", 0, ""}},
      {"16c", CalibrateGeometry{{"a", "b", "c"}, 4, 6, 40, false, "", "charuco", 30, "DICT_5X5_100"}},
      {std::string(kMaxIdBytes, 'x'), ListPlugins{}},
  };
  std::set<std::string_view> types;
  for (const auto& req : requests) {
    const std::string wire = encode_request(req);
    auto back = decode_request(wire);
    ASSERT_TRUE(back.ok()) << wire << " -> " << back.status().to_string();
    EXPECT_EQ(*back, req) << wire;
    EXPECT_EQ(json::parse(wire).at("type"), type_name(req.body));
    types.insert(type_name(req.body));
  }
  EXPECT_EQ(types.size(), std::variant_size_v<RequestBody>);
}

TEST(ProtoRequest, CalibrateGeometryFieldsAreChecked) {
  const std::string head = R"({"procam":1,"id":"a","type":"calibrate_geometry",)";
  const std::string board = R"("board":{"inner_corners":[9,7],"square_mm":75})";
  auto r = decode_request(head + R"("scans":["x","y","z"],)" + board + "}");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const auto& c = std::get<CalibrateGeometry>(r->body);
  EXPECT_EQ(c.scans.size(), 3u);
  EXPECT_EQ(c.board_cols, 9);
  EXPECT_EQ(c.board_rows, 7);
  EXPECT_DOUBLE_EQ(c.square_mm, 75.0);
  expect_error(head + board + "}", Code::bad_message, "missing field 'scans'");
  expect_error(head + R"("scans":["x","y"],)" + board + "}", Code::invalid_argument, "calibration needs 3..50");
  expect_error(head + R"("scans":["x","y","x"],)" + board + "}", Code::invalid_argument, "scan 'x' twice");
  expect_error(head + R"("scans":["x","y",7],)" + board + "}", Code::bad_message, "must hold scan ids");
  expect_error(head + R"("scans":["x","y","z"]})", Code::bad_message, "missing field 'board'");
  expect_error(head + R"("scans":["x","y","z"],"board":{"inner_corners":[9],"square_mm":75}})", Code::bad_message,
               "'board.inner_corners' must be [cols, rows]");
  expect_error(head + R"("scans":["x","y","z"],"board":{"inner_corners":[1,7],"square_mm":75}})",
               Code::invalid_argument, "each count must be 2..100");
  expect_error(head + R"("scans":["x","y","z"],"board":{"inner_corners":[9,7],"square_mm":0}})",
               Code::invalid_argument, "'board.square_mm' must be in (0, 1000]");
  expect_error(head + R"("scans":["x","y","z"],"board":{"inner_corners":[9,7],"square_mm":75,"kind":"x"}})",
               Code::bad_message, "unknown field 'board.kind'");
  expect_error(head + R"("scans":["x","y","z"],)" + board + R"(,"method":"gray"})", Code::bad_message,
               "unknown field 'method'");
}

TEST(ProtoRequest, CalibrateGeometryTakesAChArUcoBoard) {
  const std::string head = R"({"procam":1,"id":"a","type":"calibrate_geometry","scans":["x","y","z"],)";
  const std::string charuco =
      R"("board":{"type":"charuco","squares":[5,7],"square_mm":40,"marker_mm":30,"dictionary":"DICT_5X5_100"}})";
  auto r = decode_request(head + charuco);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const auto& c = std::get<CalibrateGeometry>(r->body);
  EXPECT_EQ(c.board_type, "charuco");
  EXPECT_EQ(c.board_cols, 4);  // inner corners: squares - 1
  EXPECT_EQ(c.board_rows, 6);
  EXPECT_DOUBLE_EQ(c.marker_mm, 30);
  EXPECT_EQ(c.dictionary, "DICT_5X5_100");
  // Encoded back as sent.
  const nlohmann::json b = board_json(c);
  EXPECT_EQ(b["squares"], nlohmann::json({5, 7}));
  EXPECT_EQ(b["type"], "charuco");
  auto again = decode_request(encode_request(Request{"a", c}));
  ASSERT_TRUE(again.ok()) << again.status().to_string();
  EXPECT_EQ(std::get<CalibrateGeometry>(again->body), c);
  expect_error(head + R"("board":{"type":"charuco","squares":[5,7],"square_mm":40,"marker_mm":40,"dictionary":"D"}})",
               Code::invalid_argument, "smaller than square_mm");
  expect_error(head + R"("board":{"type":"charuco","squares":[5,7],"square_mm":40,"marker_mm":30}})",
               Code::bad_message, "needs 'board.marker_mm' (a number) and 'board.dictionary'");
  expect_error(head + R"("board":{"type":"charuco","squares":[2,7],"square_mm":40,"marker_mm":30,"dictionary":"D"}})",
               Code::invalid_argument, "each count must be 3..101");
  expect_error(head + R"("board":{"type":"aruco","squares":[5,7],"square_mm":40}})", Code::invalid_argument,
               "must be \"chessboard\" or \"charuco\"");
  expect_error(head + R"("board":{"inner_corners":[9,7],"square_mm":75,"dictionary":"D"}})", Code::bad_message,
               "unknown field 'board.dictionary'");
}

TEST(ProtoRequest, ListScansFiltersAreChecked) {
  auto r = decode_request(R"({"procam":1,"id":"a","type":"list_scans"})");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(std::get<ListScans>(r->body).limit, kDefaultListScans);
  EXPECT_FALSE(std::get<ListScans>(r->body).state.has_value());
  r = decode_request(R"({"procam":1,"id":"a","type":"list_scans","limit":1000,"state":"failed"})");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(std::get<ListScans>(r->body).limit, 1000u);
  expect_error(R"({"procam":1,"id":"a","type":"list_scans","state":"sleeping"})", Code::invalid_argument, "'state'");
  expect_error(R"({"procam":1,"id":"a","type":"list_scans","limit":0})", Code::invalid_argument, "'limit'");
  expect_error(R"({"procam":1,"id":"a","type":"list_scans","limit":1001})", Code::invalid_argument, "1..1000");
  expect_error(R"({"procam":1,"id":"a","type":"list_scans","limit":"5"})", Code::bad_message, "'limit'");
  expect_error(R"({"procam":1,"id":"a","type":"list_scans","since":"x"})", Code::bad_message, "'since'");
  expect_error(R"({"procam":1,"id":"a","type":"list_rig_options","scene":"x"})", Code::bad_message, "'scene'");
}

TEST(ProtoRequest, DefaultsApplyWhenFieldsAreAbsent) {
  auto r = decode_request(scan_json().dump());
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const auto& s = std::get<Scan>(r->body);
  EXPECT_EQ(s.params, json::object());
  EXPECT_EQ(s.rig_options, json::object());
  EXPECT_FALSE(s.events);
  EXPECT_EQ(s.label, "");

  auto f = decode_request(R"({"procam":1,"id":"x","type":"fetch","scan_id":"s","file":"a.exr"})");
  ASSERT_TRUE(f.ok()) << f.status().to_string();
  EXPECT_EQ(std::get<Fetch>(f->body).offset, 0u);
  EXPECT_EQ(std::get<Fetch>(f->body).max_bytes, kDefaultFetchBytes);

  auto st = decode_request(R"({"procam":1,"id":"x","type":"status"})");
  ASSERT_TRUE(st.ok());
  EXPECT_FALSE(std::get<StatusQuery>(st->body).scan_id.has_value());
}

TEST(ProtoRequest, WhitespaceAndKeyOrderDoNotMatter) {
  auto r = decode_request(" \n{ \"type\" : \"result\" ,\n\t\"scan_id\":\"s\", \"id\":\"q\",\"procam\":1}\r\n");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->id, "q");
  EXPECT_EQ(std::get<ResultQuery>(r->body).scan_id, "s");
}

// ---- Envelope validation --------------------------------------------------------

TEST(ProtoRequest, RejectsNonJsonAndNonObjects) {
  expect_error("hello world", Code::bad_message, "JSON");
  expect_error("", Code::bad_message, "JSON");
  expect_error("[1,2,3]", Code::bad_message, "array");
  expect_error("\"scan\"", Code::bad_message, "string");
  expect_error("42", Code::bad_message, "number");
  expect_error("null", Code::bad_message, "null");
  expect_error(R"({"procam":1,"id":"a","type":"status"} {})", Code::bad_message, "JSON");
}

TEST(ProtoRequest, RejectsBinaryGarbage) {
  const std::string garbage("\x00\xff\xfe\x01{\x80\x81}\x00", 10);
  expect_error(garbage, Code::bad_message, "JSON");
  // Invalid UTF-8 inside an otherwise valid string.
  expect_error(std::string(R"({"procam":1,"id":"a","type":"scan","plugin":"p","method":"m","label":")") +
                   "\xC3\x28" + "\"}",
               Code::bad_message, "UTF-8");
  std::mt19937 rng(1234);
  for (int i = 0; i < 200; ++i) {
    std::string b(static_cast<size_t>(rng() % 64), '\0');
    for (auto& c : b) c = static_cast<char>(rng() & 0xff);
    auto r = decode_request(b);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Code::bad_message) << r.status().to_string();
  }
}

TEST(ProtoRequest, EveryTruncationIsBadMessage) {
  Scan s{"structured-light", "gray", {{"bits", 10}}, {{"scene", "v-groove"}}, true, "t", false, {}};
  const std::string wire = encode_request({"abc", s});
  ASSERT_TRUE(decode_request(wire).ok());
  for (size_t n = 0; n < wire.size(); ++n) {
    auto r = decode_request(std::string_view(wire).substr(0, n));
    ASSERT_FALSE(r.ok()) << n;
    EXPECT_EQ(r.status().code(), Code::bad_message) << n << ": " << r.status().to_string();
  }
}

TEST(ProtoRequest, MutatedRequestsNeverCrashOrReportInternal) {
  const std::string wire = encode_request(
      {"abc", Fetch{"20250301T120000Z-0001", "depth_mm.exr", 12, 4096}});
  std::mt19937 rng(99);
  int accepted = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string m = wire;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits; ++e) {
      const size_t pos = rng() % m.size();
      switch (rng() % 3) {
        case 0: m[pos] = static_cast<char>(rng() & 0xff); break;
        case 1: m.erase(pos, 1); break;
        default: m.insert(pos, 1, "{}[]\",:0a\\"[rng() % 10]); break;
      }
    }
    auto r = decode_request(m);
    if (r.ok()) {
      ++accepted;
      continue;
    }
    EXPECT_NE(r.status().code(), Code::internal) << m << " -> " << r.status().to_string();
    EXPECT_FALSE(r.status().message().empty());
  }
  EXPECT_LT(accepted, 3000);
}

TEST(ProtoRequest, RejectsOversizedMessages) {
  json j = scan_json();
  j["label"] = std::string(kMaxRequestBytes, 'x');
  std::string id = expect_error_j(j, Code::too_large, "1048576");
  EXPECT_EQ(id, "r1");  // not parsed, but the id is still found for the reply
  // Exactly at the limit is allowed through the size check (and fails later on the label).
  std::string body = scan_json().dump();
  body.insert(body.size() - 1, std::string(kMaxRequestBytes - body.size(), ' '));
  ASSERT_EQ(body.size(), kMaxRequestBytes);
  EXPECT_TRUE(decode_request(body).ok());
}

TEST(ProtoRequest, RejectsDeepNestingWithoutRecursion) {
  // A million '[' must neither crash nor take long: the depth check stops the parser.
  const std::string deep(kMaxRequestBytes, '[');
  expect_error(deep, Code::too_large, "nesting");
  json j = scan_json();
  j["params"] = json::parse(nested_object(10));
  std::string wire = j.dump();
  wire.insert(wire.size() - 1, ",\"x\":" + std::string(40, '[') + std::string(40, ']'));
  expect_error(wire, Code::too_large, "nesting");
}

TEST(ProtoRequest, RejectsDuplicateKeys) {
  expect_error(R"({"procam":1,"id":"a","id":"b","type":"status"})", Code::bad_message,
               "duplicate key 'id'");
  expect_error(R"({"procam":1,"id":"a","type":"scan","plugin":"p","method":"m","params":{"k":1,"k":2}})",
               Code::bad_message, "duplicate key 'k'");
  // The same key in sibling objects is fine.
  EXPECT_TRUE(decode_request(
                  R"({"procam":1,"id":"a","type":"scan","plugin":"p","method":"m","params":{"a":{"k":1},"b":{"k":2}}})")
                  .ok());
}

TEST(ProtoRequest, RejectsBadIds) {
  json j = scan_json();
  j.erase("id");
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'id'"), "<none>");
  j["id"] = std::string(kMaxIdBytes + 1, 'x');
  EXPECT_EQ(expect_error_j(j, Code::too_large, "'id'"), "<none>");
  j["id"] = 42;
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'id'"), "<none>");
  j["id"] = "";
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'id'"), "<none>");
  j["id"] = nullptr;
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'id'"), "<none>");
}

TEST(ProtoRequest, RejectsWrongVersions) {
  json j = scan_json();
  j["procam"] = 2;
  EXPECT_EQ(expect_error_j(j, Code::unsupported_version, "version 2"), "r1");
  j["procam"] = 0;
  expect_error_j(j, Code::unsupported_version, "version 0");
  j["procam"] = -1;
  expect_error_j(j, Code::unsupported_version, "version -1");
  j["procam"] = "1";
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'procam'"), "r1");
  j["procam"] = 1.0;
  expect_error_j(j, Code::bad_message, "'procam'");
  j.erase("procam");
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'procam'"), "r1");
  // The hint tells the client what to send.
  auto r = decode_request(R"({"procam":3,"id":"a","type":"status"})");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().hint().find("[1]"), std::string::npos) << r.status().hint();
}

TEST(ProtoRequest, RejectsUnknownTypesAndFields) {
  json j = scan_json();
  j["type"] = "delete_scan";
  EXPECT_EQ(expect_error_j(j, Code::unknown_type, "'delete_scan'"), "r1");
  for (const char* t : {"error", "event", "Scan", ""}) {
    j["type"] = t;
    expect_error_j(j, Code::unknown_type, "unknown request type");
  }
  j["type"] = 7;
  expect_error_j(j, Code::bad_message, "'type'");
  j.erase("type");
  expect_error_j(j, Code::bad_message, "'type'");

  j = scan_json();
  j["param"] = {{"bits", 10}};  // typo of "params"
  EXPECT_EQ(expect_error_j(j, Code::bad_message, "'param'"), "r1");
  auto r = decode_request(j.dump());
  EXPECT_NE(r.status().hint().find("params"), std::string::npos) << r.status().hint();
  expect_error(R"({"procam":1,"id":"a","type":"list_plugins","verbose":true})", Code::bad_message,
               "'verbose'");
  expect_error(R"({"procam":1,"id":"a","type":"describe_rig","x":1})", Code::bad_message, "'x'");
  expect_error(R"({"procam":1,"id":"a","type":"status","scan":"s"})", Code::bad_message, "'scan'");
  expect_error(R"({"procam":1,"id":"a","type":"result","scan_id":"s","offset":0})",
               Code::bad_message, "'offset'");
  expect_error(R"({"procam":1,"id":"a","type":"hello","versions":[1],"Client":"x"})",
               Code::bad_message, "'Client'");
  expect_error(R"({"procam":1,"id":"a","type":"status","ok":true})", Code::bad_message, "'ok'");
}

// ---- Per-type validation ----------------------------------------------------------

TEST(ProtoScan, RejectsBadNames) {
  for (const char* bad : {"Structured", "a b", "x/y", "gr\xC3\xA9y", "semi;colon", "dot.name"}) {
    json j = scan_json();
    j["plugin"] = bad;
    EXPECT_EQ(expect_error_j(j, Code::invalid_argument, "'plugin'"), "r1") << bad;
    j = scan_json();
    j["method"] = bad;
    expect_error_j(j, Code::invalid_argument, "'method'");
  }
  json j = scan_json();
  j["plugin"] = std::string(kMaxNameBytes + 1, 'a');
  expect_error_j(j, Code::too_large, "'plugin'");
  j["plugin"] = std::string(kMaxNameBytes, 'a');
  EXPECT_TRUE(decode_request(j.dump()).ok());
  j["plugin"] = "";
  expect_error_j(j, Code::bad_message, "'plugin'");
  j["plugin"] = 3;
  expect_error_j(j, Code::bad_message, "'plugin'");
  j.erase("plugin");
  expect_error_j(j, Code::bad_message, "'plugin'");
  j = scan_json();
  j.erase("method");
  expect_error_j(j, Code::bad_message, "'method'");
}

TEST(ProtoScan, ValidatesParamsAndRigOptions) {
  for (const char* field : {"params", "rig_options"}) {
    SCOPED_TRACE(field);
    json j = scan_json();
    for (json bad : {json::array({1}), json("x"), json(1), json(nullptr), json(true)}) {
      j[field] = bad;
      EXPECT_EQ(expect_error_j(j, Code::bad_message, "'" + std::string(field) + "'"), "r1");
    }
    j[field] = json::parse(nested_object(kMaxParamsDepth));
    EXPECT_TRUE(decode_request(j.dump()).ok());
    j[field] = json::parse(nested_object(kMaxParamsDepth + 1));
    expect_error_j(j, Code::too_large, "'" + std::string(field) + "' is nested 17");
    // Arrays count as levels too.
    j[field] = {{"a", json::parse(std::string(kMaxParamsDepth, '[') + std::string(kMaxParamsDepth, ']'))}};
    expect_error_j(j, Code::too_large, "nested");
    j[field] = {{"blob", std::string(kMaxParamsBytes, 'x')}};
    expect_error_j(j, Code::too_large, "'" + std::string(field) + "' is");
    j[field] = {{"b", std::string(kMaxParamsBytes - 8, 'x')}};  // {"b":"..."} is exactly 64 KiB
    ASSERT_EQ(j[field].dump().size(), kMaxParamsBytes);
    EXPECT_TRUE(decode_request(j.dump()).ok());
  }
}

TEST(ProtoScan, ValidatesInputs) {
  json j = scan_json();
  j["inputs"] = {{"depth_mm", {{"scan", "20250301T120000Z-0001"}, {"output", "depth_mm"}}}};
  auto r = decode_request(j.dump());
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const Scan& s = std::get<Scan>(r->body);
  ASSERT_EQ(s.inputs.size(), 1u);
  EXPECT_EQ(s.inputs.at("depth_mm"), (InputRef{"20250301T120000Z-0001", "depth_mm"}));
  j["inputs"] = json::object();  // empty = none
  EXPECT_TRUE(decode_request(j.dump()).ok());

  j["inputs"] = json::array();
  expect_error_j(j, Code::bad_message, "field 'inputs' must be an object");
  j["inputs"] = {{"depth_mm", "scan-1"}};
  expect_error_j(j, Code::bad_message, "field 'inputs.depth_mm' must be an object");
  j["inputs"] = {{"depth_mm", {{"scan", "s"}}}};
  expect_error_j(j, Code::bad_message, "needs 'scan' and 'output'");
  j["inputs"] = {{"depth_mm", {{"scan", "s"}, {"output", "depth_mm"}, {"file", "x"}}}};
  expect_error_j(j, Code::bad_message, "unknown field 'inputs.depth_mm.file'");
  j["inputs"] = {{"depth_mm", {{"scan", 7}, {"output", "depth_mm"}}}};
  expect_error_j(j, Code::bad_message, "must be strings");
  j["inputs"] = {{"depth_mm", {{"scan", ""}, {"output", "depth_mm"}}}};
  expect_error_j(j, Code::bad_message, "'inputs.depth_mm.scan' must not be empty");
  j["inputs"] = {{"depth_mm", {{"scan", std::string(kMaxIdBytes + 1, 's')}, {"output", "depth_mm"}}}};
  expect_error_j(j, Code::too_large, "'inputs.depth_mm.scan'");
  j["inputs"] = {{"depth_mm", {{"scan", "s"}, {"output", "../depth"}}}};
  expect_error_j(j, Code::invalid_argument, "'inputs.depth_mm.output' has characters outside [a-z0-9_]");
  j["inputs"] = {{"Depth-MM", {{"scan", "s"}, {"output", "depth_mm"}}}};
  expect_error_j(j, Code::invalid_argument, "input name 'Depth-MM'");
  json many = json::object();
  for (size_t i = 0; i <= kMaxScanInputs; ++i)
    many["in" + std::to_string(i)] = {{"scan", "s"}, {"output", "depth_mm"}};
  j["inputs"] = many;
  expect_error_j(j, Code::too_large, "field 'inputs' has 17 entries");
}

TEST(ProtoScan, ValidatesEventsAndLabel) {
  json j = scan_json();
  j["events"] = "yes";
  expect_error_j(j, Code::bad_message, "'events'");
  j["events"] = 1;
  expect_error_j(j, Code::bad_message, "'events'");
  j["events"] = false;
  j["label"] = std::string(kMaxLabelBytes + 1, 'l');
  expect_error_j(j, Code::too_large, "'label'");
  j["label"] = std::string(kMaxLabelBytes, 'l');
  EXPECT_TRUE(decode_request(j.dump()).ok());
  j["label"] = "";
  EXPECT_TRUE(decode_request(j.dump()).ok());
  j["label"] = 5;
  expect_error_j(j, Code::bad_message, "'label'");
}

TEST(ProtoFetch, RejectsUnsafeFileNames) {
  json j = {{"procam", 1}, {"id", "f1"}, {"type", "fetch"}, {"scan_id", "s"}};
  for (const char* bad : {"../x", "a/b", "/etc/passwd", "..", ".", ".hidden", "a..b", "a\\b",
                          "a\x01" "b", "tab\there", "del\x7f"}) {
    j["file"] = bad;
    EXPECT_EQ(expect_error_j(j, Code::invalid_argument, "'file'"), "f1") << bad;
  }
  j["file"] = std::string(kMaxFileNameBytes + 1, 'f');
  expect_error_j(j, Code::too_large, "'file'");
  j["file"] = "";
  expect_error_j(j, Code::bad_message, "'file'");
  j.erase("file");
  expect_error_j(j, Code::bad_message, "'file'");
  for (const char* good : {"depth_mm.exr", "proj col 1.png", "x", "points.ply"}) {
    j["file"] = good;
    EXPECT_TRUE(decode_request(j.dump()).ok()) << good;
  }
  j["file"] = "a.exr";
  j.erase("scan_id");
  expect_error_j(j, Code::bad_message, "'scan_id'");
}

TEST(ProtoFetch, ValidatesOffsetAndMaxBytes) {
  json j = {{"procam", 1}, {"id", "f1"}, {"type", "fetch"}, {"scan_id", "s"}, {"file", "a.exr"}};
  j["max_bytes"] = 0;
  expect_error_j(j, Code::invalid_argument, "'max_bytes'");
  j["max_bytes"] = kMaxFetchBytes + 1;
  expect_error_j(j, Code::invalid_argument, "'max_bytes'");
  j["max_bytes"] = -5;
  expect_error_j(j, Code::invalid_argument, "'max_bytes'");
  j["max_bytes"] = "1MiB";
  expect_error_j(j, Code::bad_message, "'max_bytes'");
  j["max_bytes"] = 1.5;
  expect_error_j(j, Code::bad_message, "'max_bytes'");
  j["max_bytes"] = kMaxFetchBytes;
  EXPECT_TRUE(decode_request(j.dump()).ok());
  j["max_bytes"] = 1;
  EXPECT_TRUE(decode_request(j.dump()).ok());
  j["offset"] = -1;
  expect_error_j(j, Code::invalid_argument, "'offset'");
  j["offset"] = 1.5;
  expect_error_j(j, Code::bad_message, "'offset'");
  expect_error(R"({"procam":1,"id":"f","type":"fetch","scan_id":"s","file":"a","offset":1e3})",
               Code::bad_message, "'offset'");
  j["offset"] = uint64_t{1} << 40;
  auto r = decode_request(j.dump());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(std::get<Fetch>(r->body).offset, uint64_t{1} << 40);
}

TEST(ProtoHello, ValidatesVersionsAndClient) {
  json j = {{"procam", 1}, {"id", "h"}, {"type", "hello"}, {"versions", {1}}};
  EXPECT_TRUE(decode_request(j.dump()).ok());
  j["versions"] = json::array();
  expect_error_j(j, Code::invalid_argument, "'versions'");
  j["versions"] = {0};
  expect_error_j(j, Code::invalid_argument, "'versions'");
  j["versions"] = {1, -2};
  expect_error_j(j, Code::invalid_argument, "'versions'");
  j["versions"] = {"1"};
  expect_error_j(j, Code::bad_message, "'versions'");
  j["versions"] = 1;
  expect_error_j(j, Code::bad_message, "'versions'");
  j["versions"] = std::vector<int>(65, 1);
  expect_error_j(j, Code::too_large, "'versions'");
  j.erase("versions");
  expect_error_j(j, Code::bad_message, "'versions'");
  j["versions"] = {1};
  j["client"] = std::string(kMaxClientBytes + 1, 'c');
  expect_error_j(j, Code::too_large, "'client'");
  j["client"] = 1;
  expect_error_j(j, Code::bad_message, "'client'");
}

TEST(ProtoHello, NegotiatesTheHighestCommonVersion) {
  auto v = negotiate_version(Hello{{1}, ""});
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(*v, 1);
  v = negotiate_version(Hello{{3, 1, 2}, ""});
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(*v, 1);
  v = negotiate_version(Hello{{2, 3}, ""});
  ASSERT_FALSE(v.ok());
  EXPECT_EQ(v.status().code(), Code::unsupported_version);
  EXPECT_NE(v.status().message().find("[2, 3]"), std::string::npos) << v.status().message();
  EXPECT_NE(v.status().message().find("[1]"), std::string::npos) << v.status().message();
}

TEST(ProtoStatus, ValidatesScanId) {
  expect_error(R"({"procam":1,"id":"a","type":"status","scan_id":5})", Code::bad_message, "'scan_id'");
  expect_error(R"({"procam":1,"id":"a","type":"status","scan_id":""})", Code::bad_message,
               "'scan_id'");
  expect_error(R"({"procam":1,"id":"a","type":"result"})", Code::bad_message, "'scan_id'");
  json j = {{"procam", 1}, {"id", "a"}, {"type", "result"}, {"scan_id", std::string(129, 's')}};
  expect_error_j(j, Code::too_large, "'scan_id'");
}

// ---- Replies, errors and events --------------------------------------------------

Reply decode_reply(const std::string& wire) {
  auto in = decode_incoming(wire);
  EXPECT_TRUE(in.ok()) << wire << " -> " << in.status().to_string();
  if (!in.ok() || !std::holds_alternative<Reply>(in->message)) {
    ADD_FAILURE() << "not a reply: " << wire;
    return {};
  }
  return std::get<Reply>(in->message);
}

TEST(ProtoReply, EncodeReplyDecodesBack) {
  const std::string wire = encode_reply(
      "r7", "scan", {{"scan_id", "s1"}, {"state", "queued"}, {"queue_position", 2}, {"ok", false}});
  const json j = json::parse(wire);
  EXPECT_EQ(j.at("procam"), 1);
  EXPECT_EQ(j.at("ok"), true);  // fields cannot override the envelope
  Reply r = decode_reply(wire);
  EXPECT_EQ(r.id, "r7");
  EXPECT_EQ(r.type, "scan");
  EXPECT_TRUE(r.ok);
  EXPECT_TRUE(r.error.ok());
  EXPECT_EQ(r.body, (json{{"scan_id", "s1"}, {"state", "queued"}, {"queue_position", 2}}));

  r = decode_reply(encode_reply("x", "list_plugins", nullptr));
  EXPECT_EQ(r.body, json::object());
}

TEST(ProtoReply, EncodeReplyNeverThrows) {
  // Invalid UTF-8 and non-finite numbers from a plugin must not break encoding.
  const std::string wire =
      encode_reply("x", "result", {{"label", std::string("bad \xff utf8")}, {"v", std::nan("")}});
  Reply r = decode_reply(wire);
  EXPECT_TRUE(r.ok);
  EXPECT_TRUE(r.body.at("v").is_null());
  EXPECT_NE(r.body.at("label").get<std::string>().find("bad "), std::string::npos);
  // Non-object fields are a caller bug: reported as an internal error reply.
  r = decode_reply(encode_reply("x", "status", json::array({1, 2})));
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.id, "x");
  EXPECT_EQ(r.error.code(), Code::internal);
}

TEST(ProtoReply, EncodeErrorDecodesBackWithIdOrNull) {
  Reply r = decode_reply(
      encode_error(std::string("r9"), Error(Code::not_found, "scan 'x' not found", "check the id")));
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.id, "r9");
  EXPECT_EQ(r.type, "error");
  EXPECT_EQ(r.error.code(), Code::not_found);
  EXPECT_EQ(r.error.message(), "scan 'x' not found");
  EXPECT_EQ(r.error.hint(), "check the id");

  const std::string anon = encode_error(std::nullopt, Error(Code::bad_message, "not JSON"));
  EXPECT_TRUE(json::parse(anon).at("id").is_null());
  EXPECT_EQ(json::parse(anon).at("error").at("hint"), "");
  r = decode_reply(anon);
  EXPECT_EQ(r.id, "");
  EXPECT_EQ(r.error.code(), Code::bad_message);

  // unsupported_version lists what the daemon speaks.
  const json v = json::parse(encode_error(std::string("a"), Error(Code::unsupported_version, "v2")));
  EXPECT_EQ(v.at("error").at("supported_versions"), json::array({1}));
  // An ok Status passed by mistake still yields an error reply.
  r = decode_reply(encode_error(std::string("a"), Status::Ok()));
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error.code(), Code::internal);
}

TEST(ProtoReply, DecodeRequestErrorsBecomeErrorRepliesWithTheirId) {
  // The daemon's whole error path: decode fails → encode_error with the id it saw.
  for (const auto& [bytes, want_id] : std::vector<std::pair<std::string, std::optional<std::string>>>{
           {R"({"procam":1,"id":"keep-me","type":"bogus"})", "keep-me"},
           {R"({"procam":9,"id":"keep-me","type":"status"})", "keep-me"},
           {R"({"procam":1,"id":"keep-me","type":"fetch","scan_id":"s","file":"../x"})", "keep-me"},
           {R"({"procam":1,"id":7,"type":"status"})", std::nullopt},
           {"not json", std::nullopt},
           // Unparsable bodies: a plain id in the raw bytes is still echoed.
           {R"({"procam":1,"id":"broken-1","type":"status",)", "broken-1"},
           {R"({"procam":1, "id" :  "spaced" ,"type":"ping" garbage)", "spaced"},
           {"{\"procam\":1,\"id\":\"bad\xff\",\"type\":\"ping\",}", std::nullopt},   // not printable ASCII
           {R"({"procam":1,"id":"esc\"aped","type":)", std::nullopt},                // escapes: not guessed
           {R"({"procam":1,"id":"","type":)", std::nullopt},
           {"{\"id\":\"" + std::string(129, 'a') + "\",", std::nullopt},              // over kMaxIdBytes
           {"\xEF\xBB\xBF{\"procam\":1,\"id\":\"bom-id\",\"type\":\"ping\"}", "bom-id"}}) {
    std::string id;
    bool have_id = false;
    auto req = decode_request(bytes, &id);
    ASSERT_FALSE(req.ok()) << bytes;
    have_id = !id.empty();
    Reply r = decode_reply(encode_error(have_id ? std::optional(id) : std::nullopt, req.status()));
    EXPECT_EQ(r.id, want_id.value_or("")) << bytes;
    EXPECT_EQ(r.error.code(), req.status().code());
  }
}

// PROTOCOL.md section 3: a body is UTF-8 JSON without a byte-order mark.
TEST(ProtoRequest, RejectsAByteOrderMark) {
  const std::string body = R"({"procam":1,"id":"a","type":"ping"})";
  ASSERT_TRUE(decode_request(body).ok());
  std::string id;
  auto r = decode_request("\xEF\xBB\xBF" + body, &id);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::bad_message);
  EXPECT_NE(r.status().message().find("byte-order mark"), std::string::npos) << r.status().message();
  EXPECT_EQ(id, "a");
  // A BOM-like sequence later in the text (inside a string) is ordinary UTF-8.
  auto in_label = decode_request(
      "{\"procam\":1,\"id\":\"a\",\"type\":\"scan\",\"plugin\":\"p\",\"method\":\"m\",\"label\":\"\xEF\xBB\xBF\"}");
  EXPECT_TRUE(in_label.ok()) << in_label.status().message();
}

TEST(ProtoEvent, EncodeEventDecodesBack) {
  const std::string wire = encode_event(
      "scan-1", 41, "progress", {{"stage", "capture"}, {"round", 1}, {"done", 3}, {"total", 22}});
  auto in = decode_incoming(wire);
  ASSERT_TRUE(in.ok()) << in.status().to_string();
  ASSERT_TRUE(std::holds_alternative<Event>(in->message));
  const auto& e = std::get<Event>(in->message);
  EXPECT_EQ(e.scan_id, "scan-1");
  EXPECT_EQ(e.seq, 41u);
  EXPECT_EQ(e.event, "progress");
  EXPECT_EQ(e.body, (json{{"stage", "capture"}, {"round", 1}, {"done", 3}, {"total", 22}}));
  EXPECT_FALSE(json::parse(wire).contains("id"));

  in = decode_incoming(encode_event("s", 0, "state", {{"state", "failed"},
                                                       {"error", error_to_json(Error(Code::timeout, "t"))}}));
  ASSERT_TRUE(in.ok());
  auto err = error_from_json(std::get<Event>(in->message).body.at("error"));
  ASSERT_TRUE(err.has_value());
  EXPECT_EQ(err->code(), Code::timeout);
}

TEST(ProtoIncoming, RejectsMalformedReplies) {
  auto bad = [](std::string_view s, Code code = Code::bad_message) {
    auto r = decode_incoming(s);
    EXPECT_FALSE(r.ok()) << s;
    if (!r.ok()) {
      EXPECT_EQ(r.status().code(), code) << s << ": " << r.status().to_string();
    }
  };
  bad("garbage");
  bad("[]");
  bad(R"({"id":"a","type":"scan","ok":true})");
  bad(R"({"procam":2,"id":"a","type":"scan","ok":true})", Code::unsupported_version);
  bad(R"({"procam":1,"id":"a","type":"scan"})");
  bad(R"({"procam":1,"id":"a","type":"scan","ok":"yes"})");
  bad(R"({"procam":1,"id":null,"type":"scan","ok":true})");
  bad(R"({"procam":1,"type":"scan","ok":true})");
  bad(R"({"procam":1,"id":"a","type":"error","ok":true})");
  bad(R"({"procam":1,"id":"a","type":"scan","ok":false,"error":{"code":"internal","message":"m"}})");
  bad(R"({"procam":1,"id":"a","type":"error","ok":false})");
  bad(R"({"procam":1,"id":"a","type":"error","ok":false,"error":{"message":"m"}})");
  bad(R"({"procam":1,"id":"a","type":"error","ok":false,"error":{"code":"ok","message":"m"}})");
  bad(R"({"procam":1,"type":"event","scan_id":"s","event":"state"})");
  bad(R"({"procam":1,"type":"event","scan_id":"s","seq":-1,"event":"state"})");
  bad(R"({"procam":1,"type":"event","seq":1,"event":"state"})");
}

TEST(ProtoIncoming, ToleratesUnknownFieldsAndCodes) {
  Reply r = decode_reply(
      R"({"procam":1,"id":"a","type":"hello","ok":true,"version":1,"future":{"x":1}})");
  EXPECT_EQ(r.body.at("future").at("x"), 1);
  r = decode_reply(
      R"({"procam":1,"id":"a","type":"error","ok":false,"error":{"code":"quota_exceeded","message":"m","hint":"h","extra":1}})");
  EXPECT_EQ(r.error.code(), Code::internal);
  EXPECT_NE(r.error.message().find("quota_exceeded"), std::string::npos);
  EXPECT_EQ(r.body.at("error").at("extra"), 1);
}

TEST(ProtoCodes, EveryCodeRoundTripsByName) {
  for (Code c : {Code::invalid_argument, Code::not_found, Code::unavailable,
                 Code::failed_precondition, Code::io_error, Code::corrupt_data, Code::abi_mismatch,
                 Code::plugin_error, Code::timeout, Code::cancelled, Code::internal,
                 Code::bad_message, Code::unsupported_version, Code::unknown_type,
                 Code::too_large}) {
    EXPECT_EQ(code_from_name(code_name(c)), c) << code_name(c);
    auto back = error_from_json(error_to_json(Error(c, "m", "h")));
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->code(), c);
  }
  EXPECT_FALSE(code_from_name("no_such_code").has_value());
  EXPECT_FALSE(error_from_json(json::array()).has_value());
  EXPECT_FALSE(error_from_json({{"code", "ok"}, {"message", "m"}}).has_value());
}

// ---- Helpers ---------------------------------------------------------------------

TEST(ProtoHelpers, NamesAndFileNames) {
  EXPECT_TRUE(is_valid_name("structured-light"));
  EXPECT_TRUE(is_valid_name("gray_2"));
  EXPECT_FALSE(is_valid_name(""));
  EXPECT_FALSE(is_valid_name("Gray"));
  EXPECT_FALSE(is_valid_name(std::string(65, 'a')));
  EXPECT_TRUE(is_safe_file_name("depth_mm.exr"));
  EXPECT_TRUE(is_safe_file_name(std::string(255, 'a')));
  EXPECT_FALSE(is_safe_file_name(std::string(256, 'a')));
  EXPECT_FALSE(is_safe_file_name(""));
  EXPECT_FALSE(is_safe_file_name(std::string("a\0b", 3)));
  EXPECT_FALSE(is_safe_file_name("a/b"));
  EXPECT_FALSE(is_safe_file_name("../x"));
  EXPECT_FALSE(is_safe_file_name(".."));
  EXPECT_FALSE(is_safe_file_name(".manifest.tmp"));
}

TEST(ProtoHelpers, UtcTimestamps) {
  using namespace std::chrono;
  EXPECT_EQ(utc_timestamp(system_clock::time_point{}), "1970-01-01T00:00:00.000Z");
  EXPECT_EQ(utc_timestamp(system_clock::time_point{milliseconds{1740830400250}}),
            "2025-03-01T12:00:00.250Z");
  EXPECT_EQ(utc_timestamp(system_clock::time_point{milliseconds{-1}}), "1969-12-31T23:59:59.999Z");
}

// ---- PROTOCOL.md examples ---------------------------------------------------------

struct Example {
  std::string tag, arg, body;
  int line;
};

// Fenced blocks whose info string starts with "json " (e.g. "json request").
std::vector<Example> spec_examples() {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/proto/PROTOCOL.md");
  EXPECT_TRUE(in.good()) << "cannot open PROTOCOL.md";
  std::vector<Example> out;
  std::string line;
  int n = 0;
  Example* open = nullptr;
  while (std::getline(in, line)) {
    ++n;
    if (open) {
      if (line.rfind("```", 0) == 0) {
        open = nullptr;
      } else {
        open->body += line + "\n";
      }
    } else if (line.rfind("```json ", 0) == 0) {
      std::istringstream info(line.substr(8));
      Example e;
      info >> e.tag >> e.arg;
      e.line = n;
      out.push_back(e);
      open = &out.back();
    }
  }
  EXPECT_EQ(open, nullptr) << "unterminated code block";
  return out;
}

TEST(ProtoSpec, EveryExampleInProtocolMdDecodes) {
  const auto examples = spec_examples();
  std::set<std::string> request_types, reply_types, invalid;
  int events = 0;
  for (const auto& ex : examples) {
    SCOPED_TRACE("PROTOCOL.md:" + std::to_string(ex.line) + " (" + ex.tag + ")");
    if (ex.tag == "request") {
      std::string id;
      auto r = decode_request(ex.body, &id);
      ASSERT_TRUE(r.ok()) << r.status().to_string() << "\n" << ex.body;
      request_types.emplace(type_name(r->body));
      // And our encoder produces an equivalent request.
      auto again = decode_request(encode_request(*r));
      ASSERT_TRUE(again.ok());
      EXPECT_EQ(*again, *r);
    } else if (ex.tag == "invalid-request") {
      auto want = code_from_name(ex.arg);
      ASSERT_TRUE(want.has_value()) << "unknown code '" << ex.arg << "'";
      auto r = decode_request(ex.body);
      ASSERT_FALSE(r.ok()) << ex.body;
      EXPECT_EQ(r.status().code(), *want) << r.status().to_string();
      invalid.insert(ex.arg);
    } else if (ex.tag == "reply" || ex.tag == "event") {
      auto in = decode_incoming(ex.body);
      ASSERT_TRUE(in.ok()) << in.status().to_string() << "\n" << ex.body;
      if (ex.tag == "reply") {
        ASSERT_TRUE(std::holds_alternative<Reply>(in->message));
        reply_types.insert(std::get<Reply>(in->message).type);
      } else {
        ASSERT_TRUE(std::holds_alternative<Event>(in->message));
        ++events;
      }
    } else if (ex.tag == "manifest" || ex.tag == "rig") {
      EXPECT_NO_THROW({ EXPECT_TRUE(json::parse(ex.body).is_object()); });
    } else {
      ADD_FAILURE() << "unknown example tag '" << ex.tag << "'";
    }
  }
  for (auto t : {"hello", "list_plugins", "describe_rig", "scan", "status", "result", "fetch",
                 "cancel", "ping", "list_scans", "list_rig_options", "calibrate_geometry"}) {
    EXPECT_TRUE(request_types.count(t)) << "no request example of type " << t;
    EXPECT_TRUE(reply_types.count(t)) << "no reply example of type " << t;
  }
  EXPECT_TRUE(reply_types.count("error"));
  EXPECT_GE(events, 3);
  EXPECT_GE(invalid.size(), 3u);
}

TEST(ProtoSpec, ErrorExampleMessagesMatchTheDecoder) {
  // The spec quotes two error replies verbatim; they must be what we send.
  std::map<std::string, json> quoted;
  for (const auto& ex : spec_examples()) {
    if (ex.tag != "reply") continue;
    json j = json::parse(ex.body);
    if (j.at("type") == "error" && j.at("error").at("code") == "bad_message")
      quoted[j.at("id").is_null() ? "" : j.at("id").get<std::string>()] = j;
  }
  ASSERT_TRUE(quoted.count("9") && quoted.count(""));
  std::string id;
  auto r = decode_request(
      R"({"procam": 1, "id": "9", "type": "scan", "plugin": "structured-light", "method": "gray", "param": {"bits": 10}})",
      &id);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(json::parse(encode_error(id, r.status())), quoted["9"]);
  r = decode_request("hello");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(json::parse(encode_error(std::nullopt, r.status())), quoted[""]);
}

}  // namespace
}  // namespace procam::proto
