#include "vdrig/pipeline/geometry_stage.hpp"

#include <algorithm>
#include <opencv2/core.hpp>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/pipeline/hdr_stage.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

namespace {

/// The pan/tilt a view was taken at: measured by the stage, or the planned target for a view without frames.
PanTilt measured_pan_tilt(const capture::Session& session, const capture::PlannedView& view) {
  const auto frames = session.frames_of_view(view.index);
  return frames.empty() ? view.target : frames.front().measured;
}

}  // namespace

Result<SessionGeometry> session_geometry(const capture::Session& session) {
  const capture::SessionLayout layout = session.layout();
  if (!fs::exists(layout.views_file()) || !fs::exists(layout.camera_file()))
    return make_error(ErrorCode::kNotFound,
                      "session " + session.dir().string() +
                          " has no calibrated geometry (calib/views.json and calib/camera.yml): run `vdrig calib "
                          "extrinsics " +
                          session.dir().string() + " --camera CAMERA.yml` (CAMERA.yml from `vdrig calib intrinsics`)");
  auto views = calib::read_views_json(layout.views_file());
  if (!views) return views.error();
  auto camera = CameraModel::load_yaml(layout.calib_dir() / views->camera_file);
  if (!camera) return camera.error();
  std::optional<rig::RigGeometry> kinematics;
  if (!views->kinematics.is_null()) {
    auto g = calib::KinematicFit::geometry_from_json(views->kinematics);
    if (!g) return g.error();
    kinematics = g.value();
  }
  SessionGeometry g;
  g.camera = camera.value();
  for (const auto& view : session.manifest().views) {
    const auto it = std::find_if(views->views.begin(), views->views.end(),
                                 [&](const calib::ViewRecord& r) { return r.index == view.index; });
    if (it != views->views.end() && it->usable()) {
      g.poses.push_back(it->extrinsics->pose);
      g.kinematic_pose.push_back(false);
      g.excluded.push_back(false);
      continue;
    }
    if (!kinematics)
      return make_error(ErrorCode::kNotFound, "view " + std::to_string(view.index) +
                                                  " has no calibrated pose and views.json has no kinematic fit to "
                                                  "pose it by");
    g.poses.push_back(rig::surface_pose(*kinematics, measured_pan_tilt(session, view)));
    g.kinematic_pose.push_back(true);
    g.excluded.push_back(views->exclude_unposed);
  }
  return g;
}

