// relight's default RTI basis ("rbf" over "mrgb"): per-stack PCA-compressed planes with a radial-basis
// interpolation of the light, written in relight's web format (info.json + plane_<k>.jpg) that OpenLIME loads.
//
// The model (OpenLIME's ShaderRTI with type "rbf", colorspace "mrgb"; openlime.js RBF, AdaptiveRBF, MRGB.render):
// the file holds a table of nplanes + 1 entries per light i and channel k, `basis`, as bytes: entry 0 is a mean
// (byte / 255) and entry p > 0 a basis function ((byte - 127) / range[p - 1]). Rendering under light l takes
// interpolation weights w_i(l) over the file's lights (AdaptiveRBF, alpha 8: w_i ∝ exp(-eps |l - l_i|^2), eps = 8 /
// (smooth minimum distance from l to the lights), normalised), forms base_p,k = Σ_i w_i table_p[i][k], and shows,
// per texel, rgb_k = base_0,k + Σ_p base_p+1,k c_p with c_p = (byte_p / 255 - bias_p) scale_p read from the plane
// JPEGs (plane_<j>.jpg holds planes 3j, 3j+1, 3j+2 in R, G, B). OpenLIME applies srgb2linear to that value and its
// final pass linear2srgb, so the value is shown as the display code itself: the planes are fitted in display
// codes (DisplayEncoding).
//
// How vdrig fits it (fit_rbf_basis), and where it differs from relight-cli (src/cli/rtibuilder.cpp):
//  - the same PCA: the texels' display values at the N lights (3N numbers, light-major, R G B) centred on their
//    mean, the `planes` leading eigenvectors of their covariance (on a subsample of texels, as relight samples);
//  - relight stores the eigenvectors at the lights as the table; OpenLIME then blurs them by its interpolation
//    (w_i(l_j) is far from a delta at a stack's own lights: eps ~ 16 puts half the weight on neighbours). vdrig
//    stores the table whose interpolation reproduces the eigenvectors at the lights (Tikhonov-regularised
//    deconvolution by the N x N matrix w_i(l_j), `deconvolution`), so what OpenLIME shows at the lights is the PCA
//    reconstruction and between them an RBF interpolant of it;
//  - relight projects each texel on the unquantised eigenvectors; vdrig fits each texel's coefficients by least
//    squares against what OpenLIME renders at the lights from the quantised table (8-bit basis, mean).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::rti {

/// How an observation map's radiance becomes the display value (0..1, code / 255) the planes hold.
enum class DisplayEncoding {
  kCodes,  // imported with --response codes (formerly "linear"): the values are the codes / 255 already
  kSrgb,   // imported with --response sRGB (linear radiance): the sRGB transfer curve gives the codes back
};

/// "codes" (or "linear"), "srgb" (or "sRGB"); kInvalidArgument otherwise.
Result<DisplayEncoding> parse_display_encoding(const std::string& text);

/// A relight "rbf"/"mrgb" basis as the files hold it: everything quantised as written (planes as decoded bytes).
struct RbfBasis {
  int width = 0, height = 0;  // texels; plane rows are image rows, top first (texel row t is row height - 1 - t)
  int planes = 0;             // nplanes, a multiple of 3
  std::vector<Vec3d> lights;  // unit directions, one per table entry
  double sigma = 0.125;       // relight's own renderers' Gaussian width (OpenLIME ignores it); fit: OpenLIME's mean
  /// (planes + 1) x lights x 3 bytes, entry (p, i, k) at (p * lights + i) * 3 + k, as info.json's "basis".
  std::vector<uint8_t> basis;
  std::vector<double> range, scale, bias;  // per plane, as materials[0]
  /// planes x (height x width) coefficient bytes, row-major from the top row (what the JPEGs decode to).
  std::vector<std::vector<uint8_t>> coefficient_bytes;
  /// planes / 3 encoded JPEGs (plane_<j>.jpg) whose decoding is coefficient_bytes: written as they are, so the
  /// files hold exactly what was evaluated.
  std::vector<std::string> plane_jpeg;
  int jpeg_quality = 95;

  /// The table entry (p, i, k) as the viewers dequantise it: byte / 255 for p = 0, (byte - 127) / range[p - 1].
  double table(int p, int i, int k) const;
};

