#include "vdrig/pipeline/geometry_stage.hpp"

#include <algorithm>

#include "ground_truth.hpp"
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

/// Calibrated geometry from SESSION/calib/, or nullopt when the session has none.
std::optional<Result<SessionGeometry>> calibrated_geometry(const capture::Session& session) {
  const capture::SessionLayout layout = session.layout();
  if (!fs::exists(layout.views_file()) || !fs::exists(layout.camera_file())) return std::nullopt;
  auto views = calib::read_views_json(layout.views_file());
  if (!views) return Result<SessionGeometry>(views.error());
  auto camera = CameraModel::load_yaml(layout.calib_dir() / views->camera_file);
  if (!camera) return Result<SessionGeometry>(camera.error());
  std::optional<rig::RigGeometry> kinematics;
  if (!views->kinematics.is_null()) {
    auto g = calib::KinematicFit::geometry_from_json(views->kinematics);
    if (!g) return Result<SessionGeometry>(g.error());
    kinematics = g.value();
  }
  SessionGeometry g;
  g.camera = camera.value();
  g.source = "calibrated";
  for (const auto& view : session.manifest().views) {
    const auto it = std::find_if(views->views.begin(), views->views.end(),
                                 [&](const calib::ViewRecord& r) { return r.index == view.index; });
    if (it != views->views.end() && it->usable()) {
      g.poses.push_back(it->extrinsics->pose);
      g.excluded.push_back(false);
      continue;
    }
    if (!kinematics)
      return Result<SessionGeometry>(make_error(
          ErrorCode::kNotFound, "view " + std::to_string(view.index) +
                                    " has no calibrated pose and views.json has no kinematic fit to pose it by"));
    g.poses.push_back(rig::surface_pose(*kinematics, measured_pan_tilt(session, view)));
    g.excluded.push_back(true);
  }
  return Result<SessionGeometry>(std::move(g));
}

}  // namespace

Result<SessionGeometry> session_geometry(const capture::Session& session) {
  if (auto calibrated = calibrated_geometry(session)) return std::move(*calibrated);
  auto truth = ground_truth_of(session.manifest().rig_config);
  if (!truth) return truth.error();
  if (!*truth)
    return make_error(ErrorCode::kNotFound, "session has no calibrated geometry (calib/) and is not simulated");
  SessionGeometry g;
  g.camera = (*truth)->camera;
  g.source = "simulator ground truth";
  for (const auto& view : session.manifest().views) {
    g.poses.push_back((*truth)->pose_at(measured_pan_tilt(session, view)));
    g.excluded.push_back(false);
  }
  return g;
}

Result<GeometryCalibration> calibrate_session_geometry(const capture::Session& session,
                                                       const GeometryCalibrationOptions& options) {
  auto logger = log::get("calib");
  const capture::SessionLayout files = session.layout();
  const auto& rc = session.manifest().rig_config;
  auto truth_or = ground_truth_of(rc);
  if (!truth_or) return truth_or.error();
  const std::optional<GroundTruth>& truth = truth_or.value();
  GeometryCalibration out;
  bool camera_from_session = false;  // calib/camera.yml is kept as is (it may hold the intrinsics' record)
  if (options.camera) {
    out.camera = *options.camera;
  } else if (fs::exists(files.camera_file())) {
    auto c = CameraModel::load_yaml(files.camera_file());
    if (!c) return c.error();
    out.camera = c.value();
    camera_from_session = true;
  } else if (truth) {
    logger->warn("no camera model given: using the simulator's camera (ground-truth intrinsics)");
    out.camera = truth->camera;
  } else {
    return make_error(ErrorCode::kNotFound,
                      "no camera model: pass one (vdrig calib intrinsics) or write " + files.camera_file().string());
  }
  std::string why;
  if (!out.camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "camera model: " + why);

  calib::MarkerLayout layout;
  if (options.layout) {
    layout = *options.layout;
  } else if (truth) {
    layout = truth->markers;
  } else {
    layout = calib::MarkerLayout::corners(session.manifest().surface_width_mm, session.manifest().surface_height_mm);
  }
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

}  // namespace vdrig::pipeline