Result<GeometryCalibration> calibrate_session_geometry(const capture::Session& session,
                                                       const GeometryCalibrationOptions& options) {
  auto logger = log::get("calib");
  const capture::SessionLayout files = session.layout();
  const auto& rc = session.manifest().rig_config;
  GeometryCalibration out;
  bool camera_from_session = false;  // calib/camera.yml is kept as is (it may hold the intrinsics' record)
  if (options.camera) {
    out.camera = *options.camera;
  } else if (fs::exists(files.camera_file())) {
    auto c = CameraModel::load_yaml(files.camera_file());
    if (!c) return c.error();
    out.camera = c.value();
    camera_from_session = true;
  } else {
    return make_error(ErrorCode::kNotFound,
                      "no camera model: pass one (--camera CAMERA.yml, from `vdrig calib intrinsics`) or write " +
                          files.camera_file().string());
  }
  std::string why;
  if (!out.camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "camera model: " + why);

  const calib::MarkerLayout layout =
      options.layout
          ? *options.layout
          : calib::MarkerLayout::corners(session.manifest().surface_width_mm, session.manifest().surface_height_mm);
  if (!layout.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "marker layout: " + why);

  // The nominal rig, the views' first guess: the geometry the session was planned with (its config's "geometry", or
  // the ideal rig at the configured distance; never the simulator's hidden truth), which the calibration measures.
  auto nominal_or = capture::geometry_from_rig_config(rc);
  if (!nominal_or) return nominal_or.error();
  const rig::RigGeometry nominal = nominal_or.value();

  VDRIG_TRY(merge_session_hdr(session));
  calib::ExtrinsicsOptions ext;
  ext.max_error_px = options.max_error_px;
  out.views.layout = layout;
  out.views.camera_file = files.camera_file().filename().string();  // relative to calib/, as views.json records it
  out.views.max_error_px = options.max_error_px;
  out.views.exclude_unposed = options.exclude_unposed;
  std::vector<calib::KinematicObservation> observations;
  for (const auto& view : session.manifest().views) {
    calib::ViewRecord rec;
    rec.index = view.index;
    rec.measured = measured_pan_tilt(session, view);
    if (!session.view_complete(view.index)) {
      rec.error = "view not captured";
    } else {
      auto hdr = calib::read_hdr_exr(files.hdr_file(view.index));
      auto v = hdr ? calib::calibrate_view(hdr->radiance, out.camera, rig::surface_pose(nominal, rec.measured), layout,
                                           {}, ext)
                   : Result<calib::ViewExtrinsics>(hdr.error());
      if (v) {
        rec.extrinsics = v.value();
      } else {
        rec.error = v.error().describe();
      }
    }
    if (rec.usable()) {
      observations.push_back({rec.index, rec.measured, rec.extrinsics->pose});
      ++out.usable_views;
    } else {
      logger->warn("view {}: {}", rec.index,
                   rec.extrinsics
                       ? "excluded, reprojection error " + std::to_string(rec.extrinsics->reprojection_error_px) + " px"
                       : rec.error);
    }
    out.views.views.push_back(std::move(rec));
  }
  if (out.usable_views == 0) return make_error(ErrorCode::kNotFound, "no view gave a usable marker pose");
  if (options.fit_kinematics && observations.size() >= 2) {
    auto fit = calib::fit_rig_geometry(observations);
    if (fit) {
      out.kinematics = fit.value();
      out.views.kinematics = fit->to_json();
    } else {
      logger->warn("kinematic fit: {}", fit.error().describe());
    }
  }
  std::error_code ec;
  fs::create_directories(files.calib_dir(), ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + files.calib_dir().string() + ": " + ec.message());
  if (!camera_from_session) VDRIG_TRY(out.camera.save_yaml(files.camera_file()));
  VDRIG_TRY(calib::write_views_json(files.views_file(), out.views));
  logger->info("extrinsics: {} of {} views usable", out.usable_views, out.views.views.size());
  return out;
}

Result<calib::IntrinsicsResult> calibrate_session_intrinsics(const capture::Session& session,
                                                             const SessionIntrinsicsOptions& options) {
  auto logger = log::get("calib");
  std::vector<cv::Mat> images;
  for (const auto& view : session.manifest().views) {
    if (!session.view_complete(view.index)) continue;
    auto frames = session.frames_of_view(view.index);
    std::sort(frames.begin(), frames.end(), [](const capture::FrameRecord& a, const capture::FrameRecord& b) {
      return a.exposure_s * a.gain > b.exposure_s * b.gain;
    });
    cv::Mat chosen;
    for (const auto& rec : frames) {
      auto img = session.load_image(rec);
      if (!img) return img.error();
      cv::Mat grey;
      if (img->channels() == 1) {
        grey = img.value();
      } else {
        std::vector<cv::Mat> channels;
        cv::split(img.value(), channels);
        grey = channels[1];  // green: the channel closest to luminance, without mixing in a colour conversion
      }
      const double max_code = static_cast<double>((1 << rec.bits) - 1);
      const double saturated = cv::countNonZero(grey >= max_code) / static_cast<double>(grey.total());
      if (saturated <= options.max_saturated_fraction) {
        if (grey.depth() != CV_8U) grey.convertTo(grey, CV_8U, 255.0 / max_code);
        chosen = grey;
        break;
      }
    }
    if (chosen.empty()) {
      logger->warn("view {}: every exposure has more than {:.1f}% saturated pixels; skipped", view.index,
                   100 * options.max_saturated_fraction);
      continue;
    }
    images.push_back(chosen);
  }
  if (images.empty())
    return make_error(ErrorCode::kNotFound, "session " + session.dir().string() + " has no usable chessboard view");
  return calib::calibrate_intrinsics(images, options.board_cols, options.board_rows, options.square_m,
                                     options.intrinsics);
}

}  // namespace vdrig::pipeline
