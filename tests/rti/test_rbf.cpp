// relight's default basis (PCA planes + RBF light interpolation, rti/pca_basis.hpp) on held-out lights: a
// synthetic stack (synthetic_stack.hpp, known radiance) is imported with every 9th light left out of the fits, and
// what the viewer shows at the held-out lights is compared with the true radiance in 8-bit codes, beside vdrig's
// HSH-27 (hsh:3) and, when it is built (scripts/build_relight), relight-cli's own rbf fit of the same JPEGs.
//
// relight-cli is the peer: it renders vdrig's folder with its own loader and renderer (src/rti.cpp), and its
// folder is rendered here with the weights OpenLIME uses, so the two fits are compared as OpenLIME shows them.
// Tests needing it skip, naming it, when it is absent (vdrig/test/relight_peer.hpp: where ./vdrig.sh test built it,
// they fail instead).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "synthetic_stack.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/rti/fitted_files.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/rti/pca_basis.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/relight_peer.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;

constexpr int kSize = 128, kLights = 289;
bool held_out_view(int v) { return v % 9 == 4; }  // 32 of 289, spread along the spiral (all elevations)

/// Error of an image (3 floats per texel, rows from the top, codes) against the stack's true radiance x 255, after
/// the framebuffer's rounding to 8 bits.
struct ErrorSum {
  double squared = 0, absolute = 0;
  long n = 0;
  void add(double shown, double truth) {
    const double e = std::clamp(std::round(shown), 0.0, 255.0) - truth;
    squared += e * e;
    absolute += std::abs(e);
    ++n;
  }
  double rms() const { return std::sqrt(squared / std::max(1L, n)); }
  double mean_abs() const { return absolute / std::max(1L, n); }
};

void add_image(ErrorSum& sum, const test::SyntheticStack& stack, const std::vector<float>& image, const Vec3d& l) {
  for (int row = 0; row < stack.height; ++row)
    for (int s = 0; s < stack.width; ++s) {
      const Vec3d truth = 255.0 * stack.radiance(s, stack.height - 1 - row, l);
      for (int k = 0; k < 3; ++k) sum.add(image[(static_cast<size_t>(row) * stack.width + s) * 3 + k], truth[k]);
    }
}

/// An RGB(A) image file as 3 floats per texel, rows from the top.
std::vector<float> read_rgb(const fs::path& file) {
  const cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  std::vector<float> out;
  if (bgr.empty()) return out;
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x)
      for (int k = 0; k < 3; ++k) out.push_back(bgr.at<cv::Vec3b>(y, x)[2 - k]);
  return out;
}

/// Shared by the tests: the stack, its import, vdrig's rbf fit and its folder (built once, a few seconds).
struct Shared {
  test::TempDir dir{"rti_rbf"};
  test::SyntheticStack stack;
  std::vector<int> held_out;
  std::vector<Vec3d> held_out_lights;
  std::unique_ptr<fitting::ObsMapReader> obs;
  RbfBasis basis;
  fs::path folder;
};
Shared* shared = nullptr;

class Rbf : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    shared = new Shared;
    Shared& sh = *shared;
    fs::create_directories(sh.dir / "stack");
    sh.stack = test::write_synthetic_stack(sh.dir / "stack", kSize, kSize, kLights, ".jpg");
    for (int v = 0; v < kLights; ++v)
      if (held_out_view(v)) {
        sh.held_out.push_back(v);
        sh.held_out_lights.push_back(sh.stack.lights[static_cast<size_t>(v)]);
      }
    ImportOptions import;
    import.linearisation = Linearisation::parse("linear").value();  // the codes themselves, as the viewers show
    ASSERT_TRUE(import_stack(sh.stack.lp_file, sh.dir / "stack.vdobs", import));
    auto obs = fitting::ObsMapReader::open(sh.dir / "stack.vdobs");
    ASSERT_TRUE(obs) << obs.error().describe();
    sh.obs = std::make_unique<fitting::ObsMapReader>(std::move(obs.value()));
    RbfFitOptions options;
    options.held_out = sh.held_out;
    auto basis = fit_rbf_basis(*sh.obs, options);
    ASSERT_TRUE(basis) << basis.error().describe();
    sh.basis = std::move(basis.value());
    sh.folder = sh.dir / "vdrig_rbf";
    ASSERT_TRUE(write_relight_rbf(sh.basis, sh.folder));
  }
  static void TearDownTestSuite() {
    delete shared;
    shared = nullptr;
  }
  void SetUp() override { ASSERT_NE(shared->obs, nullptr) << "the suite's set-up failed"; }
};

