#include "vdrig/pipeline/pipeline.hpp"

#include <atomic>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

rig::BackendRegistry full_registry() {
  rig::BackendRegistry registry;
  sim::register_backends(registry);
  rig::register_hardware_backends(registry);
  return registry;
}

Result<capture::Session> capture_session(const CaptureRequest& req) {
  auto logger = log::get("capture");
  auto rig = full_registry().make_rig(req.rig_config);
  if (!rig) return rig.error();
  auto samples = capture::generate(req.scheme);
  if (!samples) return samples.error();
  // The stage's geometry: the simulator knows it; a hardware rig config states it ("geometry": {"distance_mm"}).
  rig::RigGeometry geometry;
  if (req.rig_config.contains("sim")) {
    auto sc = sim::SimConfig::from_json(req.rig_config["sim"]);
    if (!sc) return sc.error();
    geometry = sc->geometry;
  }
  const auto plan = capture::plan_targets(geometry, rig->stage->spec(), samples->directions);
  for (const auto& u : plan.unreachable) {
    const SphericalDir s = spherical_from_direction(u.direction);
    logger->warn("direction {} (azimuth {:.1f} deg, zenith {:.1f} deg) is unreachable within the axis limits", u.index,
                 rad_to_deg(s.azimuth_rad), rad_to_deg(s.zenith_rad));
  }
  capture::Manifest manifest;
  manifest.rig_config = req.rig_config;
  manifest.scheme = req.scheme;
  std::string bracket = "fixed:";
  for (size_t i = 0; i < req.exposures_s.size(); ++i) bracket += (i ? "," : "") + std::to_string(req.exposures_s[i]);
  manifest.bracket = bracket;
  manifest.exposures_s = req.exposures_s;
  for (const auto& t : plan.reachable)
    manifest.views.push_back({static_cast<int>(manifest.views.size()), t.direction, t.pan_tilt});
  if (req.rig_config.contains("sim")) {
    auto scene = sim::make_scene(req.rig_config["sim"].value("scene", "patchwork"));
    if (!scene) return scene.error();
    manifest.surface_width_mm = scene->width_mm;
    manifest.surface_height_mm = scene->height_mm;
  }
  auto session = capture::Session::create(req.out_dir, manifest);
  if (!session) return session.error();
  VDRIG_TRY(rig->stage->home());
  capture::CaptureOptions options;
  options.exposures_s = req.exposures_s;
  options.on_progress = [&](const capture::CaptureProgress& p) {
    if (req.on_view) req.on_view(p.views_done, p.views_total);
  };
  VDRIG_TRY(capture::run_capture(rig.value(), session.value(), options));
  return session;
}

namespace {

Result<ResponseCurve> session_response(const capture::Session& session) {
  const fs::path calibrated = session.dir() / "calib" / "response.json";
  if (fs::exists(calibrated)) {
    std::ifstream in(calibrated);
    auto j = nlohmann::json::parse(in, nullptr, false);
    if (j.is_discarded()) return make_error(ErrorCode::kCorrupt, calibrated.string() + ": not valid JSON");
    return ResponseCurve::from_json(j);
  }
  const auto& rc = session.manifest().rig_config;
  if (!rc.contains("sim"))
    return make_error(ErrorCode::kNotFound, "no response curve: run radiometric calibration (calib/response.json)");
  auto sc = sim::SimConfig::from_json(rc["sim"]);
  if (!sc) return sc.error();
  return sc->sensor.response;
}

fs::path hdr_path(const capture::Session& session, int view) {
  char name[32];
  std::snprintf(name, sizeof name, "view_%04d.exr", view);
  return session.dir() / "hdr" / name;
}

}  // namespace

