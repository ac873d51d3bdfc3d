// SPDX-License-Identifier: MIT
// Geometric rig calibration (procam/calibration/geometric.hpp): corners,
// local homographies, OpenCV's camera and stereo calibration, view rejection.
#include "procam/calibration/geometric.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "board.hpp"

namespace procam::calibration {
namespace {

using Pts2 = std::vector<cv::Point2f>;
using Pts3 = std::vector<cv::Point3f>;

// Projector position of camera point `corner` from the decoded maps around it
// (step 2 of the header). False when too little of the window is decoded or
// the fit is degenerate.
bool projector_corner(const View& v, cv::Point2f corner, const Options& o, cv::Point2f& out) {
  const int r = o.window_radius_px;
  const int cx = static_cast<int>(std::lround(corner.x)), cy = static_cast<int>(std::lround(corner.y));
  Pts2 cam, proj;
  const int side = 2 * r + 1;
  cam.reserve(static_cast<size_t>(side * side));
  proj.reserve(cam.capacity());
  for (int y = cy - r; y <= cy + r; ++y)
    for (int x = cx - r; x <= cx + r; ++x) {
      if (x < 0 || y < 0 || x >= static_cast<int>(v.width) || y >= static_cast<int>(v.height)) continue;
      const size_t i = static_cast<size_t>(y) * v.width + static_cast<size_t>(x);
      const float c = v.proj_col[i], rr = v.proj_row[i];
      if (!std::isfinite(c) || !std::isfinite(rr)) continue;
      cam.emplace_back(static_cast<float>(x), static_cast<float>(y));
      proj.emplace_back(c, rr);
    }
  if (static_cast<double>(cam.size()) < o.min_window_valid * side * side || cam.size() < 8) return false;
  // RANSAC (3 projector px) drops decoding outliers, then least squares on
  // the inliers (OpenCV refines the RANSAC model on its inlier set).
  const cv::Mat H = cv::findHomography(cam, proj, cv::RANSAC, 3.0);
  if (H.empty()) return false;
  const cv::Vec3d p = cv::Matx33d(H) * cv::Vec3d(corner.x, corner.y, 1.0);
  if (!(std::abs(p[2]) > 1e-12)) return false;
  out = cv::Point2f(static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2]));
  return std::isfinite(out.x) && std::isfinite(out.y);
}

LensModel lens_from(const cv::Mat& K, const cv::Mat& D, cv::Size size) {
  LensModel m;
  m.width = static_cast<uint32_t>(size.width);
  m.height = static_cast<uint32_t>(size.height);
  m.fx = K.at<double>(0, 0);
  m.fy = K.at<double>(1, 1);
  m.cx = K.at<double>(0, 2);
  m.cy = K.at<double>(1, 2);
  for (int k = 0; k < 5 && k < static_cast<int>(D.total()); ++k) m.distortion[static_cast<size_t>(k)] = D.at<double>(k);
  return m;
}

double view_rms(const Pts3& obj, const Pts2& img, const cv::Mat& rvec, const cv::Mat& tvec,
                const cv::Mat& K, const cv::Mat& D) {
  Pts2 proj;
  cv::projectPoints(obj, rvec, tvec, K, D, proj);
  double s = 0;
  for (size_t i = 0; i < img.size(); ++i) {
    const cv::Point2f d = proj[i] - img[i];
    s += static_cast<double>(d.x * d.x + d.y * d.y);
  }
  return img.empty() ? 0.0 : std::sqrt(s / static_cast<double>(img.size()));
}

struct Detected {
  size_t view = 0;
  Pts3 obj;               // every board corner found in the camera image ...
  Pts2 cam;               // ... and where
  Pts3 obj_sub;           // the corners with a projector position ...
  Pts2 cam_sub, proj_sub; // ... in the camera and in the projector
};

}  // namespace

