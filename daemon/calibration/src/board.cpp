// SPDX-License-Identifier: MIT
// Board specs (parse, JSON, checks) and corner detection in a camera image
// (board.hpp, procam/calibration/geometric.hpp). OpenCV's aruco module does
// the ChArUco work; this file maps names and ids.
#include "board.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <set>
#include <utility>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/imgproc.hpp>

namespace procam::calibration {
namespace {

struct DictName {
  const char* name;
  cv::aruco::PREDEFINED_DICTIONARY_NAME id;
  int size;  // markers in the dictionary
};
constexpr std::array<DictName, 21> kDicts{{
    {"DICT_4X4_50", cv::aruco::DICT_4X4_50, 50},         {"DICT_4X4_100", cv::aruco::DICT_4X4_100, 100},
    {"DICT_4X4_250", cv::aruco::DICT_4X4_250, 250},      {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000, 1000},
    {"DICT_5X5_50", cv::aruco::DICT_5X5_50, 50},         {"DICT_5X5_100", cv::aruco::DICT_5X5_100, 100},
    {"DICT_5X5_250", cv::aruco::DICT_5X5_250, 250},      {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000, 1000},
    {"DICT_6X6_50", cv::aruco::DICT_6X6_50, 50},         {"DICT_6X6_100", cv::aruco::DICT_6X6_100, 100},
    {"DICT_6X6_250", cv::aruco::DICT_6X6_250, 250},      {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000, 1000},
    {"DICT_7X7_50", cv::aruco::DICT_7X7_50, 50},         {"DICT_7X7_100", cv::aruco::DICT_7X7_100, 100},
    {"DICT_7X7_250", cv::aruco::DICT_7X7_250, 250},      {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000, 1000},
    {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL, 1024},
    {"DICT_APRILTAG_16h5", cv::aruco::DICT_APRILTAG_16h5, 30},
    {"DICT_APRILTAG_25h9", cv::aruco::DICT_APRILTAG_25h9, 35},
    {"DICT_APRILTAG_36h10", cv::aruco::DICT_APRILTAG_36h10, 2320},
    {"DICT_APRILTAG_36h11", cv::aruco::DICT_APRILTAG_36h11, 587},
}};

const DictName* find_dict(const std::string& name) {
  for (const DictName& d : kDicts)
    if (name == d.name) return &d;
  return nullptr;
}

std::string dict_list() {
  std::string s;
  for (const DictName& d : kDicts) s += (s.empty() ? "" : ", ") + std::string(d.name);
  return s;
}

const char* kBoardForms =
    "give a chessboard as --board 9x7 --square-mm 75 (inner corners) or a ChArUco board as "
    "--board charuco:5x7:40:30:DICT_5X5_100 (squares across x down, square mm, marker mm, dictionary)";

cv::Ptr<cv::aruco::CharucoBoard> charuco_of(const BoardSpec& b) {
  return cv::aruco::CharucoBoard::create(b.cols + 1, b.rows + 1, static_cast<float>(b.square_mm),
                                         static_cast<float>(b.marker_mm),
                                         cv::aruco::getPredefinedDictionary(find_dict(b.dictionary)->id));
}

// OpenCV 4.5.4+'s interpolateCornersCharuco returns corners in a frame whose
// origin is the top-left pixel's corner (opencv_contrib PR 3024), half a
// pixel off procam's and findChessboardCorners' frame (pixel centres at
// integers; opencv/opencv issue 25539, fixed upstream only in 2026). So
// refine each corner again with cv::cornerSubPix on the whole image, which
// converges in absolute centre-at-integer coordinates whatever the start
// (measured: 0.7 px RMS off the truth before, see charuco_test.cpp). The
// window stays inside the corner's two white squares: half-size = distance
// to the nearest detected marker corner - 1, clamped to 2..5 px.
void refine_to_pixel_centres(const cv::Mat& grey, const std::vector<std::vector<cv::Point2f>>& markers,
                             std::vector<cv::Point2f>& corners) {
  for (cv::Point2f& c : corners) {
    double nearest = 1e9;
    for (const auto& m : markers)
      for (const cv::Point2f& q : m) nearest = std::min(nearest, static_cast<double>(cv::norm(q - c)));
    const int half = std::clamp(static_cast<int>(std::floor(nearest)) - 1, 2, 5);
    std::vector<cv::Point2f> one{c};
    cv::cornerSubPix(grey, one, cv::Size(half, half), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
    // Keep OpenCV's corner where the refinement ran away (> 2 px: a blurred
    // or occluded corner), rather than a wrong one.
    if (std::isfinite(one[0].x) && std::isfinite(one[0].y) && cv::norm(one[0] - c) < 2.0) c = one[0];
  }
}

}  // namespace

Status check_board(const BoardSpec& b) {
  const bool charuco = b.type == BoardType::charuco;
  const int lo = 3, hi = 100;
  if (b.cols < lo || b.rows < lo || b.cols > hi || b.rows > hi)
    return Error(Code::invalid_argument,
                 charuco ? "board: a ChArUco board needs 4..101 squares each way, got " + std::to_string(b.cols + 1) +
                               "x" + std::to_string(b.rows + 1)
                         : "board: a chessboard needs 3..100 inner corners each way, got " + std::to_string(b.cols) +
                               "x" + std::to_string(b.rows),
                 kBoardForms);
  if (!(b.square_mm > 0 && b.square_mm <= 1000))
    return Error(Code::invalid_argument, "board: square size must be in (0, 1000] mm", kBoardForms);
  if (!charuco) return {};
  if (!(b.marker_mm > 0 && b.marker_mm < b.square_mm))
    return Error(Code::invalid_argument, "board: the ChArUco marker side must be > 0 and smaller than the square",
                 "e.g. charuco:5x7:40:30:DICT_5X5_100 (40 mm squares, 30 mm markers)");
  const DictName* d = find_dict(b.dictionary);
  if (!d)
    return Error(Code::invalid_argument, "board: unknown ArUco dictionary '" + b.dictionary + "'",
                 "give one of OpenCV's predefined dictionaries: " + dict_list());
  // One marker per light square: floor(squares / 2).
  const int markers = ((b.cols + 1) * (b.rows + 1)) / 2;
  if (markers > d->size)
    return Error(Code::invalid_argument,
                 "board: a " + std::to_string(b.cols + 1) + "x" + std::to_string(b.rows + 1) + "-square ChArUco board has " +
                     std::to_string(markers) + " markers, " + b.dictionary + " only " + std::to_string(d->size),
                 "give a dictionary with more markers (e.g. DICT_5X5_1000) or check the board size");
  return {};
}

Result<BoardSpec> parse_board(const std::string& text, double square_mm) {
  BoardSpec b;
  int x = 0, y = 0;
  char tail = 0;
  if (text.rfind("charuco:", 0) == 0) {
    // charuco:SXxSY:SQUARE:MARKER:DICT
    std::vector<std::string> parts;
    size_t at = 8;
    for (size_t c; (c = text.find(':', at)) != std::string::npos; at = c + 1) parts.push_back(text.substr(at, c - at));
    parts.push_back(text.substr(at));
    double sq = 0, mk = 0;
    if (parts.size() != 4 || std::sscanf(parts[0].c_str(), "%dx%d%c", &x, &y, &tail) != 2 ||
        std::sscanf(parts[1].c_str(), "%lf%c", &sq, &tail) != 1 || std::sscanf(parts[2].c_str(), "%lf%c", &mk, &tail) != 1)
      return Error(Code::invalid_argument, "board '" + text + "' is not charuco:SXxSY:SQUARE_MM:MARKER_MM:DICT",
                   kBoardForms);
    b.type = BoardType::charuco;
    b.cols = x - 1;
    b.rows = y - 1;
    b.square_mm = sq;
    b.marker_mm = mk;
    b.dictionary = parts[3];
  } else {
    if (std::sscanf(text.c_str(), "%dx%d%c", &x, &y, &tail) != 2)
      return Error(Code::invalid_argument, "board '" + text + "' is neither COLSxROWS nor charuco:...", kBoardForms);
    b.cols = x;
    b.rows = y;
    b.square_mm = square_mm;
  }
  PROCAM_TRY(check_board(b));
  return b;
}

nlohmann::json board_to_json(const BoardSpec& b) {
  if (b.type == BoardType::charuco)
    return {{"type", "charuco"},          {"squares", {b.cols + 1, b.rows + 1}}, {"square_mm", b.square_mm},
            {"marker_mm", b.marker_mm}, {"dictionary", b.dictionary}};
  return {{"type", "chessboard"}, {"inner_corners", {b.cols, b.rows}}, {"square_mm", b.square_mm}};
}

Result<BoardSpec> board_from_json(const nlohmann::json& j) {
  const std::string form =
      "board is {\"type\": \"chessboard\", \"inner_corners\": [9, 7], \"square_mm\": 75} or {\"type\": \"charuco\", "
      "\"squares\": [5, 7], \"square_mm\": 40, \"marker_mm\": 30, \"dictionary\": \"DICT_5X5_100\"}";
  if (!j.is_object()) return Error(Code::invalid_argument, "board must be an object", form);
  BoardSpec b;
  const std::string type = j.contains("type") && j["type"].is_string() ? j["type"].get<std::string>() : "chessboard";
  const bool charuco = type == "charuco";
  if (!charuco && type != "chessboard")
    return Error(Code::invalid_argument, "board.type must be \"chessboard\" or \"charuco\", got \"" + type + "\"", form);
  const char* grid = charuco ? "squares" : "inner_corners";
  const auto& g = j.contains(grid) ? j[grid] : nlohmann::json();
  if (!g.is_array() || g.size() != 2 || !g[0].is_number_integer() || !g[1].is_number_integer() ||
      !j.contains("square_mm") || !j["square_mm"].is_number())
    return Error(Code::invalid_argument, std::string("board needs \"") + grid + "\": [x, y] and \"square_mm\"", form);
  const int off = charuco ? 1 : 0;
  b.cols = g[0].get<int>() - off;
  b.rows = g[1].get<int>() - off;
  b.square_mm = j["square_mm"].get<double>();
  if (charuco) {
    b.type = BoardType::charuco;
    if (!j.contains("marker_mm") || !j["marker_mm"].is_number() || !j.contains("dictionary") ||
        !j["dictionary"].is_string())
      return Error(Code::invalid_argument, "a ChArUco board needs \"marker_mm\" and \"dictionary\"", form);
    b.marker_mm = j["marker_mm"].get<double>();
    b.dictionary = j["dictionary"].get<std::string>();
  }
  PROCAM_TRY(check_board(b));
  return b;
}

namespace detail {

cv::Point3f corner_point(const BoardSpec& b, int index) {
  return {static_cast<float>((index % b.cols) * b.square_mm), static_cast<float>((index / b.cols) * b.square_mm), 0.f};
}

FoundCorners find_corners(const cv::Mat& white, const BoardSpec& board, int min_charuco_corners) {
  FoundCorners f;
  if (board.type == BoardType::chessboard) {
    const bool found = cv::findChessboardCorners(white, cv::Size(board.cols, board.rows), f.image,
                                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (!found || f.image.size() != static_cast<size_t>(board.cols * board.rows)) {
      f.image.clear();
      f.rejected_because = "chessboard " + std::to_string(board.cols) + "x" + std::to_string(board.rows) +
                           " inner corners not found in the white image";
      return f;
    }
    cv::cornerSubPix(white, f.image, cv::Size(11, 11), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
    for (int i = 0; i < board.cols * board.rows; ++i) f.index.push_back(i);
    return f;
  }
  // ChArUco. OpenCV refines the interpolated corners with cornerSubPix.
  try {
    const cv::Ptr<cv::aruco::CharucoBoard> cb = charuco_of(board);
    std::vector<std::vector<cv::Point2f>> marker_corners;
    std::vector<int> marker_ids;
    cv::aruco::detectMarkers(white, cb->dictionary, marker_corners, marker_ids);
    if (!marker_ids.empty())
      cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, white, cb, f.image, f.index);
    refine_to_pixel_centres(white, marker_corners, f.image);
    const int n = static_cast<int>(f.index.size());
    std::set<int> rows, cols;
    for (const int i : f.index) rows.insert(i / board.cols), cols.insert(i % board.cols);
    if (n < min_charuco_corners || rows.size() < 2 || cols.size() < 2) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "%zu ChArUco markers, %d corners found (need >= %d, not all on one board row or column); "
                    "check the dictionary (%s) and the board size",
                    marker_ids.size(), n, min_charuco_corners, board.dictionary.c_str());
      f.rejected_because = buf;
      f.image.clear();
      f.index.clear();
    }
  } catch (const cv::Exception& e) {
    f.image.clear();
    f.index.clear();
    f.rejected_because = std::string("ChArUco detection failed: ") + e.what();
  }
  return f;
}

}  // namespace detail
}  // namespace procam::calibration
