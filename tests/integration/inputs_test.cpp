// SPDX-License-Identifier: MIT
// Scans that use earlier results, end to end (PROTOCOL.md 5.4 "inputs",
// plugin ABI 2), and calibration tables through the product
// (docs/calibration.md), on a real procamd with the tiny simulated rig:
//   - a structured-light scan's depth_mm fed to inputs-fixture/stats arrives
//     intact: its mean and per-pixel +10 mm are checked against the depth map
//     the test downloads and reads itself;
//   - each input error gets its own clear reply and the daemon keeps serving;
//   - `procam calibrate` writes a table whose samples are the quantiles of the
//     reference scan's depth_mm (recomputed here), refuses to overwrite,
//     prints the rig-config line; a rig config referencing it shows the table
//     in `procam rig`, plugins receive it, and a malformed table is a clear
//     config error;
//   - offline `procam decode --input NAME=FILE` and the Python client.
// The fixture plugin is daemon/plugin_host/testdata/sdk_inputs.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "../service/service_fixture.hpp"
#include "procam/core/image_io.hpp"

namespace procam::testing {
namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

class InputsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    ConfigOptions o;
    o.plugin_paths = {PROCAM_INPUTS_FIXTURE_DIR};
    daemon_ = new ServiceDaemon(o);
    ASSERT_TRUE(daemon_->d->wait_ready()) << daemon_->d->log();
    client::Client c(daemon_->endpoint(), std::chrono::seconds(30));
    // The reference: a gray scan of the tilted plane, and its depth map as stored.
    auto sub = c.call(tiny_scan("plane", "reference"));
    ASSERT_TRUE(sub.ok()) << sub.status().to_string();
    ref_id_ = (*sub)["scan_id"];
    ASSERT_EQ(wait_final(c, ref_id_).value("state", ""), "done");
    const std::string file = (daemon_->cfgdir.path / "ref_depth_mm.exr").string();
    ASSERT_TRUE(c.fetch_file(ref_id_, "depth_mm.exr", file).ok());
    auto img = read_image(file);
    ASSERT_TRUE(img.ok()) << img.status().to_string();
    ref_depth_ = new Image(std::move(*img));
  }
  static void TearDownTestSuite() {
    delete daemon_;
    delete ref_depth_;
    daemon_ = nullptr;
    ref_depth_ = nullptr;
  }
  client::Client connect() const { return client::Client(daemon_->endpoint(), std::chrono::seconds(10)); }

  static proto::Scan fixture_scan(const std::string& method, std::map<std::string, proto::InputRef> inputs) {
    proto::Scan s;
    s.plugin = "inputs-fixture";
    s.method = method;
    s.rig_options = {{"scene", "plane"}};
    s.inputs = std::move(inputs);
    return s;
  }
  // The valid depths of the reference scan, sorted (read from its stored file).
  static std::vector<float> valid_depths() {
    std::vector<float> v;
    const float* px = ref_depth_->ptr<float>();
    for (size_t i = 0; i < ref_depth_->pixel_count(); ++i)
      if (std::isfinite(px[i])) v.push_back(px[i]);
    std::sort(v.begin(), v.end());
    return v;
  }
  // Expects the request to be refused with `code` and a message containing `part`.
  void expect_refused(const proto::Scan& s, Code code, const std::string& part) {
    ASSERT_TRUE(daemon_->d->alive()) << daemon_->d->log();
    client::Client c = connect();
    auto r = c.call(s);
    ASSERT_FALSE(r.ok()) << "accepted: " << r->dump();
    EXPECT_EQ(r.status().code(), code) << r.status().to_string();
    EXPECT_TRUE(contains(r.status().message() + " | " + r.status().hint(), part)) << r.status().to_string();
    // The daemon keeps serving.
    EXPECT_TRUE(c.call(proto::Ping{}).ok());
  }

  static ServiceDaemon* daemon_;
  static std::string ref_id_;
  static Image* ref_depth_;
};
ServiceDaemon* InputsTest::daemon_ = nullptr;
std::string InputsTest::ref_id_;
Image* InputsTest::ref_depth_ = nullptr;

