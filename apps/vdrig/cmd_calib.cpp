// `vdrig calib intrinsics|response|extrinsics` (image files or a session), `vdrig hdr merge` (image files) and `vdrig
// hdr SESSION` (every bracket of a session).
#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/calib/hdr.hpp"
#include "vdrig/calib/intrinsics.hpp"
#include "vdrig/calib/kinematic.hpp"
#include "vdrig/calib/response_recovery.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/pipeline/pipeline.hpp"

namespace vdrig::app {
namespace {

Error usage(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }

/// "0.004", "1/250" -> seconds.
Result<double> parse_seconds(const std::string& s) {
  try {
    size_t used = 0;
    if (const auto slash = s.find('/'); slash != std::string::npos) {
      const double num = std::stod(s.substr(0, slash), &used);
      const double den = std::stod(s.substr(slash + 1));
      if (used != slash || !(den > 0)) throw std::invalid_argument(s);
      return num / den;
    }
    const double v = std::stod(s, &used);
    if (used != s.size()) throw std::invalid_argument(s);
    return v;
  } catch (const std::exception&) {
    return usage("bad exposure time '" + s + "' (seconds, e.g. 0.004 or 1/250)");
  }
}

/// Loads "IMAGE:EXPOSURE_S" items as Frames (grey images become 3-channel), sorted by exposure.
/// `bits` <= 0: the container's (8 or 16).
Result<std::vector<Frame>> load_bracket(const std::vector<std::string>& items, int bits) {
  std::vector<Frame> frames;
  for (const auto& item : items) {
    const auto colon = item.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == item.size())
      return usage("bracket item '" + item + "' is not IMAGE:EXPOSURE_S");
    auto t = parse_seconds(item.substr(colon + 1));
    if (!t) return t.error();
    const std::string path = item.substr(0, colon);
    auto img = read_png(path);  // PNG or JPEG, depth unchanged
    if (!img) return img.error();
    Frame f;
    f.image = std::move(*img);
    if (f.image.channels() == 1) cv::cvtColor(f.image, f.image, cv::COLOR_GRAY2BGR);
    if (f.image.channels() == 4) cv::cvtColor(f.image, f.image, cv::COLOR_BGRA2BGR);
    f.exposure_s = *t;
    f.bits = bits > 0 ? bits : (f.image.depth() == CV_16U ? 16 : 8);
    frames.push_back(std::move(f));
  }
  std::stable_sort(frames.begin(), frames.end(),
                   [](const Frame& a, const Frame& b) { return a.exposure_s < b.exposure_s; });
  return frames;
}

/// "9x6" -> (9, 6) inner corners.
Result<std::pair<int, int>> parse_board(const std::string& board) {
  int cols = 0, rows = 0;
  char x = 0;
  std::istringstream bs(board);
  if (!(bs >> cols >> x >> rows) || (x != 'x' && x != 'X') || !bs.eof())
    return usage("--board wants COLSxROWS inner corners, e.g. 9x6; got '" + board + "'");
  return std::make_pair(cols, rows);
}

/// Prints the calibration's table and parameters and writes `out`; `names` labels the views.
Status report_intrinsics(const calib::IntrinsicsResult& result, const std::vector<std::string>& names,
                         const std::string& out) {
  const auto& c = result.camera;
  const auto& s = result.std_dev;
  std::printf("view  rms_px  status  image\n");
  for (const auto& v : result.views)
    std::printf("%4zu  %6.3f  %-7s %s\n", v.image_index, v.rms_px,
                !v.board_found ? "nofound"
                : v.outlier    ? "OUTLIER"
                : v.used       ? "ok"
                               : "dropped",
                v.image_index < names.size() ? names[v.image_index].c_str() : "");
  std::printf("RMS %.4f px over %zu views (%dx%d)\n", result.rms_px, result.used_views(), c.width, c.height);
  std::printf("fx %10.3f +- %.3f   fy %10.3f +- %.3f\n", c.fx, s.fx, c.fy, s.fy);
  std::printf("cx %10.3f +- %.3f   cy %10.3f +- %.3f\n", c.cx, s.cx, c.cy, s.cy);
  std::printf("k1 %10.5f +- %.5f   k2 %10.5f +- %.5f   k3 %10.5f +- %.5f\n", c.k1, s.k1, c.k2, s.k2, c.k3, s.k3);
  std::printf("p1 %10.6f +- %.6f   p2 %10.6f +- %.6f\n", c.p1, s.p1, c.p2, s.p2);
  VDRIG_TRY(result.save_yaml(out));
  std::printf("wrote %s\n", out.c_str());
  return Status::ok();
}

Status run_intrinsics(const std::string& board, double square_m, const std::vector<std::string>& paths,
                      const std::string& out, const calib::IntrinsicsOptions& opt) {
  auto parsed = parse_board(board);
  if (!parsed) return parsed.error();
  const auto [cols, rows] = parsed.value();
  std::vector<cv::Mat> images;
  for (const auto& p : paths) {
    auto read = read_png(p);  // PNG or JPEG; a FIFO is refused, not waited on
    if (!read) return read.error();
    cv::Mat m = std::move(read.value());
    if (m.depth() == CV_16U) m.convertTo(m, CV_8U, 1.0 / 256);  // the high byte, as IMREAD_GRAYSCALE
    if (m.channels() == 3) cv::cvtColor(m, m, cv::COLOR_BGR2GRAY);
    if (m.channels() == 4) cv::cvtColor(m, m, cv::COLOR_BGRA2GRAY);
    images.push_back(m);
  }
  auto res = calib::calibrate_intrinsics(images, cols, rows, square_m, opt);
  if (!res) return res.error();
  return report_intrinsics(res.value(), paths, out);
}

/// Intrinsics from a session of a chessboard (pipeline::calibrate_session_intrinsics: one frame per complete view).
Status run_session_intrinsics(const std::string& session_dir, const std::string& board, double square_m,
                              const std::string& out, const calib::IntrinsicsOptions& opt) {
  auto parsed = parse_board(board);
  if (!parsed) return parsed.error();
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  pipeline::SessionIntrinsicsOptions options;
  std::tie(options.board_cols, options.board_rows) = parsed.value();
  options.square_m = square_m;
  options.intrinsics = opt;
  auto res = pipeline::calibrate_session_intrinsics(session.value(), options);
  if (!res) return res.error();
  std::vector<std::string> names;
  for (const auto& view : session->manifest().views)
    if (session->view_complete(view.index)) names.push_back("view " + std::to_string(view.index));
  return report_intrinsics(res.value(), names, out);
}

Status run_response(const std::vector<std::string>& items, const std::string& out,
                    const calib::ResponseRecoveryOptions& opt) {
  auto frames = load_bracket(items, 0);
  if (!frames) return frames.error();
  auto rec = calib::recover_response(*frames, opt);
  if (!rec) return rec.error();
  for (int c = 0; c < 3; ++c) {
    const auto& r = *rec;
    const char* names = "RGB";
    std::printf("channel %c: %d samples, rms log residual %.4f, inverse(mid) %.4f\n", names[c], r.samples[c],
                r.rms_residual_log[c], r.curve.inverse(c, r.curve.max_code() / 2.0));
  }
  VDRIG_TRY(write_file_atomic(out, rec->curve.to_json().dump(1)));
  std::printf("wrote %s\n", out.c_str());
  return Status::ok();
}

Status run_session_response(const std::string& session_dir, const pipeline::ResponseCalibrationOptions& options) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  auto cal = pipeline::calibrate_session_response(session.value(), options);
  if (!cal) return cal.error();
  const auto& r = cal->response;
  std::printf("bracket of view %d (%d codes covered)\n", cal->view, cal->codes_covered);
  for (int c = 0; c < 3; ++c)
    std::printf("channel %c: %d samples, rms log residual %.4f, inverse(mid) %.4f\n", "RGB"[c], r.samples[c],
                r.rms_residual_log[c], r.curve.inverse(c, r.curve.max_code() / 2.0));
  std::printf("wrote %s\n", session->layout().response_file().c_str());
  return Status::ok();
}