Result<RigCalibration> calibrate(const std::vector<View>& views, const BoardSpec& board,
                                 uint32_t projector_width, uint32_t projector_height,
                                 const Options& options) {
  if (Status s = check_board(board); !s.ok()) return s;
  if (projector_width == 0 || projector_height == 0)
    return Error(Code::invalid_argument, "calibrate: projector size is 0", "give --projector WxH");
  if (views.empty()) return Error(Code::invalid_argument, "calibrate: no views", "capture at least 3 board poses");
  const cv::Size cam_size(static_cast<int>(views[0].width), static_cast<int>(views[0].height));
  const cv::Size proj_size(static_cast<int>(projector_width), static_cast<int>(projector_height));

  RigCalibration out;
  std::vector<Detected> det;
  for (size_t k = 0; k < views.size(); ++k) {
    const View& v = views[k];
    ViewReport rep;
    rep.name = v.name;
    const size_t n = size_t{v.width} * v.height;
    if (v.width != views[0].width || v.height != views[0].height || v.white.size() != n ||
        v.proj_col.size() != n || v.proj_row.size() != n)
      return Error(Code::invalid_argument,
                   "calibrate: view " + v.name + " (" + std::to_string(v.width) + "x" + std::to_string(v.height) +
                       ") has mismatched sizes: white " + std::to_string(v.white.size()) + " px, maps " +
                       std::to_string(v.proj_col.size()) + "/" + std::to_string(v.proj_row.size()) +
                       " px; the first view is " + std::to_string(views[0].width) + "x" +
                       std::to_string(views[0].height),
                   "every view must come from the same camera and be decoded with rows");
    cv::Mat white(cam_size, CV_8UC1, const_cast<uint8_t*>(v.white.data()));
    detail::FoundCorners found = detail::find_corners(white, board, options.min_charuco_corners);
    if (!found.rejected_because.empty()) {
      rep.rejected_because = found.rejected_because;
      out.views.push_back(rep);
      continue;
    }
    const size_t n_corners = found.image.size();
    rep.corners = static_cast<int>(n_corners);
    Detected d;
    d.view = out.views.size();
    d.cam = found.image;
    for (size_t i = 0; i < n_corners; ++i) {
      const cv::Point3f o = detail::corner_point(board, found.index[i]);
      d.obj.push_back(o);
      cv::Point2f p;
      if (!projector_corner(v, found.image[i], options, p)) continue;
      d.obj_sub.push_back(o);
      d.cam_sub.push_back(found.image[i]);
      d.proj_sub.push_back(p);
    }
    const int have = static_cast<int>(d.proj_sub.size());
    rep.projector_corners = have;
    if (have < (board.type == BoardType::charuco ? options.min_charuco_corners : 8) || have < static_cast<int>(std::ceil(options.min_corner_fraction * static_cast<double>(n_corners)))) {
      rep.rejected_because = std::to_string(have) + " of " + std::to_string(n_corners) +
                             " corners have a decoded projector position (the projector must light most of "
                             "the board, and the decode must include rows)";
      out.views.push_back(rep);
      continue;
    }
    // Views where the projector lights only part of the board still count:
    // the camera uses every corner, the projector and the joint fit the
    // corners with a projector position.
    det.push_back(std::move(d));
    out.views.push_back(rep);
  }

  for (;;) {
    if (static_cast<int>(det.size()) < options.min_views) {
      std::string why;
      for (const ViewReport& r : out.views)
        if (!r.rejected_because.empty()) why += "\n  " + r.name + ": " + r.rejected_because;
      return Error(Code::failed_precondition,
                   "calibrate: " + std::to_string(det.size()) + " usable views, need " +
                       std::to_string(options.min_views) + why,
                   "capture more board poses (tilted 20-40 degrees, filling different parts of both images)");
    }
    std::vector<Pts3> objs, objs_sub;
    std::vector<Pts2> cam_pts, cam_sub, proj_sub;
    for (const Detected& d : det) {
      objs.push_back(d.obj);
      cam_pts.push_back(d.cam);
      objs_sub.push_back(d.obj_sub);
      cam_sub.push_back(d.cam_sub);
      proj_sub.push_back(d.proj_sub);
    }
    cv::Mat Kc, Dc, Kp, Dp;
    std::vector<cv::Mat> rc, tc, rp, tp;
    out.camera_rms_px = cv::calibrateCamera(objs, cam_pts, cam_size, Kc, Dc, rc, tc);
    out.projector_rms_px = cv::calibrateCamera(objs_sub, proj_sub, proj_size, Kp, Dp, rp, tp);
    // Projector as the first device: R, T map projector to camera coordinates,
    // i.e. cam_from_proj directly.
    cv::Mat R, T, E, F;
    out.stereo_rms_px = cv::stereoCalibrate(
        objs_sub, proj_sub, cam_sub, Kp, Dp, Kc, Dc, cam_size, R, T, E, F, cv::CALIB_USE_INTRINSIC_GUESS,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-9));
    // Per-view errors under the joint model: the camera pose from solvePnP
    // with the final camera model; the projector pose follows from the rig.
    size_t worst = det.size();
    double worst_rms = 0;
    for (size_t k = 0; k < det.size(); ++k) {
      cv::Mat rvec, tvec;
      cv::solvePnP(det[k].obj, det[k].cam, Kc, Dc, rvec, tvec);
      const double ec = view_rms(det[k].obj, det[k].cam, rvec, tvec, Kc, Dc);
      cv::Mat Rc;
      cv::Rodrigues(rvec, Rc);
      // x_proj = R^T (x_cam - T): board -> camera -> projector.
      const cv::Mat Rp = R.t() * Rc, tpv = R.t() * (tvec - T);
      cv::Mat rvec_p;
      cv::Rodrigues(Rp, rvec_p);
      const double ep = view_rms(det[k].obj_sub, det[k].proj_sub, rvec_p, tpv, Kp, Dp);
      ViewReport& rep = out.views[det[k].view];
      rep.camera_rms_px = ec;
      rep.projector_rms_px = ep;
      const double e = std::max(ec, ep);
      if (e > worst_rms) worst_rms = e, worst = k;
    }
    if (worst < det.size() && worst_rms > options.max_view_rms_px) {
      ViewReport& rep = out.views[det[worst].view];
      char buf[160];
      std::snprintf(buf, sizeof buf, "reprojection RMS %.2f px (camera %.2f, projector %.2f) > %.2f px",
                    worst_rms, rep.camera_rms_px, rep.projector_rms_px, options.max_view_rms_px);
      rep.rejected_because = buf;
      det.erase(det.begin() + static_cast<std::ptrdiff_t>(worst));
      continue;  // fit again without it
    }
    for (const Detected& d : det) {
      ViewReport& rep = out.views[d.view];
      rep.used = true;
      for (size_t i = 0; i < d.obj_sub.size(); ++i) {
        const cv::Point3f& o = d.obj_sub[i];
        rep.corner_index.push_back(static_cast<int>(std::lround(static_cast<double>(o.y) / board.square_mm)) * board.cols +
                                   static_cast<int>(std::lround(static_cast<double>(o.x) / board.square_mm)));
        rep.cam_corners.push_back({d.cam_sub[i].x, d.cam_sub[i].y});
        rep.proj_corners.push_back({d.proj_sub[i].x, d.proj_sub[i].y});
      }
    }
    out.camera = lens_from(Kc, Dc, cam_size);
    out.projector = lens_from(Kp, Dp, proj_size);
    for (int i = 0; i < 9; ++i) out.cam_from_proj_rotation[static_cast<size_t>(i)] = R.at<double>(i / 3, i % 3);
    for (int i = 0; i < 3; ++i) out.cam_from_proj_translation_mm[static_cast<size_t>(i)] = T.at<double>(i);
    out.square = check_square_size(out, out.views, board);
    return out;
  }
}

