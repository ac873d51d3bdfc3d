// SPDX-License-Identifier: MIT
// The daemon's calibrate_geometry flow (PROTOCOL.md 5.12) through the scan
// service, as procamd wires it: the distorted sim rig scans four board poses
// (structured-light/gray rows=true, save_frames), a calibration record is
// submitted naming them, and its manifest, result file and per-view table
// are checked; then every refusal the request can meet. Accuracy against
// the rig's truth is geometric_sim_test's job (eight poses); here four poses
// must give a sane calibration (focal lengths within 1 %, joint RMS < 0.3 px).
// DaemonCharuco does the same with the ChArUco board charuco_sim_test prints
// on the plates, one of its views showing only part of the board.
#include "procam/calibration/daemon_job.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include "charuco_sim_scenes.hpp"
#include "procam/engine/service.hpp"
#include "procam/hw/rig.hpp"

namespace procam::calibration {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

json rig_config() {
  std::ifstream in(PROCAM_SOURCE_DIR "/configs/rigs/sim-distorted.json");
  return json::parse(in);
}

// Waits until `id` is done or failed (at most 120 s); returns its manifest.
json wait_for(engine::ScanService& service, const std::string& id) {
  for (int i = 0; i < 1200; ++i) {
    auto s = service.scan_summary(id);
    if (s.ok() && ((*s)["state"] == "done" || (*s)["state"] == "failed")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  auto m = service.manifest(id);
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  return m.ok() ? *m : json();
}

// Queues a gray scan of board pose k (finished by wait_for()).
std::string submit_pose(engine::ScanService& service, int k, json params = {{"rows", true}}, bool save_frames = true) {
  engine::ScanRequest req;
  req.plugin = "structured-light";
  req.method = "gray";
  req.params = std::move(params);
  req.rig_options = {{"scene", "calib/board-" + std::to_string(k)}};
  req.save_frames = save_frames;
  auto r = service.submit(req);
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  return r.ok() ? (*r)["scan_id"].get<std::string>() : std::string();
}

// One service and one set of pose scans for the suite (scanning is the slow
// part): four good poses, one without rows=true, one without saved frames.
class DaemonCalibration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string((fs::temp_directory_path() / ("procam_cal16_daemon_" + std::to_string(::getpid()))).string());
    fs::remove_all(*dir_);
    host_ = new host::PluginHost(host::LoadOptions{.probe_in_child = false});
    host_->load_directories({PROCAM_PLUGIN_DIR});
    auto rig = hw::create_rig(rig_config(), {PROCAM_SOURCE_DIR "/configs/rigs", {PROCAM_SOURCE_DIR "/configs/scenes"}});
    ASSERT_TRUE(rig.ok()) << rig.status().to_string();
    engine::ServiceConfig cfg;
    cfg.results_dir = *dir_;
    cfg.evaluate = false;
    cfg.calibrate_geometry = [](const engine::GeometryCalibrationJob& job) { return run_daemon_job(*host_, job, 2); };
    service_ = new engine::ScanService(std::move(*rig), *host_, cfg, nullptr);
    ASSERT_TRUE(service_->start().ok());
    good_ = new std::vector<std::string>;
    for (int k : {0, 1, 3, 5}) good_->push_back(scan_pose(k));
    no_rows_ = new std::string(scan_pose(2, json::object()));
    no_frames_ = new std::string(scan_pose(4, {{"rows", true}}, false));
  }
  static void TearDownTestSuite() {
    delete service_;
    delete host_;
    std::error_code ec;
    fs::remove_all(*dir_, ec);
    delete dir_;
    delete good_;
    delete no_rows_;
    delete no_frames_;
  }
  static json wait(const std::string& id) { return wait_for(*service_, id); }
  static std::string scan_pose(int k, json params = {{"rows", true}}, bool save_frames = true) {
    return submit_pose(*service_, k, std::move(params), save_frames);
  }
  static std::string* dir_;
  static host::PluginHost* host_;
  static engine::ScanService* service_;
  static std::vector<std::string>* good_;
  static std::string *no_rows_, *no_frames_;
};
std::string* DaemonCalibration::dir_ = nullptr;
host::PluginHost* DaemonCalibration::host_ = nullptr;
engine::ScanService* DaemonCalibration::service_ = nullptr;
std::vector<std::string>* DaemonCalibration::good_ = nullptr;
std::string* DaemonCalibration::no_rows_ = nullptr;
std::string* DaemonCalibration::no_frames_ = nullptr;

TEST_F(DaemonCalibration, PoseScansThenOneRequestGiveTheRigCalibration) {
  const std::vector<std::string>& ids = *good_;
  for (const auto& id : ids) ASSERT_EQ(wait(id)["state"], "done") << id;
  auto r = service_->submit_calibration(ids, 9, 7, 30.0, "sim poses");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const std::string cal = (*r)["scan_id"];
  const json m = wait(cal);
  ASSERT_EQ(m["state"], "done") << m.dump(2);
  EXPECT_EQ(m["plugin"], engine::kCalibrationPlugin);
  EXPECT_EQ(m["method"], engine::kCalibrationMethod);
  const json& c = m["calibration"];
  ASSERT_EQ(c["views"].size(), ids.size());
  for (size_t i = 0; i < ids.size(); ++i) {
    EXPECT_EQ(c["views"][i]["name"], ids[i]) << "views are named by their scan";
    EXPECT_TRUE(c["views"][i]["used"].get<bool>()) << c["views"][i].dump();
  }
  EXPECT_LT(c["stereo_rms_px"].get<double>(), 0.3);
  const json cfg = rig_config();
  EXPECT_NEAR(c["rig"]["cameras"][0]["intrinsics"]["fx"].get<double>(),
              cfg["cameras"][0]["intrinsics"]["fx"].get<double>(), 0.01 * 900);
  EXPECT_NEAR(c["rig"]["projector"]["intrinsics"]["fx"].get<double>(),
              cfg["projector"]["intrinsics"]["fx"].get<double>(), 0.01 * 1125);
  EXPECT_NEAR(c["square_check"]["mean_mm"].get<double>(), 30.0, 0.1);
  // The result file is the one `procam calibrate-geometry` writes, listed for fetch.
  auto path = service_->file_path(cal, c["result_file"]);
  ASSERT_TRUE(path.ok()) << path.status().to_string();
  std::ifstream in(*path);
  const json file = json::parse(in);
  EXPECT_EQ(file, c["rig"]);
  EXPECT_TRUE(service_->file_path(cal, "calibration-report.md").ok());
  // The scan report shows the per-view table.
  auto html = service_->file_path(cal, "report.html");
  ASSERT_TRUE(html.ok()) << html.status().to_string();
  std::ifstream hin(*html);
  const std::string page((std::istreambuf_iterator<char>(hin)), std::istreambuf_iterator<char>());
  EXPECT_NE(page.find("Geometric calibration"), std::string::npos);
  for (const auto& id : ids) EXPECT_NE(page.find(id), std::string::npos) << "the report's table names view " << id;
  // A calibration record is listed like a scan.
  const json listed = service_->list_scans(std::nullopt, 10);
  EXPECT_EQ(listed["scans"][0]["scan_id"], cal);
  EXPECT_EQ(listed["scans"][0]["plugin"], engine::kCalibrationPlugin);
}

TEST_F(DaemonCalibration, RefusalsSayWhatIsWrong) {
  const std::string good = (*good_)[0], no_rows = *no_rows_, no_frames = *no_frames_;
  for (const auto& id : {good, no_rows, no_frames}) ASSERT_EQ(wait(id)["state"], "done") << id;
  auto expect = [&](const std::vector<std::string>& ids, Code code, const std::string& needle) {
    auto r = service_->submit_calibration(ids, 9, 7, 30.0, "");
    ASSERT_FALSE(r.ok()) << needle;
    EXPECT_EQ(r.status().code(), code) << r.status().to_string();
    EXPECT_NE(r.status().message().find(needle), std::string::npos) << r.status().to_string();
    EXPECT_FALSE(r.status().hint().empty()) << r.status().to_string();
  };
  expect({good, good + "x", no_rows}, Code::invalid_argument, "no scan with id '" + good + "x'");
  expect({good, no_rows, no_frames}, Code::failed_precondition, "without rows=true");
  expect({good, no_frames, good}, Code::failed_precondition, "has no saved frames");
  // Too few usable views: a record that ends failed, naming the rejected view.
  auto r = service_->submit_calibration({good, (*good_)[1], (*good_)[2]}, 11, 9, 30.0, "wrong board");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const json m = wait((*r)["scan_id"]);
  EXPECT_EQ(m["state"], "failed");
  EXPECT_EQ(m["error"]["code"], "failed_precondition") << m["error"].dump();
  for (size_t i = 0; i < 3; ++i)
    EXPECT_NE(m["error"]["message"].get<std::string>().find((*good_)[i] + ": chessboard 11x9 inner corners not found"),
              std::string::npos)
        << m["error"].dump();
  // A ChArUco board with a dictionary OpenCV lacks: the record fails at once
  // (before decoding), listing the names to give.
  auto bad = service_->submit_calibration(
      {good, (*good_)[1], (*good_)[2]},
      json{{"type", "charuco"}, {"squares", {10, 8}}, {"square_mm", 30}, {"marker_mm", 22}, {"dictionary", "DICT_5X5_99"}},
      "wrong dictionary");
  ASSERT_TRUE(bad.ok()) << bad.status().to_string();
  const json mb = wait((*bad)["scan_id"]);
  EXPECT_EQ(mb["state"], "failed");
  EXPECT_EQ(mb["error"]["code"], "invalid_argument") << mb["error"].dump();
  EXPECT_NE(mb["error"]["message"].get<std::string>().find("unknown ArUco dictionary 'DICT_5X5_99'"),
            std::string::npos)
      << mb["error"].dump();
  EXPECT_NE(mb["error"]["hint"].get<std::string>().find("DICT_5X5_100"), std::string::npos) << mb["error"].dump();
}

// The ChArUco flow through the service: four plate poses and one partial
// view (pose 8, plate 1 moved so part of the board leaves the image) scanned
// from scenes written to a temp folder, then one calibration request with a
// ChArUco board. Every view is used, the partial one with fewer corners.
class DaemonCharuco : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string((fs::temp_directory_path() / ("procam_charuco_daemon_" + std::to_string(::getpid()))).string());
    fs::remove_all(*dir_);
    test::write_scenes(*dir_ + "/scenes");
    host_ = new host::PluginHost(host::LoadOptions{.probe_in_child = false});
    host_->load_directories({PROCAM_PLUGIN_DIR});
    auto rig = hw::create_rig(rig_config(), {PROCAM_SOURCE_DIR "/configs/rigs", {*dir_ + "/scenes"}});
    ASSERT_TRUE(rig.ok()) << rig.status().to_string();
    engine::ServiceConfig cfg;
    cfg.results_dir = *dir_ + "/results";
    cfg.evaluate = false;
    cfg.calibrate_geometry = [](const engine::GeometryCalibrationJob& job) { return run_daemon_job(*host_, job, 2); };
    service_ = new engine::ScanService(std::move(*rig), *host_, cfg, nullptr);
    ASSERT_TRUE(service_->start().ok());
  }
  static void TearDownTestSuite() {
    delete service_;
    delete host_;
    std::error_code ec;
    fs::remove_all(*dir_, ec);
    delete dir_;
  }
  static std::string* dir_;
  static host::PluginHost* host_;
  static engine::ScanService* service_;
};
std::string* DaemonCharuco::dir_ = nullptr;
host::PluginHost* DaemonCharuco::host_ = nullptr;
engine::ScanService* DaemonCharuco::service_ = nullptr;