Status run_merge(const std::string& response_path, int bits, const std::vector<std::string>& items,
                 const std::string& out, bool half) {
  ResponseCurve response;
  if (!response_path.empty()) {
    auto j = read_json_file(response_path);
    if (!j) return j.error();
    auto r = ResponseCurve::from_json(j.value());
    if (!r) return r.error();
    response = std::move(*r);
    bits = response.bits();
  }
  auto frames = load_bracket(items, bits);
  if (!frames) return frames.error();
  auto hdr = calib::merge_hdr(*frames, response);
  if (!hdr) return hdr.error();
  const double sat = cv::countNonZero(hdr->mask & calib::kHdrSaturated),
               blk = cv::countNonZero(hdr->mask & calib::kHdrBlack);
  const double n = hdr->mask.total();
  std::printf("merged %zu exposures: %.2f%% pixels saturated everywhere, %.2f%% black everywhere\n", frames->size(),
              100 * sat / n, 100 * blk / n);
  VDRIG_TRY(calib::write_hdr_exr(out, *hdr, half ? ExrPixelType::kHalf : ExrPixelType::kFloat));
  std::printf("wrote %s\n", out.c_str());
  return Status::ok();
}

Status run_extrinsics(const std::string& session_dir, const std::string& camera_path, double max_error_px,
                      bool exclude_unposed) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  pipeline::GeometryCalibrationOptions opt;
  opt.max_error_px = max_error_px;
  opt.exclude_unposed = exclude_unposed;
  if (!camera_path.empty()) {
    auto cam = CameraModel::load_yaml(camera_path);
    if (!cam) return cam.error();
    opt.camera = cam.value();
  }
  auto cal = pipeline::calibrate_session_geometry(session.value(), opt);
  if (!cal) return cal.error();
  std::printf("view  pan_deg  tilt_deg  error_px  status\n");
  for (const auto& v : cal->views.views) {
    std::printf("%4d  %7.2f  %8.2f  ", v.index, rad_to_deg(v.measured.pan_rad), rad_to_deg(v.measured.tilt_rad));
    if (v.extrinsics)
      std::printf("%8.4f  %s\n", v.extrinsics->reprojection_error_px, v.extrinsics->excluded ? "EXCLUDED" : "ok");
    else
      std::printf("%8s  %s\n", "-", v.error.c_str());
  }
  std::printf("%d of %zu views usable (max error %.3f px); the others are %s\n", cal->usable_views,
              cal->views.views.size(), max_error_px,
              exclude_unposed ? "left out of the observation map" : "posed by the kinematic fit");
  if (cal->kinematics) {
    const auto& k = *cal->kinematics;
    const rig::model::Params p = rig::model::to_params(k.geometry);
    // name, unit, factor from the model's units (mm, rad) to the printed ones
    const struct {
      const char* name;
      const char* unit;
      double scale;
    } rows[rig::model::kParamCount] = {{"camera distance", "mm", 1.0},
                                       {"surface offset x", "mm", 1.0},
                                       {"surface offset y", "mm", 1.0},
                                       {"surface offset z", "mm", 1.0},
                                       {"pan zero", "deg", rad_to_deg(1.0)},
                                       {"tilt zero", "deg", rad_to_deg(1.0)},
                                       {"pan axis tilt x", "deg", rad_to_deg(1.0)},
                                       {"pan axis tilt y", "deg", rad_to_deg(1.0)}};
    std::printf("rig kinematics (fitted +- standard deviation%s):\n",
                k.sigma ? "" : "; the covariance could not be computed");
    for (int i = 0; i < rig::model::kParamCount; ++i) {
      std::printf("  %-17s %11.4f", rows[i].name, p[i] * rows[i].scale);
      if (k.sigma) std::printf(" +- %.4f", (*k.sigma)[i] * rows[i].scale);
      std::printf(" %s\n", rows[i].unit);
    }
    std::printf(
        "departure of the measured poses from the model: rms %.3f mm, %.4f deg (max %.4f deg); noise estimated "
        "%.4f / %.4f deg (rotation across / about the optical axis), %.3f / %.3f mm (translation across / along)\n",
        k.rms_translation_mm, k.rms_rotation_deg, k.max_rotation_deg, k.noise_rotation_xy_deg, k.noise_rotation_z_deg,
        k.noise_translation_xy_mm, k.noise_translation_z_mm);
    if (!k.downweighted_views.empty()) {
      std::printf("views weighed less (residuals beyond the noise, chi-square > 16):");
      for (int v : k.downweighted_views) std::printf(" %d", v);
      std::printf("\n");
    }
  }
  std::printf("wrote %s and %s\n", session->layout().camera_file().c_str(), session->layout().views_file().c_str());
  return Status::ok();
}

