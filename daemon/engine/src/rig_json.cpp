// SPDX-License-Identifier: MIT
// Rig description for plugins, JSON file helpers, atomic file writes.
#include "procam/engine/rig_json.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace procam::engine {
namespace fs = std::filesystem;

nlohmann::json plugin_rig_json(hw::Rig& rig, unsigned threads) {
  const Intrinsics& p = rig.projector_intrinsics();
  nlohmann::json j;
  j["projector"] = {{"width", p.width}, {"height", p.height}, {"intrinsics", p}};
  nlohmann::json cams = nlohmann::json::array();
  const auto& cals = rig.camera_calibrations();
  for (size_t i = 0; i < rig.camera_count() && i < cals.size(); ++i) {
    const auto& info = rig.camera(i).info();
    cams.push_back({{"width", info.width},
                    {"height", info.height},
                    {"bit_depth", info.bit_depth},
                    {"calibration", cals[i]}});
  }
  j["cameras"] = std::move(cams);
  // ABI 3 "lights": lights()[k - 1] is settings.light_index k.
  nlohmann::json lights = nlohmann::json::array();
  for (const hw::LightInfo& l : rig.lights())
    lights.push_back({{"name", l.name},
                      {"camera", l.camera},
                      {"cam_from_light", l.cam_from_light},
                      {"field", l.field},
                      {"irradiance_at_1m", l.irradiance_at_1m}});
  if (!lights.empty()) j["lights"] = std::move(lights);
  j["threads"] = threads;
  return j;
}

Result<nlohmann::json> plugin_rig_json_from_config(const nlohmann::json& cfg, unsigned threads) {
  std::string field = "projector.intrinsics";
  try {
    Intrinsics p = cfg.at("projector").at("intrinsics").get<Intrinsics>();
    if (!p.valid()) return Error(Code::invalid_argument, "rig config: projector.intrinsics has a zero size or focal length");
    nlohmann::json j;
    j["projector"] = {{"width", p.width}, {"height", p.height}, {"intrinsics", p}};
    nlohmann::json cams = nlohmann::json::array();
    nlohmann::json lights = nlohmann::json::array();
    field = "cameras";
    const auto& cfg_cams = cfg.at("cameras");
    if (!cfg_cams.is_array() || cfg_cams.empty())
      return Error(Code::invalid_argument, "rig config: 'cameras' must be a non-empty array");
    for (size_t i = 0; i < cfg_cams.size(); ++i) {
      const auto& c = cfg_cams[i];
      field = "cameras[" + std::to_string(i) + "].intrinsics";
      CameraCalibration cal;
      cal.intrinsics = c.at("intrinsics").get<Intrinsics>();
      field = "cameras[" + std::to_string(i) + "].cam_from_proj";
      cal.cam_from_proj = c.at("cam_from_proj").get<Rigid3>();
      uint32_t bits = c.value("bit_depth", 8u);
      cams.push_back({{"width", cal.intrinsics.width},
                      {"height", cal.intrinsics.height},
                      {"bit_depth", bits},
                      {"calibration", cal}});
      // A light mounted on this camera (sim rig config "light", hw/sim/SCENES.md):
      // the next light_index, with the sim's defaults for what it leaves out.
      if (c.contains("light")) {
        const auto& l = c.at("light");
        field = "cameras[" + std::to_string(i) + "].light";
        const Rigid3 pose = l.contains("cam_from_light") ? l.at("cam_from_light").get<Rigid3>() : Rigid3{};
        const Intrinsics f = l.contains("field") ? l.at("field").get<Intrinsics>() : hw::default_light_field();
        lights.push_back({{"name", l.value("name", "light " + std::to_string(lights.size() + 1))},
                          {"camera", i},
                          {"cam_from_light", pose},
                          {"field", f},
                          {"irradiance_at_1m", l.value("irradiance_at_1m", 1.0)}});
      }
    }
    j["cameras"] = std::move(cams);
    if (!lights.empty()) j["lights"] = std::move(lights);
    j["threads"] = threads;
    return j;
  } catch (const std::exception& e) {
    return Error(Code::invalid_argument, "rig config: " + field + ": " + e.what(),
                 "see configs/rigs/sim.json for the expected layout");
  }
}

Result<nlohmann::json> read_json_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error(Code::not_found, "cannot open '" + path + "'", "check the path");
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    return nlohmann::json::parse(ss.str(), nullptr, true, /*ignore_comments=*/true);
  } catch (const nlohmann::json::parse_error& e) {
    return Error(Code::invalid_argument, "'" + path + "' is not valid JSON: " + e.what());
  }
}

Status write_file_atomic(const std::string& path, const std::string& bytes) {
  static std::atomic<unsigned> counter{0};
  fs::path p(path);
  const std::string tmp = (p.parent_path() / ("." + p.filename().string() + ".tmp" +
                                              std::to_string(::getpid()) + "_" +
                                              std::to_string(counter++))).string();
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Error(Code::io_error, "cannot create '" + path + "'", "check the folder is writable");
  size_t off = 0;
  while (off < bytes.size()) {
    ssize_t n = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (n <= 0) {
      ::close(fd);
      ::unlink(tmp.c_str());
      return Error(Code::io_error, "writing '" + path + "' failed (disk full?)");
    }
    off += static_cast<size_t>(n);
  }
  ::fsync(fd);
  ::close(fd);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    ::unlink(tmp.c_str());
    return Error(Code::io_error, "cannot move '" + path + "' into place");
  }
  return Status::Ok();
}

}  // namespace procam::engine