ErrorSum held_out_error(const RbfBasis& basis, RbfWeights weights = RbfWeights::kOpenLime) {
  ErrorSum sum;
  for (const Vec3d& l : shared->held_out_lights) add_image(sum, shared->stack, render_rbf(basis, l, weights), l);
  return sum;
}

TEST_F(Rbf, WritesTheLayoutOpenLimeReads) {
  const RbfBasis& b = shared->basis;
  EXPECT_EQ(b.planes, 9);
  EXPECT_EQ(b.lights.size(), static_cast<size_t>(kLights - 32));
  std::ifstream in(shared->folder / "info.json");
  const auto info = nlohmann::json::parse(in);
  EXPECT_EQ(info["type"], "rbf");
  EXPECT_EQ(info["colorspace"], "mrgb");
  EXPECT_EQ(info["nplanes"], 9);
  EXPECT_EQ(info["lights"].size(), 3 * b.lights.size());
  EXPECT_EQ(info["basis"].size(), 10 * 3 * b.lights.size());
  for (const auto& v : info["basis"]) ASSERT_TRUE(v.get<int>() >= 0 && v.get<int>() <= 255);
  ASSERT_EQ(info["materials"].size(), 1u);
  for (const char* key : {"range", "scale", "bias"}) EXPECT_EQ(info["materials"][0][key].size(), 9u) << key;
  EXPECT_FALSE(info.contains("scale")) << "scale and bias belong in materials[0] (OpenLIME, relight)";
  for (int j = 0; j < 3; ++j) EXPECT_TRUE(fs::exists(shared->folder / ("plane_" + std::to_string(j) + ".jpg")));
  // What the folder decodes to is what was evaluated.
  auto back = read_relight_rbf(shared->folder);
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_EQ(back->basis, b.basis);
  EXPECT_EQ(back->coefficient_bytes, b.coefficient_bytes);
}

TEST_F(Rbf, RefusesWhatOpenLimeCannotRender) {
  RbfFitOptions options;
  options.planes = 8;  // OpenLIME's shader reads three planes per JPEG
  EXPECT_EQ(fit_rbf_basis(*shared->obs, options).error().code, ErrorCode::kInvalidArgument);
  options.planes = 9;
  options.held_out = {kLights};
  EXPECT_EQ(fit_rbf_basis(*shared->obs, options).error().code, ErrorCode::kInvalidArgument);
}

