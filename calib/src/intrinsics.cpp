#include "vdrig/calib/intrinsics.hpp"

#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/log.hpp"

namespace vdrig::calib {

namespace {

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(m), v.end());
  if (v.size() % 2) return v[m];
  const double hi = v[m];
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + static_cast<long>(m)));
}

struct Fit {
  cv::Mat K, D, std_dev, per_view;
  std::vector<cv::Mat> rvecs, tvecs;
  double rms = 0;
};

Fit run_calibration(const std::vector<std::vector<cv::Point3f>>& object,
                    const std::vector<std::vector<cv::Point2f>>& image, cv::Size size, bool fix_aspect, bool fix_k3) {
  Fit f;
  f.K = cv::Mat::eye(3, 3, CV_64F);
  int flags = 0;
  if (fix_aspect) flags |= cv::CALIB_FIX_ASPECT_RATIO;  // fx / fy held at K's initial 1
  if (fix_k3) flags |= cv::CALIB_FIX_K3;                // k3 held at 0
  cv::Mat std_ext;
  f.rms = cv::calibrateCamera(object, image, size, f.K, f.D, f.rvecs, f.tvecs, f.std_dev, std_ext, f.per_view, flags,
                              cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, DBL_EPSILON));
  return f;
}

}  // namespace

bool IntrinsicsOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(outlier_factor > 1)) return fail("outlier factor must be > 1");
  if (subpix_half_window < 1 || subpix_half_window > kMaxSubpixHalfWindow)
    return fail("subpixel half window must be in [1, " + std::to_string(kMaxSubpixHalfWindow) + "] px, got " +
                std::to_string(subpix_half_window));
  return true;
}

size_t IntrinsicsResult::used_views() const {
  return static_cast<size_t>(std::count_if(views.begin(), views.end(), [](const auto& v) { return v.used; }));
}

