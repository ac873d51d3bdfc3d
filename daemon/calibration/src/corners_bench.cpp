// SPDX-License-Identifier: MIT
// Cost of finding a board's corners in one camera image (board.hpp):
// chessboard (findChessboardCorners + cornerSubPix) against ChArUco
// (detectMarkers + interpolateCornersCharuco + the half-pixel re-refinement),
// on the closed-form 800 x 640 view of pose 1 of the tests (63 corners).
// Single-threaded as the calibration runs it (one view at a time).
#include <benchmark/benchmark.h>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/core.hpp>

#include "board.hpp"
#include "closed_form_views.hpp"

namespace procam::calibration {
namespace {

BoardSpec board_of(bool charuco) {
  BoardSpec b{9, 7, 30.0};
  if (charuco) {
    b.type = BoardType::charuco;
    b.marker_mm = 22;
    b.dictionary = "DICT_5X5_100";
  }
  return b;
}

View view_of(const BoardSpec& b) {
  const double S = b.square_mm;
  cv::Mat bitmap;
  if (b.type == BoardType::charuco)
    cv::aruco::CharucoBoard::create(b.cols + 1, b.rows + 1, static_cast<float>(S), static_cast<float>(b.marker_mm),
                                    cv::aruco::getPredefinedDictionary(cv::aruco::DICT_5X5_100))
        ->draw(cv::Size((b.cols + 1) * 60, (b.rows + 1) * 60), bitmap, 0, 1);
  auto reflectance = [bitmap, b, S](double bx, double by) {
    if (bx < -S || by < -S || bx >= b.cols * S || by >= b.rows * S) return 220.f;
    if (bitmap.empty())
      return ((static_cast<long>(std::floor(bx / S)) + static_cast<long>(std::floor(by / S))) & 1) == 0 ? 30.f : 220.f;
    const int u = static_cast<int>((bx + S) / S * 60), v = static_cast<int>((by + S) / S * 60);
    return 30.f + 190.f * static_cast<float>(bitmap.at<uint8_t>(v, u)) / 255.f;
  };
  const test::BoardLook look{reflectance, -2 * S, (b.cols + 1) * S, -2 * S, (b.rows + 1) * S};
  cv::Matx33d Rb;
  cv::Vec3d tb;
  test::pose_of({0, 0, 0, 0, 0, 650}, cv::Vec3d(4 * S, 3 * S, 0), Rb, tb);
  return test::render(test::Truth{}, look, Rb, tb, "bench", 1);
}

void BM_FindCorners(benchmark::State& state) {
  const BoardSpec b = board_of(state.range(0) == 1);
  View v = view_of(b);
  const cv::Mat white(static_cast<int>(v.height), static_cast<int>(v.width), CV_8UC1, v.white.data());
  size_t found = 0;
  for (auto _ : state) {
    const detail::FoundCorners f = detail::find_corners(white, b, 6);
    found = f.image.size();
    benchmark::DoNotOptimize(found);
  }
  state.counters["corners"] = static_cast<double>(found);
  state.SetLabel(state.range(0) == 1 ? "charuco" : "chessboard");
}
BENCHMARK(BM_FindCorners)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace procam::calibration
BENCHMARK_MAIN();