// `vdrig rti rbf STACK` reads the photographs through the one-pass reader (stack_reader.hpp), twice, instead of an
// imported observation map: the same texels sampled for the PCA, the same values, so the same basis up to the
// order of float sums (a byte of the table or a coefficient may round the other way).
TEST_F(Rbf, FromTheStackAsFromTheImport) {
  RbfFitOptions options;
  options.held_out = shared->held_out;
  auto direct = fit_rbf_basis(shared->stack.lp_file, options);
  ASSERT_TRUE(direct) << direct.error().describe();
  EXPECT_EQ(direct->lights.size(), shared->basis.lights.size());
  double worst = 0, sum = 0;
  long n = 0;
  for (const Vec3d& l : shared->held_out_lights) {
    const std::vector<float> a = render_rbf(direct.value(), l), b = render_rbf(shared->basis, l);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i, ++n) {
      worst = std::max(worst, double(std::abs(a[i] - b[i])));
      sum += std::abs(a[i] - b[i]);
    }
  }
  const ErrorSum held = held_out_error(direct.value());
  std::printf("rbf from the stack against from the import: mean %.4f, max %.2f codes; held-out RMS %.3f\n", sum / n,
              worst, held.rms());
  // Measured mean 0.04-0.20, max 1.2-1.6 codes from run to run: the workers' float sums come in another order, a
  // few bytes of the table round the other way, and the plane JPEGs' blocks around them change.
  EXPECT_LT(sum / n, 0.35);
  EXPECT_LT(worst, 3.0);
  EXPECT_NEAR(held.rms(), held_out_error(shared->basis).rms(), 0.02);
  EXPECT_LT(held.rms(), 1.6);
  // The stack holds the codes: an sRGB encoding applies to observation maps only.
  options.encoding = DisplayEncoding::kSrgb;
  EXPECT_EQ(fit_rbf_basis(shared->stack.lp_file, options).error().code, ErrorCode::kInvalidArgument);
  options.encoding = DisplayEncoding::kCodes;
  EXPECT_EQ(fit_rbf_basis(shared->dir / "no_such_stack", options).error().code, ErrorCode::kNotFound);
}

// `vdrig rti import FOLDER --out map.exr` of an rbf folder (vdrig has no rbf model): HSH-27 fitted to what OpenLIME
// shows at the folder's lights, so view, render and compare work on it. Lossy, but on this smooth stack HSH-27 holds
// the rbf within a fraction of a code, and the map is as close to the truth at held-out lights as the folder.
TEST_F(Rbf, ImportedAsAParameterMap) {
  auto map = read_fitted_file(shared->folder);
  ASSERT_TRUE(map) << map.error().describe();
  EXPECT_EQ(map->model().name(), "hsh:3");
  ASSERT_EQ(map->texels_s(), kSize);
  // At the held-out lights: against OpenLIME's rendering of the folder (unrounded), and against the truth.
  double vs_rbf_sq = 0;
  long vs_rbf_n = 0;
  ErrorSum vs_truth;
  for (const Vec3d& l : shared->held_out_lights) {
    const std::vector<float> shown = render_rbf(shared->basis, l);
    for (int row = 0; row < kSize; ++row)
      for (int s = 0; s < kSize; ++s) {
        const Vec3d v = 255.0 * map->evaluate(s, kSize - 1 - row, l);
        const Vec3d truth = 255.0 * shared->stack.radiance(s, kSize - 1 - row, l);
        for (int k = 0; k < 3; ++k) {
          const double d = v[k] - shown[(static_cast<size_t>(row) * kSize + s) * 3 + static_cast<size_t>(k)];
          vs_rbf_sq += d * d;
          ++vs_rbf_n;
          vs_truth.add(v[k], truth[k]);
        }
      }
  }
  const float rms_centre = map->at("rms.G", kSize / 2, kSize / 2) * 255.0f;
  std::printf(
      "rbf folder imported as hsh:3: %.3f codes RMS from OpenLIME's rendering, %.3f from the truth at held-out "
      "lights (the folder itself: %.3f); rms.G at the centre %.3f codes\n",
      std::sqrt(vs_rbf_sq / vs_rbf_n), vs_truth.rms(), held_out_error(shared->basis).rms(), rms_centre);
  // Measured 1.03 and 0.92 (the folder itself 1.07: HSH-27 smooths some of the planes' JPEG noise away).
  EXPECT_LT(std::sqrt(vs_rbf_sq / vs_rbf_n), 1.5);
  EXPECT_LT(vs_truth.rms(), 1.4);
  EXPECT_LT(vs_truth.rms(), held_out_error(shared->basis).rms() + 0.2);
  EXPECT_GT(rms_centre, 0.0f);  // the conversion's own residual is recorded
  EXPECT_LT(rms_centre, 1.0f);
  // Another model on request; one that is not linear in the light is refused.
  auto ptm = read_fitted_file(shared->folder / "info.json", "ptm:rgb");
  ASSERT_TRUE(ptm) << ptm.error().describe();
  EXPECT_EQ(ptm->model().name(), "ptm:rgb");
  EXPECT_EQ(read_fitted_file(shared->folder, "phong:1").error().code, ErrorCode::kInvalidArgument);
}

