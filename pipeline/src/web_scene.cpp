#include "vdrig/pipeline/web_scene.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <utility>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/open_below.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/viewer/surface_renderer.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// A regular file below a session folder, opened as the console opens its other session files (open_regular_below):
/// one path component at a time from the session folder with O_NOFOLLOW, so that a link anywhere below the folder
/// (a linked maps/, hdr/ or obsmap/ folder, or a linked file) is refused, not followed. The readers take a path:
/// they get /proc/self/fd/N, which names the file already opened, not a path resolved again (no race with a link
/// made after the check).
class OpenedBelow {
 public:
  static Result<OpenedBelow> open(const fs::path& session_dir, const fs::path& file) {
    const Error missing = make_error(ErrorCode::kNotFound, "no " + file.lexically_relative(session_dir).string() +
                                                               " in " + session_dir.filename().string());
    const fs::path relative = file.lexically_relative(session_dir);
    if (relative.empty() || *relative.begin() == "..") return missing;
    std::vector<std::string> parts;
    for (const auto& p : relative) parts.push_back(p.string());
    struct stat st {};
    const int fd = open_regular_below(session_dir, parts, st);
    if (fd < 0) return missing;
    return OpenedBelow(fd);
  }
  OpenedBelow(OpenedBelow&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  OpenedBelow& operator=(OpenedBelow&&) = delete;
  ~OpenedBelow() {
    if (fd_ >= 0) ::close(fd_);
  }
  fs::path path() const { return "/proc/self/fd/" + std::to_string(fd_); }

 private:
  explicit OpenedBelow(int fd) : fd_(fd) {}
  int fd_ = -1;
};

/// The map names of SESSION/maps/ (regular *.exr files, not links), sorted.
std::vector<std::string> map_names(const capture::SessionLayout& layout) {
  std::vector<std::string> maps;
  std::error_code ec;
  for (fs::directory_iterator it(layout.maps_dir(), ec), end; !ec && it != end; it.increment(ec))
    if (it->path().extension() == ".exr" && it->symlink_status(ec).type() == fs::file_type::regular)
      maps.push_back(it->path().stem().string());
  std::sort(maps.begin(), maps.end());
  return maps;
}

/// The map `map_name` (empty: the first) of a session, read through OpenedBelow; its name in `name`.
Result<fitting::ParameterMap> read_map(const capture::Session& session, const fs::path& session_dir,
                                       const std::string& map_name, std::vector<std::string>& maps, std::string& name) {
  maps = map_names(session.layout());
  if (maps.empty())
    return make_error(ErrorCode::kNotFound, "session " + session_dir.filename().string() + " has no maps (vdrig fit)");
  name = map_name.empty() ? maps.front() : map_name;
  if (std::find(maps.begin(), maps.end(), name) == maps.end())
    return make_error(ErrorCode::kNotFound, "no map " + name + " in " + session_dir.filename().string());
  auto file = OpenedBelow::open(session_dir, session.layout().parameter_map_file(name));
  if (!file) return file.error();
  auto map = fitting::ParameterMap::read(file->path());
  if (!map) return make_error(map.error().code, "map " + name + ": " + map.error().message);
  return map;
}

}  // namespace