Status run_session_hdr(const std::string& session_dir, const pipeline::HdrMergeOptions& options) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  std::printf("HDR merge of %s -> %s\n", session->dir().c_str(), session->layout().hdr_dir().c_str());
  pipeline::HdrMergeOptions with_progress = options;
  ProgressLine progress;
  with_progress.on_view = [&progress](int done, int total) {
    progress.update(done, total, "  views %d/%d", done, total);
  };
  auto summary = pipeline::merge_session_hdr(session.value(), with_progress);
  progress.finish();
  if (!summary) return summary.error();
  // What this run did: a second run over a merged session merges nothing and says so.
  std::printf("merged %d views, %d already current", summary->merged, summary->current);
  if (summary->incomplete > 0) std::printf(", %d incomplete skipped", summary->incomplete);
  std::printf(" -> %s\n", session->layout().hdr_dir().c_str());
  return Status::ok();
}

const CommandRegistrar registrar([](CLI::App& root) {
  auto* calib = root.add_subcommand("calib", "camera calibration: intrinsics from a chessboard, response curve");
  calib->require_subcommand(1);

  {
    auto* cmd = calib->add_subcommand(
        "intrinsics", "intrinsics (Brown-Conrady) from chessboard photographs or a session of a chessboard");
    struct Args {
      std::string board = "9x6", out = "camera.yml", session;
      double square_m = 0.025;
      std::vector<std::string> images;
      calib::IntrinsicsOptions opt;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("--board", a->board, "inner corners COLSxROWS")->capture_default_str();
    cmd->add_option("--square", a->square_m, "square size, metres")->capture_default_str();
    cmd->add_option("--out", a->out, "OpenCV YAML to write")->capture_default_str();
    cmd->add_flag("--fix-aspect", a->opt.fix_aspect_ratio, "hold fx = fy (CALIB_FIX_ASPECT_RATIO)");
    cmd->add_flag("--fix-k3", a->opt.fix_k3, "hold k3 = 0 (CALIB_FIX_K3; few views, or small distortion)");
    cmd->add_flag("--drop-outliers", a->opt.drop_outliers, "calibrate again without outlier views");
    cmd->add_option("--outlier-factor", a->opt.outlier_factor, "outlier if view RMS > factor x median")
        ->capture_default_str();
    cmd->add_option("--subpix-half-window", a->opt.subpix_half_window,
                    "cornerSubPix half window, px (OpenCV's samples use 11)")
        ->capture_default_str();
    auto* images = cmd->add_option("images", a->images, "chessboard images");
    cmd->add_option("--session", a->session,
                    "a session of a chessboard (e.g. the built-in scene chessboard: --board 8x6 --square 0.16): "
                    "per view, the longest exposure with at most 0.5% saturated pixels")
        ->excludes(images);
    cmd->callback([a] {
      if (!a->session.empty())
        finish(run_session_intrinsics(a->session, a->board, a->square_m, a->out, a->opt));
      else if (a->images.empty())
        finish(usage("calib intrinsics wants chessboard images or --session SESSION"));
      else
        finish(run_intrinsics(a->board, a->square_m, a->images, a->out, a->opt));
    });
  }
  {
    auto* cmd = calib->add_subcommand(
        "response", "response curve (Debevec-Malik) from a bracket of a static scene, or from a session's brackets");
    struct Args {
      std::vector<std::string> bracket;
      std::string out = "response.json", session;
      pipeline::ResponseCalibrationOptions session_options;
    };
    auto a = std::make_shared<Args>();
    auto* session =
        cmd->add_option("session", a->session,
                        "session folder: recover the curve from one view's bracket -> SESSION/calib/response.json");
    cmd->add_option("--bracket", a->bracket, "IMAGE:EXPOSURE_S items (seconds, e.g. a.png:1/250)")->excludes(session);
    cmd->add_option("--out", a->out, "response JSON to write (with --bracket)")->capture_default_str();
    cmd->add_option("--view", a->session_options.view,
                    "with SESSION: the view whose bracket is used (default: of 16 views spread over the session, the "
                    "one covering the most codes)");
    cmd->add_option("--lambda", a->session_options.recovery.lambda, "smoothness weight")->capture_default_str();
    cmd->add_option("--samples", a->session_options.recovery.samples, "pixels per channel (0: automatic)")
        ->capture_default_str();
    cmd->callback([a] {
      if (!a->session.empty())
        finish(run_session_response(a->session, a->session_options));
      else if (a->bracket.empty())
        finish(usage("calib response wants SESSION or --bracket IMAGE:EXPOSURE_S ..."));
      else
        finish(run_response(a->bracket, a->out, a->session_options.recovery));
    });
  }

  {
    auto* cmd = calib->add_subcommand(
        "extrinsics", "per-view poses from the corner markers + rig kinematic fit -> SESSION/calib/views.json");
    struct Args {
      std::string session, camera;
      double max_error_px = 1.0;
      bool exclude_unposed = false;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("session", a->session, "session folder")->required();
    cmd->add_option("--camera", a->camera,
                    "camera model YAML (vdrig calib intrinsics); default SESSION/calib/camera.yml");
    cmd->add_option("--max-error-px", a->max_error_px, "exclude views with a larger RMS reprojection error")
        ->capture_default_str();
    cmd->add_flag("--exclude-unposed", a->exclude_unposed,
                  "leave views without a usable marker pose out of the observation map (default: pose them by the "
                  "kinematic fit)");
    cmd->callback([a] { finish(run_extrinsics(a->session, a->camera, a->max_error_px, a->exclude_unposed)); });
  }

  // `vdrig hdr SESSION` merges a session (resumable: merged views are kept); `vdrig hdr merge ...` merges files.
  auto* hdr = root.add_subcommand("hdr", "high dynamic range merging: `hdr SESSION` or `hdr merge IMAGE:T ...`");
  hdr->require_subcommand(0, 1);
  auto hdr_session = std::make_shared<std::string>();
  auto hdr_options = std::make_shared<pipeline::HdrMergeOptions>();
  hdr->add_option("session", *hdr_session, "session folder: merge every complete view into SESSION/hdr/");
  hdr->add_flag("--force", hdr_options->force,
                "merge every view again (views whose HDR image is damaged are merged again anyway)");
  hdr->callback([hdr, hdr_session, hdr_options] {
    if (!hdr->get_subcommands().empty()) return;
    if (hdr_session->empty()) finish(usage("hdr wants SESSION or the merge subcommand (see --help)"));
    finish(run_session_hdr(*hdr_session, *hdr_options));
  });
  {
    auto* cmd = hdr->add_subcommand("merge", "merge a bracket to relative radiance (OpenEXR: R, G, B, mask)");
    struct Args {
      std::string response, out = "out.exr";
      int bits = 0;
      bool full_float = false;
      std::vector<std::string> items;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("--response", a->response, "response JSON (vdrig calib response); none: linear raw camera");
    cmd->add_option("--bits", a->bits, "significant bits of a linear camera's codes (default: 8 or 16)");
    cmd->add_option("--out", a->out, "OpenEXR to write")->capture_default_str();
    cmd->add_flag("--float", a->full_float, "32-bit float channels (default half)");
    cmd->add_option("items", a->items, "IMAGE:EXPOSURE_S items")->required();
    cmd->callback([a] { finish(run_merge(a->response, a->bits, a->items, a->out, !a->full_float)); });
  }
});

}  // namespace
}  // namespace vdrig::app
