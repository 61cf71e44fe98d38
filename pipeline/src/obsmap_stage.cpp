#include "vdrig/pipeline/obsmap_stage.hpp"

#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

namespace {

/// The view input of session view `view`: its HDR image (radiance and clip mask) with the session's geometry.
Result<fitting::ViewInput> session_view_input(const capture::Session& session, const SessionGeometry& geometry,
                                              int view) {
  auto hdr = calib::read_hdr_exr(session.layout().hdr_file(view));
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
  const capture::SessionLayout layout = session.layout();
  const fs::path path = layout.obsmap_file(S, T);
  const int views = static_cast<int>(session.manifest().views.size());
  std::error_code ec;
  auto current = [&]() -> bool {
    const auto built = fs::last_write_time(path, ec);
    if (ec) return false;
    auto reader = fitting::ObsMapReader::open(path);
    if (!reader || reader->views() != views || reader->spec().texels_s != S || reader->spec().texels_t != T)
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