// The accuracy table of docs/rti.md ("Compressed basis"): held-out lights, codes, against the true radiance.
TEST_F(Rbf, HeldOutLightsBesideHsh27) {
  const ErrorSum rbf = held_out_error(shared->basis);

  // relight-cli's table (the eigenvectors themselves, no deconvolution) through the same fit, for the figure.
  RbfFitOptions plain;
  plain.held_out = shared->held_out;
  plain.deconvolution = -1;
  auto undeconvolved = fit_rbf_basis(*shared->obs, plain);
  ASSERT_TRUE(undeconvolved);
  const ErrorSum rbf_plain = held_out_error(undeconvolved.value());
  if (std::getenv("VDRIG_RBF_SWEEP")) {  // how the deconvolution weight was chosen (docs/rti.md)
    for (double lambda : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 1e-5}) {
      plain.deconvolution = lambda;
      for (int planes : {9, 18}) {
        plain.planes = planes;
        auto b = fit_rbf_basis(*shared->obs, plain);
        ASSERT_TRUE(b);
        const ErrorSum e = held_out_error(b.value());
        std::printf("  deconvolution %g, %d planes: held-out RMS %.3f, mean |error| %.3f codes\n", lambda, planes,
                    e.rms(), e.mean_abs());
      }
    }
  }

  fitting::MapFitOptions fit;
  fit.model = fitting::parse_model("hsh:3").value();
  fit.held_out = shared->held_out;
  auto map = fitting::fit_parameter_map(*shared->obs, fit);
  ASSERT_TRUE(map) << map.error().describe();
  ErrorSum hsh;
  for (const Vec3d& l : shared->held_out_lights)
    for (int t = 0; t < kSize; ++t)
      for (int s = 0; s < kSize; ++s) {
        const Vec3d v = 255.0 * map->model().evaluate(map->parameters(s, t), l);
        const Vec3d truth = 255.0 * shared->stack.radiance(s, t, l);
        for (int k = 0; k < 3; ++k) hsh.add(v[k], truth[k]);
      }
  std::printf("held-out lights (%zu of %d, %dx%d): RMS / mean |error| in codes\n", shared->held_out.size(), kLights,
              kSize, kSize);
  std::printf("  vdrig rbf-9 (OpenLIME weights):             %.3f / %.3f\n", rbf.rms(), rbf.mean_abs());
  std::printf("  vdrig rbf-9 without deconvolution:          %.3f / %.3f\n", rbf_plain.rms(), rbf_plain.mean_abs());
  std::printf("  vdrig hsh:3 (unquantised fit):              %.3f / %.3f\n", hsh.rms(), hsh.mean_abs());
  // Bounds ~1.5x the measured figures (docs/rti.md: 1.07, 0.88; 7.0 without the deconvolution).
  EXPECT_LT(rbf.rms(), 1.6);
  EXPECT_LT(rbf.mean_abs(), 1.05);
  EXPECT_LT(hsh.rms(), 1.3);
  EXPECT_LT(rbf.rms(), rbf_plain.rms() / 4) << "the deconvolved table is the point of vdrig's fit";
}

// A stack imported as linear radiance (--response sRGB) is put back through the sRGB curve: the viewer must still
// show the photographs' codes.
TEST_F(Rbf, SrgbImportShowsTheCodes) {
  ImportOptions import;
  import.linearisation = Linearisation::parse("sRGB").value();
  ASSERT_TRUE(import_stack(shared->stack.lp_file, shared->dir / "srgb.vdobs", import));
  auto obs = fitting::ObsMapReader::open(shared->dir / "srgb.vdobs");
  ASSERT_TRUE(obs);
  RbfFitOptions options;
  options.held_out = shared->held_out;
  options.encoding = DisplayEncoding::kSrgb;
  auto basis = fit_rbf_basis(obs.value(), options);
  ASSERT_TRUE(basis) << basis.error().describe();
  const ErrorSum e = held_out_error(basis.value());
  std::printf("sRGB import, --encoding srgb: held-out RMS %.3f / mean %.3f codes\n", e.rms(), e.mean_abs());
  EXPECT_LT(e.rms(), 1.6);                     // as the codes import: measured 1.07
  options.encoding = DisplayEncoding::kCodes;  // the mistake the option exists for: linear radiance shown as codes
  auto dark = fit_rbf_basis(obs.value(), options);
  ASSERT_TRUE(dark);
  const double dark_rms = held_out_error(dark.value()).rms();
  std::printf("sRGB import shown as codes (--encoding codes): held-out RMS %.3f codes\n", dark_rms);
  EXPECT_GT(dark_rms, 40.0);  // measured 62.3
}