TEST_F(InputsTest, AnEarlierDepthMapReachesThePluginIntact) {
  const std::vector<float> valid = valid_depths();
  ASSERT_GT(valid.size(), ref_depth_->pixel_count() / 2) << "the reference scan decoded too little of the plane";
  double sum = 0;
  for (float v : valid) sum += double(v);
  client::Client c = connect();
  auto sub = c.call(fixture_scan("stats", {{"depth_mm", {ref_id_, "depth_mm"}}}));
  ASSERT_TRUE(sub.ok()) << sub.status().to_string() << daemon_->d->log();
  const std::string id = (*sub)["scan_id"];
  ASSERT_EQ(wait_final(c, id).value("state", ""), "done") << daemon_->d->log();
  auto reply = c.call(proto::ResultQuery{id});
  ASSERT_TRUE(reply.ok());
  const nlohmann::json* m = &(*reply)["manifest"];
  EXPECT_EQ((*m)["inputs"], (nlohmann::json{{"depth_mm", {{"scan", ref_id_}, {"output", "depth_mm"}}}}));
  double mean = NAN, count = NAN;
  for (const auto& o : (*m)["outputs"]) {
    if (o["name"] == "input_mean_mm") mean = o["value"];
    if (o["name"] == "input_valid_count") count = o["value"];
  }
  EXPECT_EQ(count, double(valid.size()));
  EXPECT_NEAR(mean, sum / double(valid.size()), 1e-3);  // float sums of ~10^4 values of ~800 mm
  // Per pixel: the plugin's depth + 10 equals the stored reference + 10 exactly.
  const std::string file = (daemon_->cfgdir.path / "shifted.exr").string();
  ASSERT_TRUE(c.fetch_file(id, "shifted_depth_mm.exr", file).ok());
  auto shifted = read_image(file);
  ASSERT_TRUE(shifted.ok());
  ASSERT_EQ(shifted->pixel_count(), ref_depth_->pixel_count());
  const float* a = ref_depth_->ptr<float>();
  const float* b = shifted->ptr<float>();
  size_t mismatches = 0;
  for (size_t i = 0; i < shifted->pixel_count(); ++i)
    mismatches += std::isfinite(a[i]) ? (b[i] != a[i] + 10.f) : !std::isnan(b[i]);
  EXPECT_EQ(mismatches, 0u);
}

TEST_F(InputsTest, EachInputErrorIsAClearReply) {
  const std::map<std::string, proto::InputRef> good = {{"depth_mm", {ref_id_, "depth_mm"}}};
  // Unknown scan.
  expect_refused(fixture_scan("stats", {{"depth_mm", {"20990101-000000-000000", "depth_mm"}}}), Code::not_found,
                 "names scan '20990101-000000-000000', which this daemon does not have");
  // Missing output (the message lists what it has).
  expect_refused(fixture_scan("stats", {{"depth_mm", {ref_id_, "height_mm"}}}), Code::not_found,
                 "has no output 'height_mm'");
  // Wrong kind: a scalar, and a PNG mask.
  expect_refused(fixture_scan("stats", {{"depth_mm", {ref_id_, "valid_fraction"}}}), Code::invalid_argument,
                 "is a scalar, not a map");
  expect_refused(fixture_scan("stats", {{"depth_mm", {ref_id_, "valid"}}}), Code::invalid_argument,
                 "png-u8 image; the input needs a float map");
  // A method that takes none; a name the method does not take; a required one absent.
  expect_refused(fixture_scan("plain", good), Code::invalid_argument,
                 "method 'inputs-fixture/plain' takes no inputs");
  proto::Scan gray = tiny_scan("plane");
  gray.inputs = good;
  expect_refused(gray, Code::invalid_argument, "method 'structured-light/gray' takes no inputs");
  expect_refused(fixture_scan("stats", {{"depth_mm", {ref_id_, "depth_mm"}}, {"ref_mm", {ref_id_, "depth_mm"}}}),
                 Code::invalid_argument, "has no input 'ref_mm'");
  expect_refused(fixture_scan("stats", {}), Code::invalid_argument, "needs input 'depth_mm'");
  // A scan that has not finished, and one that failed: queue them behind
  // three slower scans (multi-round ensembles), name them at once.
  client::Client c = connect();
  proto::Scan slow = tiny_scan("plane");
  slow.method = "ensemble";
  std::vector<std::string> ahead;
  for (int i = 0; i < 3; ++i) {
    auto r = c.call(slow);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    ahead.push_back((*r)["scan_id"]);
  }
  auto queued = c.call(tiny_scan("plane"));
  auto doomed = c.call(tiny_scan("plane"));
  ASSERT_TRUE(queued.ok() && doomed.ok());
  const std::string qid = (*queued)["scan_id"], did = (*doomed)["scan_id"];
  expect_refused(fixture_scan("stats", {{"depth_mm", {qid, "depth_mm"}}}), Code::failed_precondition,
                 "which is still queued");
  ASSERT_TRUE(c.call(proto::Cancel{did}).ok());  // queued: it ends failed (cancelled) at once
  expect_refused(fixture_scan("stats", {{"depth_mm", {did, "depth_mm"}}}), Code::failed_precondition, "which failed");
  for (const auto& id : ahead) (void)c.call(proto::Cancel{id});
  ASSERT_EQ(wait_final(c, qid).value("state", ""), "done");
  // After all that, a good request still runs.
  auto ok = c.call(fixture_scan("stats", good));
  ASSERT_TRUE(ok.ok()) << ok.status().to_string();
  EXPECT_EQ(wait_final(c, (*ok)["scan_id"]).value("state", ""), "done");
}

