#include "session_data.hpp"

#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/pipeline/obsmap_stage.hpp"

namespace vdrig::app {

Result<SessionData> open_session_data(const std::string& dir) {
  auto session = capture::Session::open(dir);
  if (!session) return session.error();
  auto geometry = pipeline::session_geometry(session.value());
  if (!geometry) return geometry.error();
  int kinematic = 0, excluded = 0;
  for (const bool k : geometry->kinematic_pose) kinematic += k ? 1 : 0;
  for (const bool e : geometry->excluded) excluded += e ? 1 : 0;
  log::get("app")->info("session {}: {} views ({} posed by the kinematic fit only, {} excluded), camera {}x{} ({})",
                        dir, geometry->poses.size(), kinematic, excluded, geometry->camera.width,
                        geometry->camera.height, geometry->source);
  return SessionData{std::move(session.value()), std::move(geometry.value())};
}

Status SessionData::check_view(int view) const {
  if (view < 0 || view >= view_count())
    return make_error(ErrorCode::kInvalidArgument, "--view " + std::to_string(view) +
                                                       " is not a view of the session (0.." +
                                                       std::to_string(view_count() - 1) + ")");
  return Status::ok();
}

Result<cv::Mat> SessionData::photo(int view) const {
  const auto file = session.layout().hdr_file(view);
  auto hdr = calib::read_hdr_exr(file);
  if (!hdr)
    return make_error(hdr.error().code, "view " + std::to_string(view) + ": " + hdr.error().message +
                                            " (merge the brackets first: vdrig hdr SESSION)");
  return hdr->radiance;
}

Result<fitting::TexelObservations> SessionData::observations(const fitting::ParameterMap& map, int s, int t) const {
  auto path = pipeline::session_obsmap_file(session, map.texels_s(), map.texels_t());
  if (!path) return path.error();
  auto reader = fitting::ObsMapReader::open(path.value());
  if (!reader) return reader.error();
  auto tile = reader->read_tile_of_texel(s, t);
  if (!tile) return tile.error();
  return tile->texel(s, t);
}

Result<std::pair<int, int>> parse_texel(const std::string& text) {
  const auto comma = text.find(',');
  try {
    if (comma != std::string::npos) {
      size_t used_s = 0, used_t = 0;
      const int s = std::stoi(text.substr(0, comma), &used_s), t = std::stoi(text.substr(comma + 1), &used_t);
      if (used_s == comma && used_t == text.size() - comma - 1 && s >= 0 && t >= 0) return std::make_pair(s, t);
    }
  } catch (const std::exception&) {
  }
  return make_error(ErrorCode::kInvalidArgument, "--texel must be S,T (texel column and row), e.g. 40,17; got " + text);
}

}  // namespace vdrig::app