namespace {
cv::Mat camera_matrix(const LensModel& m) {
  return (cv::Mat_<double>(3, 3) << m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1);
}
cv::Mat dist_coeffs(const LensModel& m) {
  return (cv::Mat_<double>(1, 5) << m.distortion[0], m.distortion[1], m.distortion[2],
          m.distortion[3], m.distortion[4]);
}
}  // namespace

SquareCheck check_square_size(const RigCalibration& model, const std::vector<ViewReport>& views,
                              const BoardSpec& board) {
  SquareCheck c;
  const cv::Mat Kc = camera_matrix(model.camera), Dc = dist_coeffs(model.camera);
  const cv::Mat Kp = camera_matrix(model.projector), Dp = dist_coeffs(model.projector);
  cv::Mat P_proj = cv::Mat::eye(3, 4, CV_64F), P_cam(3, 4, CV_64F);  // projector frame: x_cam = R x + t
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) P_cam.at<double>(i, j) = model.cam_from_proj_rotation[static_cast<size_t>(3 * i + j)];
    P_cam.at<double>(i, 3) = model.cam_from_proj_translation_mm[static_cast<size_t>(i)];
  }
  double sum = 0, sq = 0;
  for (const ViewReport& v : views) {
    if (!v.used || v.cam_corners.empty()) continue;
    Pts2 cam, proj, cam_n, proj_n;
    for (size_t i = 0; i < v.cam_corners.size(); ++i) {
      cam.emplace_back(v.cam_corners[i][0], v.cam_corners[i][1]);
      proj.emplace_back(v.proj_corners[i][0], v.proj_corners[i][1]);
    }
    cv::undistortPoints(cam, cam_n, Kc, Dc);
    cv::undistortPoints(proj, proj_n, Kp, Dp);
    cv::Mat X;
    cv::triangulatePoints(P_proj, P_cam, proj_n, cam_n, X);
    X.convertTo(X, CV_64F);
    std::vector<cv::Vec3d> pts(v.corner_index.size());
    std::vector<int> at(static_cast<size_t>(board.cols * board.rows), -1);
    for (size_t i = 0; i < pts.size(); ++i) {
      const double w = X.at<double>(3, static_cast<int>(i));
      pts[i] = cv::Vec3d(X.at<double>(0, static_cast<int>(i)), X.at<double>(1, static_cast<int>(i)),
                         X.at<double>(2, static_cast<int>(i))) / w;
      at[static_cast<size_t>(v.corner_index[i])] = static_cast<int>(i);
    }
    for (int r = 0; r < board.rows; ++r)
      for (int col = 0; col < board.cols; ++col) {
        const int a = at[static_cast<size_t>(r * board.cols + col)];
        if (a < 0) continue;
        for (const int b : {col + 1 < board.cols ? at[static_cast<size_t>(r * board.cols + col + 1)] : -1,
                            r + 1 < board.rows ? at[static_cast<size_t>((r + 1) * board.cols + col)] : -1}) {
          if (b < 0) continue;
          const double d = cv::norm(pts[static_cast<size_t>(a)] - pts[static_cast<size_t>(b)]);
          sum += d;
          sq += (d - board.square_mm) * (d - board.square_mm);
          ++c.pairs;
        }
      }
  }
  if (c.pairs > 0) {
    c.mean_mm = sum / static_cast<double>(c.pairs);
    c.rms_error_mm = std::sqrt(sq / static_cast<double>(c.pairs));
  }
  return c;
}