TEST_F(InputsTest, WrongSizeIsRefused) {
  // A daemon whose camera is not the reference scan's size cannot use its
  // map: the full-size rig serving a copy of the tiny daemon's results.
  TempDir copy;
  fs::copy(daemon_->results, copy.path / "results", fs::copy_options::recursive);
  ConfigOptions o;
  o.tiny_rig = false;
  o.plugin_paths = {PROCAM_INPUTS_FIXTURE_DIR};
  ServiceDaemon big(o, (copy.path / "results").string());
  ASSERT_TRUE(big.d->wait_ready()) << big.d->log();
  client::Client c(big.endpoint(), std::chrono::seconds(30));
  auto r = c.call(fixture_scan("stats", {{"depth_mm", {ref_id_, "depth_mm"}}}));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  EXPECT_TRUE(contains(r.status().message(), "is 128x80, camera 0 of this rig is 1280x800")) << r.status().to_string();
  EXPECT_TRUE(c.call(proto::Ping{}).ok());
}

TEST_F(InputsTest, CalibrateWritesATableTheRigThenShows) {
  const fs::path out = daemon_->cfgdir.path / "tables" / "fixture.json";
  std::string text;
  const std::vector<std::string> cmd = {bin("procam"), "calibrate", "inputs-fixture/calibrate", "--scene", "plane",
                                        "--out", out.string(), "--endpoint", daemon_->endpoint()};
  ASSERT_EQ(run_command(cmd, &text), 0) << text;
  EXPECT_TRUE(contains(text, "\"calibration_tables\": {\"inputs-fixture.calibrate\": \"" + out.string() + "\"}")) << text;
  std::ifstream in(out);
  const nlohmann::json table = nlohmann::json::parse(in);
  // The samples are the quantiles of the reference scan's depth_mm, computed
  // here from the first scan's stored map (the calibrate run scanned the same
  // static sim scene again: the sim is deterministic, so the maps agree to
  // well under 0.01 mm).
  const std::vector<float> v = valid_depths();
  std::vector<std::pair<double, double>> expect;
  for (int k = 0; k <= 10; ++k) {
    const double q = k / 10.0;
    const double y = v[static_cast<size_t>(std::lround(q * double(v.size() - 1)))];
    if (expect.empty() || y > expect.back().second) expect.push_back({q, y});
  }
  ASSERT_EQ(table["samples"].size(), expect.size()) << table.dump();
  for (size_t i = 0; i < expect.size(); ++i) {
    EXPECT_NEAR(table["samples"][i][0].get<double>(), expect[i].first, 1e-9);
    EXPECT_NEAR(table["samples"][i][1].get<double>(), expect[i].second, 0.01);
  }
  EXPECT_EQ(table["made"]["plugin"], "inputs-fixture");
  EXPECT_EQ(table["made"]["scene"], "plane");
  EXPECT_EQ(table["made"]["rig"], "sim-tiny");
  EXPECT_TRUE(table["made"]["from_scan"].is_string());
  EXPECT_TRUE(table["made"]["date"].is_string());
  // Never over an existing file without --force.
  ASSERT_NE(run_command(cmd, &text), 0);
  EXPECT_TRUE(contains(text, "exists; not overwriting it")) << text;
  std::vector<std::string> forced = cmd;
  forced.insert(forced.end(), {"--force", "1"});
  ASSERT_EQ(run_command(forced, &text), 0) << text;

  // A rig config referencing it: procamd loads it, `procam rig` lists it.
  TempDir dir;
  fs::create_directories(dir.path / "tables");
  fs::copy_file(out, dir.path / "tables" / "t.json");
  nlohmann::json rig = rig_json(true);
  rig["calibration_tables"] = {{"inputs-fixture.calibrate", "tables/t.json"}};
  std::ofstream(dir.path / "rig.json") << rig.dump(2);
  nlohmann::json cfg = {{"rig", "rig.json"}, {"scene_dirs", {source("configs/scenes")}},
                        {"results_dir", (dir.path / "results").string()}, {"threads", 1}};
  std::ofstream(dir.path / "procamd.json") << cfg.dump(2);
  {
    Daemon d({"--config", (dir.path / "procamd.json").string()});
    ASSERT_TRUE(d.wait_ready()) << d.log();
    ASSERT_EQ(run_command({bin("procam"), "rig", "--endpoint", d.endpoint}, &text), 0) << text;
    EXPECT_TRUE(contains(text, "table      inputs-fixture.calibrate: quantile [fraction] -> depth [mm]")) << text;
    EXPECT_TRUE(contains(text, std::to_string(expect.size()) + " samples")) << text;
    EXPECT_TRUE(contains(text, "made: ")) << text;
  }
  // A malformed table stops the daemon at start with the file and the field.
  nlohmann::json broken = table;
  broken["samples"][1][0] = broken["samples"][0][0];
  std::ofstream(dir.path / "tables" / "t.json") << broken.dump();
  Daemon bad({"--config", (dir.path / "procamd.json").string()});
  EXPECT_FALSE(bad.wait_ready(std::chrono::seconds(10)));
  EXPECT_NE(bad.stop(), 0);
  EXPECT_TRUE(contains(bad.log(), "'calibration_tables.inputs-fixture.calibrate'")) << bad.log();
  EXPECT_TRUE(contains(bad.log(), "samples[1]")) << bad.log();
  EXPECT_TRUE(contains(bad.log(), "x must increase strictly")) << bad.log();
}