/// Whose interpolation weights to render with.
enum class RbfWeights {
  kOpenLime,    // openlime.js AdaptiveRBF(samples, alpha 8): what OpenLIME shows
  kRelightCli,  // relight's Rti::lightWeightsRbf: exp(-|l - l_i|^2 / sigma^2), weights below 0.001 dropped
};

/// OpenLIME's AdaptiveRBF kernel width at `light`: alpha 8 over the smooth minimum distance to `lights`.
double openlime_epsilon(const std::vector<Vec3d>& lights, const Vec3d& light);

/// The interpolation weights over `lights` for the unit direction `light` (they sum to 1).
std::vector<double> rbf_weights(const std::vector<Vec3d>& lights, const Vec3d& light, RbfWeights kind,
                                double sigma = 0.125);

/// The image the viewer shows under `light` (unit; OpenLIME's setLight takes x, y and sets z = sqrt(1 - x^2 - y^2)):
/// CV-free, 3 floats per texel (R G B) in display codes 0..255 before the 8-bit framebuffer's rounding, rows from
/// the top, clamped to [0, 255] as the canvas does. kRelightCli also truncates to integers as relight-cli's
/// renderer does (its (int) casts), so its result is comparable byte for byte with relight-cli -L.
std::vector<float> render_rbf(const RbfBasis& basis, const Vec3d& light, RbfWeights kind = RbfWeights::kOpenLime);

struct RbfFitOptions {
  int planes = 9;  // relight-cli's default; a multiple of 3 (OpenLIME reads three planes per JPEG), 3..48
  DisplayEncoding encoding = DisplayEncoding::kCodes;
  /// Tikhonov weight of the table deconvolution, relative to the interpolation matrix's largest squared singular
  /// value (1); < 0: no deconvolution, the eigenvectors themselves are the table (what relight-cli writes).
  double deconvolution = 1e-3;
  int pca_texels = 16384;     // texels sampled for the covariance (evenly over the map)
  std::vector<int> held_out;  // observation-map views left out of the fit (their lights are not in the table)
  int jpeg_quality = 95;      // 1..100
  int threads = 0;            // 0: hardware concurrency
  std::function<void(const std::string& stage, int done, int total)> on_progress;
};

/// Fits the basis to every texel of an observation map (vdrig rti import), quantised as write_relight_rbf will
/// write it; the coefficient planes go through the JPEG encoder and back, so `coefficient_bytes` are what a
/// viewer decodes. Errors: kInvalidArgument (planes, held-out views, fewer lights than planes + 1), the reader's
/// kCorrupt/kIo.
Result<RbfBasis> fit_rbf_basis(const fitting::ObsMapReader& obs, const RbfFitOptions& options);
/// The same fit straight from a stack's photographs (its .lp, or a folder holding one), the codes being the display
/// values (options.encoding must be kCodes), read a band of rows at a time as `vdrig rti fit STACK` reads them
/// (stack_fit.hpp), twice: once for the PCA, once for the coefficients. Errors as fit_stack's, and as above.
Result<RbfBasis> fit_rbf_basis(const std::filesystem::path& stack, const RbfFitOptions& options);

/// Writes `basis` as a relight folder: info.json (type "rbf", colorspace "mrgb", lights, sigma, nplanes, basis,
/// materials [{range, scale, bias}]) and plane_<j>.jpg (4:4:4). kIo/kNoSpace when writing fails.
Status write_relight_rbf(const RbfBasis& basis, const std::filesystem::path& out);

/// Reads a relight folder (or its info.json) of type "rbf" and colorspace "mrgb", as relight-cli or
/// write_relight_rbf writes it, planes decoded by OpenCV's JPEG decoder. kNotFound, kCorrupt (malformed JSON,
/// sizes that disagree), kUnsupported (another type or colour space).
Result<RbfBasis> read_relight_rbf(const std::filesystem::path& folder);

/// `basis` as a parameter map of `model` (linear in shared directions: hsh:N, ptm:rgb, sh-*:N; kInvalidArgument
/// otherwise), for `vdrig view`, `render`, `compare` (vdrig has no rbf model): each texel's least-squares fit of what
/// OpenLIME shows at the basis's own lights (render_rbf before the canvas's clamp; values in [0, 1] units). Lossy:
/// rms.R/G/B hold each texel's RMS distance from that rendering at those lights, in [0, 1] units.
Result<fitting::ParameterMap> rbf_parameter_map(const RbfBasis& basis, const fitting::ModelPtr& model);

}  // namespace vdrig::rti