Result<WebScene> web_scene(const fs::path& session_dir, const std::string& map_name) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  const capture::SessionLayout& layout = session->layout();
  std::vector<std::string> maps;
  std::string name;
  auto map = read_map(session.value(), session_dir, map_name, maps, name);
  if (!map) return map.error();
  std::error_code ec;
  auto geometry = session_geometry(session.value());
  if (!geometry) return geometry.error();

  WebScene out;
  const auto& img = map->image();
  const int channels = static_cast<int>(img.channels.size());
  const int layers = std::max(1, (channels + 3) / 4);
  out.params.assign(static_cast<size_t>(layers) * img.width * img.height * 4, 0.0f);
  for (int c = 0; c < channels; ++c)
    for (int y = 0; y < img.height; ++y) {
      const float* row = img.channels[c].ptr<float>(y);
      for (int x = 0; x < img.width; ++x)
        out.params[((static_cast<size_t>(c / 4) * img.height + y) * img.width + x) * 4 + c % 4] = row[x];
    }
  const CameraModel& cam = geometry->camera;
  json views = json::array();
  for (size_t i = 0; i < geometry->poses.size(); ++i) {
    if (i < geometry->excluded.size() && geometry->excluded[i]) continue;
    const ViewPose& pose = geometry->poses[i];
    json r = json::array();
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 3; ++col) r.push_back(pose.R(row, col));
    const Vec3d c = pose.camera_centre();
    const bool photo = fs::symlink_status(layout.hdr_file(static_cast<int>(i)), ec).type() == fs::file_type::regular;
    views.push_back({{"index", i}, {"R", r}, {"centre", {c.x(), c.y(), c.z()}}, {"photo", photo}});
  }
  out.scene = {{"map", name},
               {"maps", maps},
               {"model", map->model().name()},
               {"glsl", viewer::surface_glsl(map.value())},
               {"texels", {map->texels_s(), map->texels_t()}},
               {"size_mm", {map->width_mm(), map->height_mm()}},
               {"layers", layers},
               {"image_size", {img.width, img.height}},
               {"camera",
                {{"width", cam.width},
                 {"height", cam.height},
                 {"fx", cam.fx},
                 {"fy", cam.fy},
                 {"cx", cam.cx},
                 {"cy", cam.cy},
                 {"dist", {cam.k1, cam.k2, cam.p1, cam.p2, cam.k3}}}},
               {"views", views}};
  return out;
}

Result<cv::Mat> web_photo(const fs::path& session_dir, int view) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  if (view < 0 || view >= static_cast<int>(session->manifest().views.size()))
    return make_error(ErrorCode::kNotFound, "no view " + std::to_string(view));
  auto file = OpenedBelow::open(session_dir, session->layout().hdr_file(view));
  if (!file) return file.error();
  auto hdr = calib::read_hdr_exr(file->path());
  if (!hdr) return make_error(hdr.error().code, "view " + std::to_string(view) + ": " + hdr.error().message);
  return hdr->radiance;
}

Result<std::string> web_texel_svg(const fs::path& session_dir, const std::string& map_name, int s, int t) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  std::vector<std::string> maps;
  std::string name;
  auto map = read_map(session.value(), session_dir, map_name, maps, name);
  if (!map) return map.error();
  if (s < 0 || s >= map->texels_s() || t < 0 || t >= map->texels_t())
    return make_error(ErrorCode::kInvalidArgument,
                      "texel " + std::to_string(s) + "," + std::to_string(t) + " is outside map " + name + " (" +
                          std::to_string(map->texels_s()) + "x" + std::to_string(map->texels_t()) + " texels)");
  const fs::path obs_file = session->layout().obsmap_file(map->texels_s(), map->texels_t());
  auto opened = OpenedBelow::open(session_dir, obs_file);
  if (!opened)
    return make_error(ErrorCode::kNotFound,
                      "no observation map " + obs_file.filename().string() + " (vdrig obsmap build SESSION --res " +
                          std::to_string(map->texels_s()) + "x" + std::to_string(map->texels_t()) + ")");
  auto reader = fitting::ObsMapReader::open(opened->path());
  if (!reader) return make_error(reader.error().code, obs_file.filename().string() + ": " + reader.error().message);
  auto tile = reader->read_tile_of_texel(s, t);
  if (!tile) return make_error(tile.error().code, obs_file.filename().string() + ": " + tile.error().message);
  const auto held_out = viewer::held_out_views(map.value());
  viewer::plot::Figure curve =
      viewer::curve_figure(viewer::inspect_texel(map.value(), s, t, tile->texel(s, t), held_out));
  curve.title = name + " texel " + std::to_string(s) + "," + std::to_string(t) + ": " + curve.title;
  // A document of its own (served as image/svg+xml, shown in an <img>) needs the namespace that inline SVG in the
  // report's HTML does without.
  std::string svg = viewer::plot::to_svg(curve);
  if (svg.starts_with("<svg ")) svg.insert(4, " xmlns=\"http://www.w3.org/2000/svg\"");
  return svg;
}

}  // namespace vdrig::pipeline