Status merge_session_hdr(const capture::Session& session) {
  auto response = session_response(session);
  if (!response) return response.error();
  std::error_code ec;
  fs::create_directories(session.dir() / "hdr", ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create hdr/: " + ec.message());
  const auto& views = session.manifest().views;
  std::atomic<size_t> next{0};
  std::mutex error_mutex;
  Status first_error;
  auto worker = [&] {
    for (size_t i = next++; i < views.size(); i = next++) {
      const int v = views[i].index;
      if (!session.view_complete(v) || fs::exists(hdr_path(session, v))) continue;
      std::vector<Frame> frames;
      Status status;
      for (const auto& rec : session.frames_of_view(v)) {
        auto img = session.load_image(rec);
        if (!img) {
          status = img.error();
          break;
        }
        Frame f;
        f.image = img.value();
        f.exposure_s = rec.exposure_s;
        f.gain = rec.gain;
        f.bits = rec.bits;
        frames.push_back(std::move(f));
      }
      // The merge wants a monotonic bracket: sort by effective exposure.
      std::sort(frames.begin(), frames.end(),
                [](const Frame& a, const Frame& b) { return a.exposure_s * a.gain < b.exposure_s * b.gain; });
      if (status) {
        auto hdr = calib::merge_hdr(frames, response.value());
        status = hdr ? calib::write_hdr_exr(hdr_path(session, v), hdr.value(), ExrPixelType::kFloat) : hdr.status();
      }
      if (!status) {
        std::lock_guard lock(error_mutex);
        if (first_error)
          first_error = make_error(status.error().code, "view " + std::to_string(v) + ": " + status.error().message);
      }
    }
  };
  std::vector<std::thread> pool;
  for (unsigned k = 0; k < std::max(1u, std::thread::hardware_concurrency()); ++k) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  return first_error;
}

namespace {

/// Calibrated geometry from SESSION/calib/, or nullopt when the session has none.
std::optional<Result<SessionGeometry>> calibrated_geometry(const capture::Session& session) {
  const fs::path dir = session.dir() / "calib";
  if (!fs::exists(dir / "views.json") || !fs::exists(dir / "camera.yml")) return std::nullopt;
  auto views = calib::read_views_json(dir / "views.json");
  if (!views) return Result<SessionGeometry>(views.error());
  auto camera = CameraModel::load_yaml(dir / views->camera_file);
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
    const auto frames = session.frames_of_view(view.index);
    const PanTilt measured = frames.empty() ? view.target : frames.front().measured;
    g.poses.push_back(rig::surface_pose(*kinematics, measured));
    g.excluded.push_back(true);
  }
  return Result<SessionGeometry>(std::move(g));
}

}  // namespace

Result<SessionGeometry> session_geometry(const capture::Session& session) {
  if (auto calibrated = calibrated_geometry(session)) return std::move(*calibrated);
  const auto& rc = session.manifest().rig_config;
  if (!rc.contains("sim"))
    return make_error(ErrorCode::kNotFound, "session has no calibrated geometry (calib/) and is not simulated");
  auto sc = sim::SimConfig::from_json(rc["sim"]);
  if (!sc) return sc.error();
  SessionGeometry g;
  g.camera = sc->camera;
  g.source = "simulator ground truth";
  for (const auto& view : session.manifest().views) {
    const auto frames = session.frames_of_view(view.index);
    const PanTilt measured = frames.empty() ? view.target : frames.front().measured;
    g.poses.push_back(rig::surface_pose(sc->geometry, measured));
    g.excluded.push_back(false);
  }
  return g;
}

