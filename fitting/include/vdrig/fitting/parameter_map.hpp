// ParameterMap: a fitted model per texel, stored as one multi-channel OpenEXR file.
//
// Channels (float): Phong  kd.R kd.G kd.B, ks<k>.R/G/B, r<k>.x/y/z, m (shared) or m<k> (per lobe), k = 0..K-1;
//                   phong:auto also "lobes" (the count chosen for the texel; its unused lobes are zero, K = the
//                   largest count chosen anywhere);
//                   SH / HSH  sh.R.<ii> / hsh.R.<ii> (coefficient index ii = l(l+1)+m, two digits), same for G, B.
//   quality         rms.R/G/B (root mean square residual), mpe.R/G/B (mean percentage error), n (samples used),
//                   holdout.R/G/B (RMS on held-out views, when views were held out).
// Header attributes: vdrig.model ("phong", "sh-zh", "sh-lsop", "sh-ls", "hsh"), vdrig.lobes, vdrig.shared_m,
//                    vdrig.bands, vdrig.surface_width_mm, vdrig.surface_height_mm, vdrig.source_session.
// Texel (s, t) is pixel (x = s, y = t) of the image, so row 0 holds the texels at the smallest y.
#pragma once

#include <filesystem>
#include <string>

#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/phong.hpp"

namespace vdrig::fitting {

/// An SH (sh.hpp) or HSH (hsh.hpp) expansion of RGB radiance: coeffs is n^2 x 3 (column = channel).
struct ShExpansion {
  bool hemispherical = false;
  Eigen::MatrixXd coeffs;

  /// RGB radiance toward unit direction v (HSH: directions below the horizon are treated as on it).
  Vec3d evaluate(const Vec3d& v) const;
};

inline constexpr int kParameterMapFormatVersion = 1;

/// Which model a map holds.
struct ModelDescriptor {
  std::string kind = "phong";  // "phong", "sh-zh", "sh-lsop", "sh-ls", "hsh"
  int lobes = 1;               // Phong; 0 = "auto" not resolved yet
  bool auto_lobes = false;     // phong:auto (the map stores `lobes` = the largest count chosen and a "lobes" channel)
  bool shared_shininess = true;
  int bands = 0;  // SH / HSH: n bands, n^2 coefficients per channel

  /// Parses "phong:1", "phong:auto", "phong:2:per-lobe-m", "sh-zh:6", "sh-lsop:6", "sh-ls:6", "hsh:5".
  static Result<ModelDescriptor> parse(const std::string& spec);
  std::string to_string() const;
  int coefficients_per_channel() const { return bands * bands; }
};

class ParameterMap {
 public:
  ParameterMap() = default;
  ParameterMap(const ModelDescriptor& model, int texels_s, int texels_t, double width_mm, double height_mm);

  const ModelDescriptor& model() const { return model_; }
  int texels_s() const { return image_.width; }
  int texels_t() const { return image_.height; }
  double width_mm() const { return width_mm_; }
  double height_mm() const { return height_mm_; }
  ExrImage& image() { return image_; }
  const ExrImage& image() const { return image_; }

  /// Channel value at texel (s, t); the channel must exist.
  float& at(const std::string& channel, int s, int t);
  float at(const std::string& channel, int s, int t) const;
  bool has(const std::string& channel) const { return image_.find(channel) >= 0; }

  void set_phong(int s, int t, const PhongParams& params);
  PhongParams phong(int s, int t) const;
  void set_quality(int s, int t, const FitQuality& q);
  /// SH / HSH coefficients (n^2 x 3) of texel (s, t).
  void set_sh(int s, int t, const Eigen::MatrixXd& coeffs);
  ShExpansion sh(int s, int t) const;
  /// Adds a zero channel if absent (e.g. holdout.R/G/B); existing channels are kept.
  void add_channel(const std::string& name);
  /// holdout.R/G/B of texel (s, t) (adds the channels when missing; not thread-safe then).
  void set_holdout_rms(int s, int t, const Vec3d& rms);

  /// RGB radiance of texel (s, t) toward unit direction v (surface frame), whatever the model.
  Vec3d evaluate(int s, int t, const Vec3d& v) const;

  void set_source_session(const std::string& s) { image_.string_attributes["vdrig.source_session"] = s; }

  Status write(const std::filesystem::path& path, ExrPixelType type = ExrPixelType::kFloat) const;
  /// Largest map read(): its float channels may take at most this much (an 8192 x 8192 SH map is over 10 GB).
  static constexpr size_t kMaxReadBytes = size_t{4} << 30;
  /// Reads a map written by write(). Errors: kInvalidArgument for a map over kMaxReadBytes (refused from the
  /// header, before allocating); kCorrupt for a file that is not a parameter map, a NaN or infinite value in any
  /// channel, or a value out of its model's range (Phong: m >= 0).
  static Result<ParameterMap> read(const std::filesystem::path& path);

 private:
  void index_coefficients();

  ModelDescriptor model_;
  double width_mm_ = 0, height_mm_ = 0;
  ExrImage image_;
  std::vector<int> coeff_channel_;  // SH / HSH: image channel of coefficient i of colour c at [c * n^2 + i]
};

}  // namespace vdrig::fitting
