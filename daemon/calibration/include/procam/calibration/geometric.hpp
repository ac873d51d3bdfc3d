// SPDX-License-Identifier: MIT
// Geometric calibration of a projector-camera rig from chessboard views
// captured under Gray codes (issue 16 item 1; docs/calibration.md).
//
// Method (Moreno & Taubin 2012, "Simple, accurate, and robust projector-camera
// calibration"):
//  1. camera: the board's inner corners in each view's white image
//     (chessboard: cv::findChessboardCorners + cornerSubPix, all corners;
//     ChArUco: cv::aruco::detectMarkers + interpolateCornersCharuco, the
//     corners the view shows, each with its id -> board point);
//  2. projector: around each corner, the decoded projector column/row of every
//     valid camera pixel in a (2r+1)^2 window define a local homography
//     camera -> projector (least squares over the window, RANSAC-guarded); the
//     corner's projector position is the homography applied to the camera
//     corner. Local, so it holds under lens distortion of either device;
//  3. cv::calibrateCamera for camera and projector separately (intrinsics and
//     5 distortion coefficients k1 k2 p1 p2 k3), then cv::stereoCalibrate with
//     those as the initial guess, giving cam_from_proj (x_cam = R x_proj + t).
// Views are rejected, each with a reason, when the board is not found (ChArUco:
// fewer than min_charuco_corners corners, or all on one board row/column), when
// fewer than min_corner_fraction of its found corners have a projector position (a
// board partly outside the projector's light is used with the corners it
// has: all of them for the camera, the lit ones for the projector and the
// joint fit), or when the view's reprojection
// RMS after the joint fit exceeds max_view_rms_px (then the rest are fitted
// again). OpenCV does the fitting; this file only organises it.
//
// Units: pixels with centres at integers (OpenCV's and procam's convention),
// mm for the board and the pose. Thread-safety: pure functions.
// Errors: Code::invalid_argument for bad inputs (sizes, board spec),
// Code::failed_precondition when fewer than min_views views survive, naming
// every rejected view and why.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"

namespace procam::calibration {

// The printed target. Both types are described by their inner-corner grid
// (cols x rows; a board of 10 x 8 squares has 9 x 7), so corner (c, r) sits
// at (c, r) * square_mm on the board and has index r * cols + c.
//  - chessboard: every corner must be found in a view
//    (cv::findChessboardCorners);
//  - ChArUco (OpenCV's aruco module): ArUco markers of side marker_mm in the
//    light squares of a (cols + 1) x (rows + 1)-square board; corners come
//    from cv::aruco::detectMarkers + interpolateCornersCharuco, so a view may
//    show part of the board (each corner is identified by its marker
//    neighbours). OpenCV's ChArUco corner id is this index.
enum class BoardType { chessboard, charuco };

struct BoardSpec {
  int cols = 9, rows = 7;   // inner corners per row / per column
  double square_mm = 75.0;  // edge of one square
  BoardType type = BoardType::chessboard;
  double marker_mm = 0;                 // ChArUco: marker side, < square_mm
  std::string dictionary = "DICT_5X5_100";  // ChArUco: OpenCV predefined dictionary name
};

// Parses the command line's board: "9x7" (chessboard inner corners; the
// square size comes from `square_mm`) or
// "charuco:SXxSY:SQUARE_MM:MARKER_MM:DICT" (ChArUco, SX x SY *squares*, e.g.
// "charuco:5x7:40:30:DICT_5X5_100"). Validates like check_board.
Result<BoardSpec> parse_board(const std::string& text, double square_mm);

// Checks a board: >= 3x3 inner corners (ChArUco: >= 3x3 squares) up to 100,
// square in (0, 1000] mm, ChArUco marker in (0, square), a known dictionary
// with enough markers for the board. invalid_argument saying what to give.
Status check_board(const BoardSpec& board);

// The board as JSON: {"type": "chessboard", "inner_corners": [c, r],
// "square_mm": s} or {"type": "charuco", "squares": [c + 1, r + 1],
// "square_mm": s, "marker_mm": m, "dictionary": "DICT_..."}; and back
// (a missing "type" is a chessboard), validated by check_board.
nlohmann::json board_to_json(const BoardSpec& board);
Result<BoardSpec> board_from_json(const nlohmann::json& j);

// Intrinsics + OpenCV's 5-coefficient distortion (k1, k2, p1, p2, k3).
struct LensModel {
  uint32_t width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::array<double, 5> distortion{};
};

// One board pose: the camera's white (fully lit) image, 8-bit grey, and the
// decoded projector column/row of every camera pixel (NaN: not decoded).
struct View {
  std::string name;
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> white;                // width*height
  std::vector<float> proj_col, proj_row;     // width*height, projector pixels
};

struct Options {
  int window_radius_px = 15;       // local homography window: (2r+1)^2 camera pixels
  double min_window_valid = 0.5;   // fraction of the window that must be decoded
  double min_corner_fraction = 0.5;  // corners with a projector position, per view
  double max_view_rms_px = 2.0;    // reject a view above this after the joint fit
  int min_views = 3;
  int min_charuco_corners = 6;     // ChArUco: fewer interpolated corners reject the view
};

struct ViewReport {
  std::string name;
  bool used = false;
  std::string rejected_because;  // empty when used
  int corners = 0;               // board corners found in the camera image (ChArUco: interpolated)
  int projector_corners = 0;     // of which with a projector position
  double camera_rms_px = 0, projector_rms_px = 0;  // after the joint fit (used views)
  // The corners with a projector position: board index (row * cols + col),
  // camera and projector pixel.
  std::vector<int> corner_index;
  std::vector<std::array<float, 2>> cam_corners, proj_corners;
};

// Independent check of a model on real data (no ground truth needed): each
// corner is triangulated from its camera and projector positions
// (undistorted, cv::triangulatePoints) and the distance between neighbouring
// corners is compared with the board's square size. A focal length or
// baseline that is off scales every distance.
struct SquareCheck {
  size_t pairs = 0;
  double mean_mm = 0;       // mean neighbour distance
  double rms_error_mm = 0;  // RMS of (distance - square_mm)
};

struct RigCalibration {
  LensModel camera, projector;
  std::array<double, 9> cam_from_proj_rotation{};  // row-major R: x_cam = R x_proj + t
  std::array<double, 3> cam_from_proj_translation_mm{};
  double camera_rms_px = 0;     // cv::calibrateCamera, camera alone
  double projector_rms_px = 0;  // cv::calibrateCamera, projector alone
  double stereo_rms_px = 0;     // cv::stereoCalibrate: overall RMS over both devices
  std::vector<ViewReport> views;
  SquareCheck square;  // check_square_size of this model on its used views
};

SquareCheck check_square_size(const RigCalibration& model, const std::vector<ViewReport>& views,
                              const BoardSpec& board);

// Calibrates from `views` (>= options.min_views usable) of `board`, for a
// projector of projector_width x projector_height pixels.
Result<RigCalibration> calibrate(const std::vector<View>& views, const BoardSpec& board,
                         uint32_t projector_width, uint32_t projector_height,
                         const Options& options = {});

// The rig-config form of a result: {"projector": {"intrinsics": {...,
// "distortion": [5]}}, "cameras": [{"intrinsics": {...}, "cam_from_proj":
// {"rotation": [9], "translation_mm": [3]}}], "calibration_report": {...}}.
nlohmann::json to_rig_json(const RigCalibration& result);

// A per-view table (Markdown) of what was used, rejected and why, and the RMS.
std::string report_markdown(const RigCalibration& result);

}  // namespace procam::calibration