Result<GeometryCalibration> calibrate_session_geometry(const capture::Session& session,
                                                       const GeometryCalibrationOptions& options) {
  auto logger = log::get("calib");
  const fs::path dir = session.dir() / "calib";
  const auto& rc = session.manifest().rig_config;
  std::optional<sim::SimConfig> sim_config;
  if (rc.contains("sim")) {
    auto sc = sim::SimConfig::from_json(rc["sim"]);
    if (!sc) return sc.error();
    sim_config = sc.value();
  }
  GeometryCalibration out;
  bool camera_from_session = false;  // calib/camera.yml is kept as is (it may hold the intrinsics' record)
  if (options.camera) {
    out.camera = *options.camera;
  } else if (fs::exists(dir / "camera.yml")) {
    auto c = CameraModel::load_yaml(dir / "camera.yml");
    if (!c) return c.error();
    out.camera = c.value();
    camera_from_session = true;
  } else if (sim_config) {
    logger->warn("no camera model given: using the simulator's camera (ground-truth intrinsics)");
    out.camera = sim_config->camera;
  } else {
    return make_error(ErrorCode::kNotFound,
                      "no camera model: pass one (vdrig calib intrinsics) or write calib/camera.yml");
  }
  std::string why;
  if (!out.camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "camera model: " + why);

  calib::MarkerLayout layout;
  if (options.layout) {
    layout = *options.layout;
  } else if (sim_config) {
    auto scene = sim::make_scene(sim_config->scene);
    if (!scene) return scene.error();
    layout.centres_mm = scene->marker_centres_mm();
    if (!scene->markers.empty()) layout.radius_mm = scene->markers.front().radius_mm;
  } else {
    layout = calib::MarkerLayout::corners(session.manifest().surface_width_mm, session.manifest().surface_height_mm);
  }
  if (!layout.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "marker layout: " + why);

  // The nominal rig: the configured camera distance, no surface offset (what the calibration measures).
  rig::RigGeometry nominal;
  if (sim_config) nominal.camera_distance_mm = sim_config->geometry.camera_distance_mm;
  if (rc.contains("geometry") && rc["geometry"].contains("distance_mm"))
    nominal.camera_distance_mm = rc["geometry"]["distance_mm"].get<double>();

  VDRIG_TRY(merge_session_hdr(session));
  calib::ExtrinsicsOptions ext;
  ext.max_error_px = options.max_error_px;
  out.views.layout = layout;
  out.views.max_error_px = options.max_error_px;
  std::vector<calib::KinematicObservation> observations;
  for (const auto& view : session.manifest().views) {
    calib::ViewRecord rec;
    rec.index = view.index;
    const auto frames = session.frames_of_view(view.index);
    rec.measured = frames.empty() ? view.target : frames.front().measured;
    if (!session.view_complete(view.index)) {
      rec.error = "view not captured";
    } else {
      auto hdr = calib::read_hdr_exr(hdr_path(session, view.index));
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
  fs::create_directories(dir, ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create calib/: " + ec.message());
  if (!camera_from_session) VDRIG_TRY(out.camera.save_yaml(dir / "camera.yml"));
  VDRIG_TRY(calib::write_views_json(dir / "views.json", out.views));
  logger->info("extrinsics: {} of {} views usable", out.usable_views, out.views.views.size());
  return out;
}

namespace {

/// The view input of session view `view`: its HDR image (radiance and clip mask) with the session's geometry.
Result<fitting::ViewInput> session_view_input(const capture::Session& session, const SessionGeometry& geometry,
                                              int view) {
  auto hdr = calib::read_hdr_exr(hdr_path(session, view));
  if (!hdr)
    return make_error(hdr.error().code, "view " + std::to_string(view) + ": " + hdr.error().message +
                                            " (merge the brackets first: vdrig hdr SESSION)");
  fitting::ViewInput input;
  input.radiance_bgr = hdr->radiance;
  input.clip_mask = hdr->mask;
  input.camera = geometry.camera;
  input.pose = geometry.poses.at(view);
  input.excluded = geometry.excluded.at(view);
  return input;
}

}  // namespace

Result<fitting::ObservationMap> build_session_obsmap(const capture::Session& session, int S, int T,
                                                     const std::vector<int>& views_in) {
  auto geometry = session_geometry(session);
  if (!geometry) return geometry.error();
  std::vector<int> views = views_in;
  if (views.empty())
    for (const auto& v : session.manifest().views) views.push_back(v.index);
  fitting::ObservationMapSpec spec{S, T, session.manifest().surface_width_mm, session.manifest().surface_height_mm};
  std::string why;
  if (!spec.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  fitting::ObservationMap map(spec, static_cast<int>(views.size()));
  for (size_t i = 0; i < views.size(); ++i) {
    auto input = session_view_input(session, geometry.value(), views[i]);
    if (!input) return input.error();
    fitting::add_view(map, static_cast<int>(i), input.value());
  }
  log::get("fitting")->info("observation map {}x{} from {} views ({})", S, T, views.size(), geometry->source);
  return map;
}

Status build_session_obsmap_file(const capture::Session& session, int S, int T, const fs::path& path,
                                 const ObsMapBuildOptions& options) {
  auto geometry = session_geometry(session);
  if (!geometry) return geometry.error();
  std::vector<int> views = options.views;
  if (views.empty())
    for (const auto& v : session.manifest().views) views.push_back(v.index);
  for (int v : views)
    if (v < 0 || v >= static_cast<int>(geometry->poses.size()))
      return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(v) + " is not in the session");
  fitting::ObservationMapSpec spec{S, T, session.manifest().surface_width_mm, session.manifest().surface_height_mm};
  std::string why;
  if (!spec.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  std::error_code ec;
  if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
  auto writer = fitting::ObsMapWriter::create(path, spec, static_cast<int>(views.size()), options.file);
  if (!writer) return writer.error();
  for (size_t i = 0; i < views.size(); ++i) {
    auto input = session_view_input(session, geometry.value(), views[i]);
    if (!input) return input.error();
    VDRIG_TRY(writer->add_view(static_cast<int>(i), input.value()));
    if (options.on_view) options.on_view(static_cast<int>(i) + 1, static_cast<int>(views.size()));
  }
  VDRIG_TRY(writer->finish());
  log::get("fitting")->debug("observation map {}x{} from {} views ({}) -> {}", S, T, views.size(), geometry->source,
                             path.string());
  return Status::ok();
}

Result<fs::path> session_obsmap_file(const capture::Session& session, int S, int T,
                                     const ObsMapBuildOptions& options_in) {
  ObsMapBuildOptions options = options_in;
  options.views.clear();  // the cached file always holds every view, in manifest order
  const fs::path path = session.dir() / "obsmap" / (std::to_string(S) + "x" + std::to_string(T) + ".vdobs");
  const int views = static_cast<int>(session.manifest().views.size());
  std::error_code ec;
  auto current = [&]() -> bool {
    const auto built = fs::last_write_time(path, ec);
    if (ec) return false;
    auto reader = fitting::ObsMapReader::open(path);
    if (!reader || reader->views() != views || reader->spec().texels_s != S || reader->spec().texels_t != T)
      return false;
    for (const auto& v : session.manifest().views) {
      const auto t = fs::last_write_time(hdr_path(session, v.index), ec);
      if (ec || t > built) return false;
    }
    for (const char* name : {"calib/camera.yml", "calib/views.json"}) {
      const auto t = fs::last_write_time(session.dir() / name, ec);
      if (!ec && t > built) return false;
    }
    ec.clear();
    return true;
  };
  if (current()) {
    log::get("fitting")->info("observation map {} is current, reused", path.string());
    return path;
  }
  VDRIG_TRY(build_session_obsmap_file(session, S, T, path, options));
  return path;
}

Result<Comparison> render_and_compare(const capture::Session& session, const fitting::ParameterMap& map, int view,
                                      const fs::path& out_dir, const cv::Mat& region) {
  auto geometry = session_geometry(session);
  if (!geometry) return geometry.error();
  const auto frames = session.frames_of_view(view);
  if (frames.empty()) return make_error(ErrorCode::kNotFound, "view " + std::to_string(view) + " has no frames");
  auto response = session_response(session);
  if (!response) return response.error();
  // Compare in the camera's own units with the middle exposure of the bracket (well exposed on most of the surface).
  const capture::FrameRecord& rec = frames[frames.size() / 2];
  auto photo = session.load_image(rec);
  if (!photo) return photo.error();

  auto ctx = viewer::GlContext::create(geometry->camera.width, geometry->camera.height, false);
  if (!ctx) return ctx.error();
  auto renderer = viewer::SurfaceRenderer::create(map);
  if (!renderer) return renderer.error();
  auto radiance = renderer.value()->render_radiance(geometry->camera, geometry->poses.at(view), {});
  if (!radiance) return radiance.error();
  const cv::Mat render = viewer::to_camera_codes(radiance.value(), rec.exposure_s, rec.gain, response.value());

  cv::Mat diff;
  cv::absdiff(render, photo.value(), diff);
  cv::Mat diff_f;
  diff.convertTo(diff_f, CV_32F);
  const cv::Mat mask = region.empty() ? cv::Mat(diff.size(), CV_8U, cv::Scalar(255)) : region;
  const cv::Scalar mean = cv::mean(diff_f, mask);
  Comparison c;
  c.mean_abs_error = (mean[0] + mean[1] + mean[2]) / 3.0;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  char stem[32];
  std::snprintf(stem, sizeof stem, "view_%04d", view);
  c.render_png = out_dir / (std::string(stem) + "_render.png");
  c.photo_png = out_dir / (std::string(stem) + "_photo.png");
  c.diff_png = out_dir / (std::string(stem) + "_diff_x8.png");
  cv::Mat diff_vis;
  diff.convertTo(diff_vis, CV_8U, 8.0);  // amplified 8x so small differences are visible
  VDRIG_TRY(write_png(c.render_png, render));
  VDRIG_TRY(write_png(c.photo_png, photo.value()));
  VDRIG_TRY(write_png(c.diff_png, diff_vis));
  return c;
}

}  // namespace vdrig::pipeline

namespace vdrig::pipeline {

cv::Mat surface_region_mask(const CameraModel& camera, const ViewPose& pose, double x0, double y0, double x1,
                            double y1) {
  cv::Mat mask(camera.height, camera.width, CV_8UC1, cv::Scalar(0));
  const Mat3d Rt = pose.R.transpose();
  const Vec3d c = pose.camera_centre();
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const Vec3d ray = Rt * camera.pixel_ray({double(x), double(y)});
      if (std::abs(ray.z()) < 1e-12) continue;
      const double s = -c.z() / ray.z();
      if (s <= 0) continue;
      const Vec3d p = c + s * ray;
      if (p.x() >= x0 && p.x() <= x1 && p.y() >= y0 && p.y() <= y1) mask.at<uint8_t>(y, x) = 255;
    }
  return mask;
}

}  // namespace vdrig::pipeline
