#include "vdrig/pipeline/obsmap_stage.hpp"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

namespace {

/// Masks the pixels of `hdr` with a NaN or infinite channel, and their 8 neighbours (bilinear sampling reaches
/// them): radiance set to 0 and the mask marked as clipped both ways, so no texel samples them. Returns how many
/// pixels were non-finite.
int mask_non_finite(calib::HdrImage& hdr) {
  cv::Mat bad(hdr.radiance.size(), CV_8UC1, cv::Scalar::all(0));
  int count = 0;
  for (int y = 0; y < hdr.radiance.rows; ++y)
    for (int x = 0; x < hdr.radiance.cols; ++x) {
      const cv::Vec3f& p = hdr.radiance.at<cv::Vec3f>(y, x);
      if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) continue;
      bad.at<uint8_t>(y, x) = 1;
      ++count;
    }
  if (count == 0) return 0;
  cv::dilate(bad, bad, cv::Mat::ones(3, 3, CV_8UC1));
  if (hdr.mask.empty()) hdr.mask = cv::Mat(hdr.radiance.size(), CV_8UC1, cv::Scalar::all(0));
  hdr.radiance.setTo(cv::Scalar::all(0), bad);
  hdr.mask.setTo(cv::Scalar::all(calib::kHdrSaturated | calib::kHdrBlack), bad);
  return count;
}

/// The view input of session view `view`: its HDR image (radiance and clip mask) with the session's geometry. An
/// image of another size than the camera's is refused (kCorrupt); non-finite pixels are masked (mask_non_finite) and
/// added to `*non_finite`.
Result<fitting::ViewInput> session_view_input(const capture::Session& session, const SessionGeometry& geometry,
                                              int view, long long* non_finite) {
  const fs::path file = session.layout().hdr_file(view);
  auto hdr = calib::read_hdr_exr(file);
  if (!hdr)
    return make_error(hdr.error().code, "view " + std::to_string(view) + ": " + hdr.error().message +
                                            " (merge the brackets first: vdrig hdr SESSION)");
  const CameraModel& camera = geometry.camera;
  if (hdr->radiance.cols != camera.width || hdr->radiance.rows != camera.height ||
      (!hdr->mask.empty() && hdr->mask.size() != hdr->radiance.size()))
    return make_error(ErrorCode::kCorrupt, "view " + std::to_string(view) + ": " + file.string() + " is " +
                                               std::to_string(hdr->radiance.cols) + "x" +
                                               std::to_string(hdr->radiance.rows) + ", the camera " +
                                               std::to_string(camera.width) + "x" + std::to_string(camera.height) +
                                               " (merge it again: vdrig hdr --force SESSION)");
  if (const int bad = mask_non_finite(hdr.value()); bad > 0) {
    log::get("fitting")->warn("view {}: {} non-finite (NaN/Inf) pixels in {} masked", view, bad, file.string());
    *non_finite += bad;
  }
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
  long long non_finite = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    auto input = session_view_input(session, geometry.value(), views[i], &non_finite);
    if (!input) return input.error();
    fitting::add_view(map, static_cast<int>(i), input.value());
  }
  log::get("fitting")->info("observation map {}x{} from {} views ({}); {} non-finite pixels masked", S, T, views.size(),
                            geometry->source, non_finite);
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
  // A file of the session (obsmap/) is never reached through a link planted in the session.
  if (const fs::path inside = path.lexically_relative(session.dir()); !inside.empty() && *inside.begin() != "..")
    VDRIG_TRY(check_no_symlinks_below(session.dir(), path));
  std::error_code ec;
  if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
  auto writer = fitting::ObsMapWriter::create(path, spec, static_cast<int>(views.size()), options.file);
  if (!writer) return writer.error();
  long long non_finite = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    auto input = session_view_input(session, geometry.value(), views[i], &non_finite);
    if (!input) return input.error();
    VDRIG_TRY(writer->add_view(static_cast<int>(i), input.value()));
    if (options.on_view) options.on_view(static_cast<int>(i) + 1, static_cast<int>(views.size()));
  }
  VDRIG_TRY(writer->finish());
  if (non_finite > 0)
    log::get("fitting")->warn("observation map {}: {} non-finite HDR pixels masked in all", path.string(), non_finite);
  log::get("fitting")->debug("observation map {}x{} from {} views ({}) -> {}", S, T, views.size(), geometry->source,
                             path.string());
  return Status::ok();
}

Result<fs::path> session_obsmap_file(const capture::Session& session, int S, int T,
                                     const ObsMapBuildOptions& options_in) {
  ObsMapBuildOptions options = options_in;
  options.views.clear();  // the cached file always holds every view, in manifest order
  const capture::SessionLayout layout = session.layout();
  const fs::path path = layout.obsmap_file(S, T);
  const int views = static_cast<int>(session.manifest().views.size());
  std::error_code ec;
  auto current = [&]() -> bool {
    const auto built = fs::last_write_time(path, ec);
    if (ec) return false;
    auto reader = fitting::ObsMapReader::open(path);
    // An older format's map was sampled by older rules (version 2 flags grazing samples kObsCoarse): rebuilt.
    if (!reader || reader->header().version < fitting::kObsFileVersion || reader->views() != views ||
        reader->spec().texels_s != S || reader->spec().texels_t != T)
      return false;
    for (const auto& v : session.manifest().views) {
      const auto t = fs::last_write_time(layout.hdr_file(v.index), ec);
      if (ec || t > built) return false;
    }
    for (const fs::path& calibration : {layout.camera_file(), layout.views_file()}) {
      const auto t = fs::last_write_time(calibration, ec);
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

}  // namespace vdrig::pipeline
