#include "vdrig/pipeline/web_scene.hpp"

#include <algorithm>

#include "vdrig/calib/hdr.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;
using nlohmann::json;

Result<WebScene> web_scene(const fs::path& session_dir, const std::string& map_name) {
  auto session = capture::Session::open(session_dir);
  if (!session) return session.error();
  const capture::SessionLayout& layout = session->layout();
  std::vector<std::string> maps;
  std::error_code ec;
  for (fs::directory_iterator it(layout.maps_dir(), ec), end; !ec && it != end; it.increment(ec))
    if (it->path().extension() == ".exr" && it->is_regular_file(ec)) maps.push_back(it->path().stem().string());
  std::sort(maps.begin(), maps.end());
  if (maps.empty())
    return make_error(ErrorCode::kNotFound, "session " + session_dir.filename().string() + " has no maps (vdrig fit)");
  const std::string name = map_name.empty() ? maps.front() : map_name;
  if (std::find(maps.begin(), maps.end(), name) == maps.end())
    return make_error(ErrorCode::kNotFound, "no map " + name + " in " + session_dir.filename().string());
  auto map = fitting::ParameterMap::read(layout.parameter_map_file(name));
  if (!map) return map.error();
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
    const bool photo = fs::exists(layout.hdr_file(static_cast<int>(i)), ec);
    views.push_back({{"index", i}, {"R", r}, {"centre", {c.x(), c.y(), c.z()}}, {"photo", photo}});
  }
  out.scene = {{"map", name},
               {"maps", maps},
               {"model", map->model().name()},
               {"glsl", viewer::model_glsl(map.value())},
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
  auto hdr = calib::read_hdr_exr(session->layout().hdr_file(view));
  if (!hdr) return hdr.error();
  return hdr->radiance;
}

}  // namespace vdrig::pipeline