TEST_F(InputsTest, OfflineDecodeTakesInputFiles) {
  // The reference scan's frames are not kept; the fixture's one white frame is
  // rendered here as a file (any 128x80 grey image works for its plan).
  TempDir dir;
  fs::create_directories(dir.path / "frames");
  Image white(128, 80, PixelType::u8);
  std::fill(white.ptr<uint8_t>(), white.ptr<uint8_t>() + white.pixel_count(), uint8_t{200});
  ASSERT_TRUE(write_image((dir.path / "frames" / "000.png").string(), white).ok());
  const std::string depth = (daemon_->cfgdir.path / "ref_depth_mm.exr").string();
  nlohmann::json rig = rig_json(true);
  std::ofstream(dir.path / "rig.json") << rig.dump();
  std::string text;
  const std::vector<std::string> base = {bin("procam"), "decode", "--plugin", "inputs-fixture", "--method", "stats",
                                         "--frames", (dir.path / "frames").string(), "--out",
                                         (dir.path / "out").string(), "--rig", (dir.path / "rig.json").string(),
                                         "--plugins", PROCAM_INPUTS_FIXTURE_DIR, "--json"};
  std::vector<std::string> cmd = base;
  cmd.insert(cmd.end(), {"--input", "depth_mm=" + depth});
  ASSERT_EQ(run_command(cmd, &text), 0) << text;
  const std::vector<float> v = valid_depths();
  double sum = 0;
  for (float x : v) sum += double(x);
  std::ifstream in(dir.path / "out" / "manifest.json");
  const nlohmann::json m = nlohmann::json::parse(in);
  double mean = NAN;
  for (const auto& o : m["outputs"])
    if (o["name"] == "input_mean_mm") mean = o["value"];
  EXPECT_NEAR(mean, sum / double(v.size()), 1e-3);
  // Without it, and with a file that is not a map: clear errors.
  ASSERT_NE(run_command(base, &text), 0);
  EXPECT_TRUE(contains(text, "needs input 'depth_mm'")) << text;
  cmd = base;
  cmd.insert(cmd.end(), {"--input", "depth_mm=" + (dir.path / "nope.exr").string()});
  ASSERT_NE(run_command(cmd, &text), 0);
  EXPECT_TRUE(contains(text, "input 'depth_mm': file")) << text;
  EXPECT_TRUE(contains(text, "does not exist")) << text;
  cmd = base;
  cmd.insert(cmd.end(), {"--input", "depth_mm=" + (dir.path / "frames" / "000.png").string()});
  ASSERT_NE(run_command(cmd, &text), 0);
  EXPECT_TRUE(contains(text, "must be a 1-channel float map (image_f32)")) << text;
}

TEST_F(InputsTest, PluginsListsEachMethodsInputs) {
  std::string text;
  ASSERT_EQ(run_command({bin("procam"), "plugins", "--endpoint", daemon_->endpoint()}, &text), 0) << text;
  EXPECT_TRUE(contains(text, "--input depth_mm=<scan id>  image_f32, mm  a depth map of camera 0")) << text;
}

TEST_F(InputsTest, PythonClientPassesInputs) {
  std::string text;
  const std::string script =
      "import sys; sys.path.insert(0, '" + source("clients/python") + "')\n"
      "from procam_client import Client\n"
      "with Client('" + daemon_->endpoint() + "') as c:\n"
      "    s = c.scan('inputs-fixture', 'stats', rig_options={'scene': 'plane'}, inputs={'depth_mm': '" + ref_id_ + "'})\n"
      "    m = c.result(s['scan_id'])\n"
      "    print('STATE', s['state'], 'INPUTS', m['inputs']['depth_mm']['scan'])\n";
  ASSERT_EQ(run_command({"/usr/bin/python3", "-B", "-c", script}, &text), 0) << text;
  EXPECT_TRUE(contains(text, "STATE done INPUTS " + ref_id_)) << text;
}

}  // namespace
}  // namespace procam::testing