Result<IntrinsicsResult> calibrate_intrinsics(std::span<const cv::Mat> images, int board_cols, int board_rows,
                                              double square_m, const IntrinsicsOptions& opt) {
  const auto bad = [](const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); };
  if (images.empty()) return bad("no calibration images");
  if (board_cols < 2 || board_rows < 2 || board_cols == board_rows)
    return bad("board needs at least 2x2 inner corners and cols != rows (a square board's orientation is ambiguous)");
  if (!(square_m > 0)) return bad("square size must be positive (metres)");
  std::string why;
  if (!opt.is_valid(&why)) return bad(why);
  auto log = log::get("calib");

  const cv::Size size = images[0].size();
  // cv::cornerSubPix asserts that its window (plus a margin) fits the image, and a board of n corners needs a few
  // pixels per square to be found at all: a smaller image is refused here rather than aborting inside OpenCV.
  const int min_side = std::max({2 * opt.subpix_half_window + 5, 4 * (board_cols + 1), 4 * (board_rows + 1)});
  if (size.width < min_side || size.height < min_side)
    return bad("images are " + std::to_string(size.width) + "x" + std::to_string(size.height) + " px; a " +
               std::to_string(board_cols) + "x" + std::to_string(board_rows) +
               " board with a subpixel half window of " + std::to_string(opt.subpix_half_window) + " needs at least " +
               std::to_string(min_side) + " px a side");
  IntrinsicsResult res;
  res.board_cols = board_cols;
  res.board_rows = board_rows;
  res.square_m = square_m;
  res.fix_aspect_ratio = opt.fix_aspect_ratio;
  res.fix_k3 = opt.fix_k3;
  std::vector<cv::Point3f> board;
  for (int r = 0; r < board_rows; ++r)
    for (int c = 0; c < board_cols; ++c)
      board.emplace_back(static_cast<float>(c * square_m), static_cast<float>(r * square_m), 0.0f);

  std::vector<std::vector<cv::Point2f>> corners_of(images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    const cv::Mat& img = images[i];
    if (img.empty() || img.depth() != CV_8U || (img.channels() != 1 && img.channels() != 3))
      return bad("image " + std::to_string(i) + " is empty or not 8-bit grey/BGR");
    if (img.size() != size)
      return bad("image " + std::to_string(i) + " is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) +
                 ", image 0 is " + std::to_string(size.width) + "x" + std::to_string(size.height));
    cv::Mat grey;
    if (img.channels() == 3)
      cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
    else
      grey = img;
    IntrinsicsView v;
    v.image_index = i;
    std::vector<cv::Point2f> corners;
    v.board_found = cv::findChessboardCorners(grey, {board_cols, board_rows}, corners,
                                              cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (v.board_found) {
      const int hw = opt.subpix_half_window;
      cv::cornerSubPix(grey, corners, {hw, hw}, {-1, -1},
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.0001));
      corners_of[i] = std::move(corners);
    } else {
      log->warn("image {}: no {}x{} chessboard found; skipped", i, board_cols, board_rows);
    }
    v.used = v.board_found;
    res.views.push_back(v);
  }

  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::vector<cv::Point3f>> object;
    std::vector<std::vector<cv::Point2f>> image;
    std::vector<size_t> index;
    for (const auto& v : res.views)
      if (v.used) {
        object.push_back(board);
        image.push_back(corners_of[v.image_index]);
        index.push_back(v.image_index);
      }
    if (object.size() < 3)
      return bad("the board was found in " + std::to_string(object.size()) + " image(s); at least 3 are needed");
    Fit fit;
    try {
      fit = run_calibration(object, image, size, opt.fix_aspect_ratio, opt.fix_k3);
    } catch (const cv::Exception& e) {
      return make_error(ErrorCode::kInternal, std::string("cv::calibrateCamera: ") + e.what());
    }
    res.rms_px = fit.rms;
    auto& cam = res.camera;
    cam.width = size.width;
    cam.height = size.height;
    cam.fx = fit.K.at<double>(0, 0);
    cam.fy = fit.K.at<double>(1, 1);
    cam.cx = fit.K.at<double>(0, 2);
    cam.cy = fit.K.at<double>(1, 2);
    const double* d = fit.D.ptr<double>();
    cam.k1 = d[0];
    cam.k2 = d[1];
    cam.p1 = d[2];
    cam.p2 = d[3];
    cam.k3 = d[4];
    // stdDeviationsIntrinsics order: fx, fy, cx, cy, k1, k2, p1, p2, k3, ...
    const double* s = fit.std_dev.ptr<double>();
    res.std_dev = {s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8]};
    // With the aspect fixed, fx = a fy is not a free parameter (OpenCV reports 0); it inherits fy's uncertainty.
    if (opt.fix_aspect_ratio) res.std_dev.fx = res.std_dev.fy * cam.fx / cam.fy;

    // Per-view errors of the views not in this fit (dropped outliers) with the final model, for the report.
    std::vector<double> rms_used;
    for (size_t k = 0; k < index.size(); ++k) {
      auto& v = res.views[index[k]];
      v.rms_px = fit.per_view.at<double>(static_cast<int>(k));
      cv::Mat R;
      cv::Rodrigues(fit.rvecs[k], R);
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) v.pose.R(r, c) = R.at<double>(r, c);
        v.pose.t(r) = fit.tvecs[k].at<double>(r) * 1000.0;  // metres -> mm
      }
      rms_used.push_back(v.rms_px);
    }
    const double med = median_of(rms_used);
    bool any_outlier = false;
    for (auto& v : res.views) {
      if (!v.board_found) continue;
      if (!v.used) {  // dropped in pass 0: re-evaluate its error against the final model
        cv::Mat rvec, tvec;
        std::vector<cv::Point2f> proj;
        cv::solvePnP(board, corners_of[v.image_index], fit.K, fit.D, rvec, tvec);
        cv::projectPoints(board, rvec, tvec, fit.K, fit.D, proj);
        v.rms_px = cv::norm(proj, corners_of[v.image_index], cv::NORM_L2) / std::sqrt(double(proj.size()));
      }
      v.outlier = v.rms_px > opt.outlier_factor * med;
      any_outlier = any_outlier || (v.outlier && v.used);
    }
    if (pass == 0 && opt.drop_outliers && any_outlier) {
      for (auto& v : res.views)
        if (v.outlier) {
          log->info("image {}: outlier view (RMS {:.3f} px > {} x median {:.3f} px); calibrating without it",
                    v.image_index, v.rms_px, opt.outlier_factor, med);
          v.used = false;
        }
      continue;
    }
    break;
  }
  if (!res.camera.is_valid(&why)) return make_error(ErrorCode::kInternal, "calibration gave an invalid camera: " + why);
  return res;
}

Status IntrinsicsResult::save_yaml(const std::filesystem::path& path) const {
  // The calibration record OpenCV's sample writes, plus vdrig's standard deviations and view bookkeeping.
  return camera.save_yaml(path, rms_px, [this](cv::FileStorage& fs) {
    fs << "nframes" << static_cast<int>(used_views());
    fs << "board_width" << board_cols << "board_height" << board_rows << "square_size" << square_m;
    fs << "flags"
       << ((fix_aspect_ratio ? static_cast<int>(cv::CALIB_FIX_ASPECT_RATIO) : 0) |
           (fix_k3 ? static_cast<int>(cv::CALIB_FIX_K3) : 0));
    std::vector<double> errs;
    std::vector<int> used_idx, outliers;
    for (const auto& v : views) {
      if (v.used) {
        errs.push_back(v.rms_px);
        used_idx.push_back(static_cast<int>(v.image_index));
      }
      if (v.outlier) outliers.push_back(static_cast<int>(v.image_index));
    }
    fs << "per_view_reprojection_errors" << cv::Mat(errs, true);
    fs << "view_indices" << used_idx;
    fs << "outlier_views" << outliers;
    const auto& s = std_dev;
    fs << "std_dev_intrinsics" << (cv::Mat_<double>(9, 1) << s.fx, s.fy, s.cx, s.cy, s.k1, s.k2, s.p1, s.p2, s.k3);
  });
}

}  // namespace vdrig::calib
