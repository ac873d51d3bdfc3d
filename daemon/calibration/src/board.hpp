// SPDX-License-Identifier: MIT
// Internal: the board's corners in one camera image, for either board type
// (procam/calibration/geometric.hpp BoardSpec). OpenCV finds them:
// chessboard: cv::findChessboardCorners + cornerSubPix (all or nothing);
// ChArUco: cv::aruco::detectMarkers + interpolateCornersCharuco (any subset,
// each corner with its id). Thread-safety: pure. Never throws (OpenCV
// exceptions become a rejection reason).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "procam/calibration/geometric.hpp"

namespace procam::calibration::detail {

struct FoundCorners {
  std::vector<cv::Point2f> image;  // camera pixels (centres at integers)
  std::vector<int> index;          // board corner index r * cols + c, same order
  std::string rejected_because;    // empty when usable
};

// `white`: 8-bit grey camera image. `min_charuco_corners`: fewer interpolated
// ChArUco corners (or corners all on one board row/column) reject the view.
FoundCorners find_corners(const cv::Mat& white, const BoardSpec& board, int min_charuco_corners);

// Board point (mm, z = 0) of corner `index`.
cv::Point3f corner_point(const BoardSpec& board, int index);

}  // namespace procam::calibration::detail
