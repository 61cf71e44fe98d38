#include "vdrig/capture/session_layout.hpp"

#include <cstdio>

#include "vdrig/core/result.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;

fs::path SessionLayout::manifest_file() const { return dir_ / "manifest.json"; }
fs::path SessionLayout::journal_file() const { return dir_ / "journal.jsonl"; }
fs::path SessionLayout::lock_file() const { return dir_ / "capture.lock"; }

fs::path SessionLayout::frames_dir() const { return dir_ / "frames"; }

fs::path SessionLayout::frame_file_relative(int view, int bracket_index) {
  char name[48];
  std::snprintf(name, sizeof name, "view_%04d_e%02d.png", view, bracket_index);
  return fs::path("frames") / name;
}

fs::path SessionLayout::frame_file(int view, int bracket_index) const {
  return dir_ / frame_file_relative(view, bracket_index);
}

fs::path SessionLayout::hdr_dir() const { return dir_ / "hdr"; }

fs::path SessionLayout::hdr_file(int view) const {
  char name[32];
  std::snprintf(name, sizeof name, "view_%04d.exr", view);
  return hdr_dir() / name;
}

fs::path SessionLayout::calib_dir() const { return dir_ / "calib"; }
fs::path SessionLayout::response_file() const { return calib_dir() / "response.json"; }
fs::path SessionLayout::camera_file() const { return calib_dir() / "camera.yml"; }
fs::path SessionLayout::views_file() const { return calib_dir() / "views.json"; }

fs::path SessionLayout::obsmap_dir() const { return dir_ / "obsmap"; }

fs::path SessionLayout::obsmap_file(int texels_s, int texels_t) const {
  return obsmap_dir() / (std::to_string(texels_s) + "x" + std::to_string(texels_t) + ".vdobs");
}

fs::path SessionLayout::maps_dir() const { return dir_ / "maps"; }

fs::path SessionLayout::parameter_map_file(const std::string& model_spec) const {
  VDRIG_CHECK(
      !model_spec.empty() && model_spec.find('/') == std::string::npos && model_spec != "." && model_spec != "..",
      "a model spec names a file in maps/: '" + model_spec + "'");
  return maps_dir() / (model_spec + ".exr");
}

fs::path SessionLayout::renders_dir() const { return dir_ / "renders"; }
fs::path SessionLayout::compare_dir() const { return renders_dir() / "compare"; }

}  // namespace vdrig::capture