TEST_F(DaemonCharuco, PoseScansThenOneRequestGiveTheRigCalibration) {
  std::vector<std::string> ids;
  for (int k : {0, 1, 3, 5, 8}) ids.push_back(submit_pose(*service_, k));
  for (const auto& id : ids) ASSERT_EQ(wait_for(*service_, id)["state"], "done") << id;
  const json board{{"type", "charuco"},
                   {"squares", {10, 8}},
                   {"square_mm", test::kSquare},
                   {"marker_mm", test::kMarker},
                   {"dictionary", "DICT_4X4_50"}};
  auto r = service_->submit_calibration(ids, board, "sim ChArUco poses");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const json m = wait_for(*service_, (*r)["scan_id"]);
  ASSERT_EQ(m["state"], "done") << m.dump(2);
  const json& c = m["calibration"];
  ASSERT_EQ(c["views"].size(), ids.size());
  for (size_t i = 0; i < ids.size(); ++i) EXPECT_TRUE(c["views"][i]["used"].get<bool>()) << c["views"][i].dump();
  EXPECT_GE(c["views"][0]["corners"].get<int>(), 60) << "a whole board shows (nearly) all 63 inner corners";
  EXPECT_LT(c["views"][4]["corners"].get<int>(), 63 * 9 / 10) << "pose 8 shows only part of the board";
  EXPECT_GE(c["views"][4]["corners"].get<int>(), 6);
  EXPECT_LT(c["stereo_rms_px"].get<double>(), 0.3);
  const json cfg = rig_config();
  EXPECT_NEAR(c["rig"]["cameras"][0]["intrinsics"]["fx"].get<double>(),
              cfg["cameras"][0]["intrinsics"]["fx"].get<double>(), 0.01 * 900);
  EXPECT_NEAR(c["rig"]["projector"]["intrinsics"]["fx"].get<double>(),
              cfg["projector"]["intrinsics"]["fx"].get<double>(), 0.01 * 1125);
  EXPECT_NEAR(c["square_check"]["mean_mm"].get<double>(), test::kSquare, 0.1);
  auto path = service_->file_path((*r)["scan_id"], c["result_file"]);
  ASSERT_TRUE(path.ok()) << path.status().to_string();
  std::ifstream in(*path);
  EXPECT_EQ(json::parse(in), c["rig"]);
}

}  // namespace
}  // namespace procam::calibration