TEST_F(Rbf, ReaderRefusesOtherBases) {
  const fs::path other = shared->dir / "hsh_folder";
  fs::create_directories(other);
  std::ofstream(other / "info.json") << R"({"width": 4, "height": 4, "type": "hsh", "colorspace": "rgb"})";
  EXPECT_EQ(read_relight_rbf(other).error().code, ErrorCode::kUnsupported);
  std::ofstream(other / "info.json") << "{ not json";
  EXPECT_EQ(read_relight_rbf(other).error().code, ErrorCode::kCorrupt);
  EXPECT_EQ(read_relight_rbf(shared->dir / "nothing_here").error().code, ErrorCode::kNotFound);
}

/// Runs relight-cli; its stdout and stderr for the failure message.
test::ProcessRun relight(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {test::relight_cli_path().string()};
  argv.insert(argv.end(), args.begin(), args.end());
  return test::run_process(argv, {.timeout_s = 300, .merge_stderr = true});
}

/// relight-cli's rendering (its own loader and Rti::render) of `folder` under light l, 3 floats per texel.
std::vector<float> relight_render(const fs::path& folder, const Vec3d& l, const fs::path& png) {
  char light[96];
  std::snprintf(light, sizeof light, "%.9f:%.9f:%.9f", l.x(), l.y(), l.z());
  const auto run = relight({"-L", light, "-D", png.string(), (folder / "info.json").string()});
  EXPECT_EQ(run.exit_code, 0) << run.out;
  return read_rgb(png);
}

// The peer reads vdrig's folder: relight-cli's renderer (its own weights, exp(-d^2 / sigma^2)) against vdrig's
// evaluation of the same folder with those weights. Checks the layout (basis order, mean, range, scale and bias in
// materials[0], plane order and rows) through a program that was not written from vdrig's reading of the format.
TEST_F(Rbf, RelightCliRendersVdrigsFolderAsVdrigDoes) {
  VDRIG_REQUIRE_RELIGHT_CLI();
  ErrorSum diff;
  double worst = 0;
  for (size_t i = 0; i < shared->held_out_lights.size(); i += 8) {
    const Vec3d& l = shared->held_out_lights[i];
    const auto peer = relight_render(shared->folder, l, shared->dir / "peer.png");
    ASSERT_EQ(peer.size(), static_cast<size_t>(kSize) * kSize * 3);
    const auto ours = render_rbf(shared->basis, l, RbfWeights::kRelightCli);
    for (size_t x = 0; x < peer.size(); ++x) {
      diff.add(ours[x], peer[x]);
      worst = std::max(worst, double(std::abs(ours[x] - peer[x])));
    }
  }
  std::printf("relight-cli vs vdrig rendering vdrig's folder: RMS %.4f, max %.0f codes\n", diff.rms(), worst);
  // Measured: identical. A code where float and double round differently before relight's truncation.
  EXPECT_LE(worst, 1.0);
  EXPECT_LT(diff.rms(), 0.05);
}

