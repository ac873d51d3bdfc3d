// SPDX-License-Identifier: MIT
// Test helper shared by charuco_sim_test and daemon_job_test: a ChArUco
// board drawn by OpenCV (cv::aruco::CharucoBoard::draw: 10 x 8 squares of
// 30 mm, 20 mm DICT_4X4_50 markers, 10 bitmap px per mm so square edges fall
// on bitmap pixel boundaries) inside a 30 mm white border, written as a PGM
// and printed on the eight calibration plates (configs/scenes/calib) as an
// image texture, plus two poses (plates 1 and 2 moved) that show only part
// of the board. The sim itself does not link OpenCV.
#pragma once

#include <array>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/core.hpp>

#include "procam/calibration/geometric.hpp"

namespace procam::calibration::test {

constexpr int kPoses = 10;  // the eight calibration plates, then 1 and 2 again, moved (kShift)
constexpr int kPxPerMm = 10;
constexpr double kSquare = 30, kMarker = 20, kBorder = 30;  // mm
// 10 x 8 squares = 9 x 7 inner corners.
inline BoardSpec charuco_board(const std::string& dict = "DICT_4X4_50") {
  BoardSpec b;
  b.type = BoardType::charuco;
  b.cols = 9;
  b.rows = 7;
  b.square_mm = kSquare;
  b.marker_mm = kMarker;
  b.dictionary = dict;
  return b;
}
// Poses 8 and 9: plates 1 and 2 with their centres moved (mm, camera frame)
// so that part of the board leaves the camera's view.
inline const std::map<int, std::array<double, 2>> kShift = {{8, {170, 0}}, {9, {0, 140}}};
inline int plate_of(int pose) { return pose < 8 ? pose : pose - 7; }

// OpenCV's ChArUco drawing, framed by a white border, as a binary PGM.
inline void write_board_pgm(const std::string& path) {
  const auto board = cv::aruco::CharucoBoard::create(10, 8, static_cast<float>(kSquare), static_cast<float>(kMarker),
                                                      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50));
  cv::Mat img;
  board->draw(cv::Size(10 * 30 * kPxPerMm, 8 * 30 * kPxPerMm), img, 0, 1);
  const int b = static_cast<int>(kBorder) * kPxPerMm;
  cv::copyMakeBorder(img, img, b, b, b, b, cv::BORDER_CONSTANT, cv::Scalar(255));
  std::ofstream out(path, std::ios::binary);
  out << "P5\n" << img.cols << " " << img.rows << "\n255\n";
  for (int r = 0; r < img.rows; ++r) out.write(reinterpret_cast<const char*>(img.ptr(r)), img.cols);
}

// configs/scenes/calib/board-k.json with the image texture (and kShift).
inline std::string write_scenes(const std::string& dir) {
  namespace fs = std::filesystem;
  fs::create_directories(dir + "/calib");
  write_board_pgm(dir + "/calib/charuco.pgm");
  for (int k = 0; k < kPoses; ++k) {
    const std::string name = "board-" + std::to_string(k);
    std::ifstream in(PROCAM_SOURCE_DIR "/configs/scenes/calib/board-" + std::to_string(plate_of(k)) + ".json");
    nlohmann::json j = nlohmann::json::parse(in);
    auto& o = j["objects"][0];
    o["texture"] = {{"type", "image"}, {"file", "charuco.pgm"}, {"size_mm", {360, 300}}, {"dark", 0.08},
                    {"light", 0.85}};
    if (auto s = kShift.find(k); s != kShift.end()) {
      o["point_mm"][0] = o["point_mm"][0].get<double>() + s->second[0];
      o["point_mm"][1] = o["point_mm"][1].get<double>() + s->second[1];
    }
    std::ofstream(dir + "/calib/" + name + ".json") << j.dump(1);
  }
  return dir;
}

}  // namespace procam::calibration::test