namespace {
nlohmann::json lens_json(const LensModel& m) {
  return {{"width", m.width}, {"height", m.height}, {"fx", m.fx}, {"fy", m.fy},
          {"cx", m.cx},       {"cy", m.cy},         {"distortion", m.distortion}};
}
}  // namespace

nlohmann::json to_rig_json(const RigCalibration& r) {
  nlohmann::json views = nlohmann::json::array();
  for (const ViewReport& v : r.views)
    views.push_back({{"name", v.name}, {"used", v.used}, {"rejected_because", v.rejected_because},
                     {"corners", v.corners}, {"projector_corners", v.projector_corners},
                     {"camera_rms_px", v.camera_rms_px}, {"projector_rms_px", v.projector_rms_px}});
  return {{"projector", {{"intrinsics", lens_json(r.projector)}}},
          {"cameras",
           {{{"intrinsics", lens_json(r.camera)},
             {"cam_from_proj",
              {{"rotation", r.cam_from_proj_rotation}, {"translation_mm", r.cam_from_proj_translation_mm}}}}}},
          {"calibration_report",
           {{"method", "chessboard corners; projector corners by local homography (Moreno & Taubin 2012); "
                       "OpenCV calibrateCamera + stereoCalibrate; distortion k1 k2 p1 p2 k3"},
            {"camera_rms_px", r.camera_rms_px},
            {"projector_rms_px", r.projector_rms_px},
            {"stereo_rms_px", r.stereo_rms_px},
            {"square_check", {{"pairs", r.square.pairs}, {"mean_mm", r.square.mean_mm},
                              {"rms_error_mm", r.square.rms_error_mm}}},
            {"views", views}}}};
}

std::string report_markdown(const RigCalibration& r) {
  std::ostringstream s;
  char buf[256];
  s << "| view | used | corners | with projector position | camera RMS (px) | projector RMS (px) | why rejected |\n"
    << "|---|---|---:|---:|---:|---:|---|\n";
  for (const ViewReport& v : r.views) {
    std::snprintf(buf, sizeof buf, "| %s | %s | %d | %d | %.3f | %.3f | %s |\n", v.name.c_str(),
                  v.used ? "yes" : "no", v.corners, v.projector_corners, v.camera_rms_px,
                  v.projector_rms_px, v.rejected_because.c_str());
    s << buf;
  }
  std::snprintf(buf, sizeof buf,
                "\nRMS reprojection error: camera %.3f px, projector %.3f px, joint (stereo) %.3f px\n",
                r.camera_rms_px, r.projector_rms_px, r.stereo_rms_px);
  s << buf;
  std::snprintf(buf, sizeof buf,
                "Board squares measured by triangulating the corners: mean %.2f mm, RMS error %.2f mm "
                "(%zu neighbour pairs)\n",
                r.square.mean_mm, r.square.rms_error_mm, r.square.pairs);
  s << buf;
  return s.str();
}

}  // namespace procam::calibration
