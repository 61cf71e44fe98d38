// ParameterMap: a fitted reflectance model per texel, stored as one multi-channel OpenEXR file.
//
// Channels (float): the model's parameter channels (ReflectanceModel::channels(), e.g. kd.R or sh.R.05), then
//   quality         rms.R/G/B (root mean square residual), mpe.R/G/B (mean percentage error), n (samples used),
//                   holdout.R/G/B (RMS on held-out views, when views were held out).
//   A fit may add channels of its own (phong's "shared_lights").
// Header attributes: vdrig.model (the model's family), vdrig.model_spec (its full name), the model's own
//   attributes (ReflectanceModel::write_attributes), vdrig.surface_width_mm, vdrig.surface_height_mm,
//   vdrig.parameter_map_version, vdrig.source_session, vdrig.held_out_views (the observation-map views left out of
//   the fit, on which holdout.R/G/B were measured, comma-separated, when any; fit_map.hpp), vdrig.command (the
//   command that made the map, when a command did: vdrig fit, vdrig demo), vdrig.fit_seconds (a number: the fit's
//   wall time, kFitSecondsAttribute, when the command measured it; `vdrig report` shows it).
// Texel (s, t) is pixel (x = s, y = t) of the image, so row 0 holds the texels at the smallest y.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/fit_quality.hpp"
#include "vdrig/fitting/model.hpp"

namespace vdrig::fitting {

inline constexpr int kParameterMapFormatVersion = 1;
/// Number attribute: the wall time of the fit that made the map, seconds (vdrig fit, vdrig demo).
inline constexpr const char* kFitSecondsAttribute = "vdrig.fit_seconds";

class ParameterMap {
 public:
  ParameterMap() = default;
  /// A map of zeros. Precondition (checked): model->storable().
  ParameterMap(ModelPtr model, int texels_s, int texels_t, double width_mm, double height_mm);

  const ReflectanceModel& model() const { return *model_; }
  const ModelPtr& model_ptr() const { return model_; }
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

  /// The model's parameters of texel (s, t), in the order of model().channels().
  std::vector<double> parameters(int s, int t) const;
  /// Sets them (parameters.size() == model().parameter_count(), checked). Distinct texels may be set concurrently.
  void set_parameters(int s, int t, std::span<const double> parameters);
  /// Image channel index of model parameter i (for code reading the channels directly, e.g. the viewer).
  int parameter_channel(int i) const { return parameter_channel_.at(static_cast<size_t>(i)); }

  void set_quality(int s, int t, const FitQuality& q);
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
  /// header, before allocating); kCorrupt for a file that is not a parameter map of a registered model, lacks one of
  /// the model's channels, holds a NaN or infinite value in any channel, or a texel the model refuses
  /// (ReflectanceModel::check_parameters, e.g. a negative Phong exponent).
  static Result<ParameterMap> read(const std::filesystem::path& path);

 private:
  void index_parameters();

  ModelPtr model_;
  double width_mm_ = 0, height_mm_ = 0;
  ExrImage image_;
  std::vector<int> parameter_channel_;  // image channel of model parameter i, looked up once
};

/// The same for one texel's parameters of a ReflectanceModel.
FitQuality measure_quality(const ReflectanceModel& model, std::span<const double> parameters,
                           const TexelObservations& obs);

}  // namespace vdrig::fitting