// relight-cli -b rbf on the same JPEGs without the held-out lights, both folders shown with OpenLIME's weights.
TEST_F(Rbf, AtLeastAsAccurateAsRelightCli) {
  VDRIG_REQUIRE_RELIGHT_CLI();
  const fs::path train = shared->dir / "train";
  fs::create_directories(train);
  std::string lp = std::to_string(kLights - static_cast<int>(shared->held_out.size())) + "\n";
  for (int v = 0; v < kLights; ++v) {
    if (held_out_view(v)) continue;
    char name[32];
    std::snprintf(name, sizeof name, "image_%03d.jpg", v);
    fs::copy_file(shared->dir / "stack" / name, train / name);
    const Vec3d& l = shared->stack.lights[static_cast<size_t>(v)];
    char line[160];
    std::snprintf(line, sizeof line, "%s %.9f %.9f %.9f\n", name, l.x(), l.y(), l.z());
    lp += line;
  }
  std::ofstream(train / "train.lp") << lp;
  const fs::path out = shared->dir / "relight_rbf";
  // -I srgb: fit the codes as they are (relight-cli linearises by default), as vdrig's import above.
  const auto run = relight({"-b", "rbf", "-p", "9", "-I", "srgb", train.string(), out.string()});
  ASSERT_EQ(run.exit_code, 0) << run.out;
  auto theirs = read_relight_rbf(out);
  ASSERT_TRUE(theirs) << theirs.error().describe();
  const ErrorSum relight_openlime = held_out_error(theirs.value());
  const ErrorSum ours = held_out_error(shared->basis);
  ErrorSum relight_own;  // relight-cli's own renderer on its own folder
  for (const Vec3d& l : shared->held_out_lights)
    add_image(relight_own, shared->stack, relight_render(out, l, shared->dir / "own.png"), l);
  ErrorSum ours_relight_own;  // vdrig's folder in relight-cli's renderer (its sigma approximates OpenLIME's width)
  for (const Vec3d& l : shared->held_out_lights)
    add_image(ours_relight_own, shared->stack, relight_render(shared->folder, l, shared->dir / "ours.png"), l);
  std::printf("held-out lights: RMS / mean |error| in codes\n");
  std::printf("  vdrig rbf-9, relight-cli's renderer:         %.3f / %.3f\n", ours_relight_own.rms(),
              ours_relight_own.mean_abs());
  std::printf("  vdrig rbf-9, OpenLIME weights:               %.3f / %.3f\n", ours.rms(), ours.mean_abs());
  std::printf("  relight-cli rbf-9, OpenLIME weights:         %.3f / %.3f\n", relight_openlime.rms(),
              relight_openlime.mean_abs());
  std::printf("  relight-cli rbf-9, relight-cli's renderer:   %.3f / %.3f\n", relight_own.rms(),
              relight_own.mean_abs());
  // Measured 1.07 against 7.2 (OpenLIME) and 3.3 (relight-cli's renderer).
  EXPECT_LE(ours.rms(), relight_openlime.rms());
  EXPECT_LE(ours.rms(), relight_own.rms());
  EXPECT_LE(ours_relight_own.rms(), relight_own.rms()) << "in relight's own viewer too";

  // `vdrig rti import` of relight-cli's folder: the hsh:3 map is what OpenLIME shows of it, near enough that it is
  // about as far from the truth at the held-out lights.
  auto imported = read_fitted_file(out);
  ASSERT_TRUE(imported) << imported.error().describe();
  ErrorSum map_error;
  for (const Vec3d& l : shared->held_out_lights)
    for (int row = 0; row < kSize; ++row)
      for (int s = 0; s < kSize; ++s) {
        const Vec3d v = 255.0 * imported->evaluate(s, kSize - 1 - row, l);
        const Vec3d truth = 255.0 * shared->stack.radiance(s, kSize - 1 - row, l);
        for (int k = 0; k < 3; ++k) map_error.add(v[k], truth[k]);
      }
  std::printf("  relight-cli rbf-9 imported by vdrig (hsh:3): %.3f / %.3f\n", map_error.rms(), map_error.mean_abs());
  EXPECT_NEAR(map_error.rms(), relight_openlime.rms(), 0.25 * relight_openlime.rms());
}

}  // namespace
}  // namespace vdrig::rti
