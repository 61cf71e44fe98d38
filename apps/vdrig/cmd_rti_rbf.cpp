#include "cmd_rti_rbf.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "progress.hpp"
#include "vdrig/rti/pca_basis.hpp"

namespace vdrig::app {
namespace {

struct RbfArgs {
  std::string input, out, encoding = "codes", held_out;
  int planes = 9, quality = 95, threads = 0;
};

Result<std::vector<int>> parse_views(const std::string& text) {
  std::vector<int> views;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    try {
      size_t used = 0;
      views.push_back(std::stoi(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      return make_error(ErrorCode::kInvalidArgument, "--hold-out: \"" + item + "\" is not a view index");
    }
  }
  return views;
}

Status run_rbf(const RbfArgs& a) {
  rti::RbfFitOptions options;
  options.planes = a.planes;
  options.jpeg_quality = a.quality;
  options.threads = a.threads;
  auto encoding = rti::parse_display_encoding(a.encoding);
  if (!encoding) return encoding.error();
  options.encoding = encoding.value();
  if (!a.held_out.empty()) {
    auto views = parse_views(a.held_out);
    if (!views) return views.error();
    options.held_out = std::move(views.value());
  }
  ProgressLine progress;
  options.on_progress = [&progress](const std::string& stage, int done, int total) {
    progress.update(done, total, "  %s %d/%d", stage.c_str(), done, total);
  };
  // A stack (its .lp, or a folder holding one) is read straight from its photographs, as `vdrig rti fit STACK`.
  std::error_code ec;
  const bool stack = std::filesystem::is_directory(a.input, ec) || std::filesystem::path(a.input).extension() == ".lp";
  Result<rti::RbfBasis> basis = make_error(ErrorCode::kInternal, "not fitted");
  if (stack) {
    basis = rti::fit_rbf_basis(std::filesystem::path(a.input), options);
  } else {
    auto obs = fitting::ObsMapReader::open(a.input);
    if (!obs) return obs.error();
    basis = rti::fit_rbf_basis(obs.value(), options);
  }
  progress.finish();
  if (!basis) return basis.error();
  VDRIG_TRY(rti::write_relight_rbf(basis.value(), a.out));
  std::printf("wrote %s: rbf over mrgb, %d planes, %zu lights, %dx%d texels\n", a.out.c_str(), basis->planes,
              basis->lights.size(), basis->width, basis->height);
  return Status::ok();
}

}  // namespace

void add_rti_rbf_command(CLI::App& rti) {
  auto a = std::make_shared<RbfArgs>();
  auto* cmd = rti.add_subcommand(
      "rbf", "stack -> relight folder of PCA planes with RBF light interpolation (relight's default basis)");
  cmd->add_option("input", a->input,
                  "the stack (its .lp, or a folder holding one), or an observation-map file (vdrig rti import)")
      ->required();
  cmd->add_option("--out", a->out, "relight folder to write (info.json + plane_<k>.jpg)")->required();
  cmd->add_option("--planes", a->planes, "PCA planes, a multiple of 3 (3..48)")->capture_default_str();
  cmd->add_option("--encoding", a->encoding,
                  "observation maps: their values: codes (imported with --response codes/linear) | srgb (with "
                  "--response sRGB)")
      ->capture_default_str();
  cmd->add_option("--hold-out", a->held_out, "comma-separated view indices left out of the fit");
  cmd->add_option("--quality", a->quality, "JPEG quality 1..100")->capture_default_str();
  cmd->add_option("--threads", a->threads, "worker threads (0: all cores)")->capture_default_str();
  cmd->callback([a] { finish(run_rbf(*a)); });
}

}  // namespace vdrig::app
