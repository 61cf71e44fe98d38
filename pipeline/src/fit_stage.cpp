#include "vdrig/pipeline/fit_stage.hpp"

#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include "vdrig/pipeline/compare_stage.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;

double default_smoothing(const fitting::ReflectanceModel& model) {
  return model.family() == "sh-ls" || model.family() == "hsh" ? 1e-4 : 0.0;
}

Result<fitting::MapFitOptions> fit_options_for(const FitRequest& r, int session_views) {
  auto model = fitting::parse_model(r.model);
  if (!model) return model.error();
  if (r.residual != "absolute" && r.residual != "relative")
    return make_error(ErrorCode::kInvalidArgument, "--residual must be absolute or relative");
  if (r.window != "none" && r.window != "hanning" && r.window != "lanczos")
    return make_error(ErrorCode::kInvalidArgument, "--window must be none, hanning or lanczos");
  if (r.threads < 0 || r.threads > fitting::MapFitOptions::kMaxThreads)
    return make_error(ErrorCode::kInvalidArgument, "--threads must be in [0, " +
                                                       std::to_string(fitting::MapFitOptions::kMaxThreads) +
                                                       "] (0: all cores), got " + std::to_string(r.threads));
  if (r.holdout < 0 || r.holdout >= session_views)
    return make_error(ErrorCode::kInvalidArgument,
                      "--holdout must be in [0, " + std::to_string(session_views - 1) + "]");
  fitting::MapFitOptions options;
  options.model = model.value();
  options.threads = r.threads;
  options.phong.residual =
      r.residual == "relative" ? fitting::ResidualMode::kRelative : fitting::ResidualMode::kAbsolute;
  // SH/HSH regularisation: both option sets get it, the model's own validation rejects what does not apply.
  const fitting::RingingWindow window = r.window == "hanning"   ? fitting::RingingWindow::kHanning
                                        : r.window == "lanczos" ? fitting::RingingWindow::kLanczos
                                                                : fitting::RingingWindow::kNone;
  options.shared_lights = r.shared_lights;
  options.phong.lobe_support = r.lobe_support;
  options.phong.significant_lobes_only = !r.all_lobes;
  const double smoothing = r.smoothing.value_or(default_smoothing(*options.model));
  options.sh.smoothing = options.hsh.smoothing = smoothing;
  options.sh.window = options.hsh.window = window;
  // They regularise the basis expansions, i.e. the models fitted by a linear operator.
  if ((r.smoothing.value_or(0.0) != 0.0 || window != fitting::RingingWindow::kNone) &&
      !options.model->linear_in_shared_directions())
    return make_error(ErrorCode::kInvalidArgument,
                      "--smoothing and --window do not apply to " + options.model->family() + " models");
  // Held-out views spread over the session (never the normal view 0), as `vdrig demo` picks them. The observation
  // map holds every view so that the fit can measure the model on the held-out ones (holdout.R/G/B) while leaving
  // them out of the fit itself.
  options.held_out = spread_holdout_views(session_views, r.holdout);
  return options;
}

Status check_fit_output_writable(const fs::path& out) {
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec)
    return make_error(ErrorCode::kInvalidArgument, "--out: cannot create folder " + dir.string() + ": " + ec.message());
  if (fs::is_directory(out)) return make_error(ErrorCode::kInvalidArgument, "--out: " + out.string() + " is a folder");
  std::string probe = (dir / ".vdrig-write-check-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0)
    return make_error(ErrorCode::kInvalidArgument,
                      "--out: cannot write in " + dir.string() + ": " + std::strerror(errno));
  ::close(fd);
  ::unlink(probe.c_str());
  return Status::ok();
}

size_t map_bytes_at_most(const fitting::ReflectanceModel& model, int texels_s, int texels_t) {
  const size_t parameters = model.storable() ? model.channels().size() : std::max<size_t>(model.channels().size(), 32);
  return (parameters + 7 + 3 + 2) * static_cast<size_t>(texels_s) * static_cast<size_t>(texels_t) * sizeof(float);
}

Status check_map_fits(const fitting::ReflectanceModel& model, int texels_s, int texels_t, const fs::path& out) {
  const size_t bytes = map_bytes_at_most(model, texels_s, texels_t);
  auto mib = [](size_t b) { return std::to_string(b >> 20) + " MiB"; };
  if (bytes > fitting::ParameterMap::kMaxReadBytes)
    return make_error(ErrorCode::kInvalidArgument,
                      "--res " + std::to_string(texels_s) + "x" + std::to_string(texels_t) + ": a " + model.name() +
                          " map would take " + mib(bytes) + ", above the " + mib(fitting::ParameterMap::kMaxReadBytes) +
                          " that vdrig render/view can read back; choose a smaller --res");
  struct statvfs fs_stat {};
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  if (::statvfs(dir.c_str(), &fs_stat) == 0) {
    const size_t free_bytes = static_cast<size_t>(fs_stat.f_bavail) * fs_stat.f_frsize;
    if (free_bytes < bytes)
      return make_error(ErrorCode::kNoSpace, "--out " + out.string() + ": the map may take up to " + mib(bytes) +
                                                 " and " + dir.string() + " has " + mib(free_bytes) + " free");
  }
  return Status::ok();
}

FitSummary summarize_fit(const fitting::ParameterMap& map) {
  auto median_of = [&](const std::string& prefix) {
    std::vector<float> v;
    for (int t = 0; t < map.texels_t(); ++t)
      for (int s = 0; s < map.texels_s(); ++s)
        if (map.at("n", s, t) > 0)
          v.push_back((map.at(prefix + "R", s, t) + map.at(prefix + "G", s, t) + map.at(prefix + "B", s, t)) / 3.0f);
    if (v.empty()) return 0.0f;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  FitSummary summary;
  summary.median_rms = median_of("rms.");
  if (map.has("holdout.R")) summary.median_holdout_rms = median_of("holdout.");
  return summary;
}

}  // namespace vdrig::pipeline
