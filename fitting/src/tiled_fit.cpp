#include "vdrig/fitting/tiled_fit.hpp"

#include <fmt/format.h>

#include "tile_bytes.hpp"

namespace vdrig::fitting {
namespace {

/// A map fitted tile by tile by the model's own fit_map on a map of the tile's size (texel coordinates shifted to
/// the tile's); a record is the tile map's channels: names, then w x h floats each.
class PerTexelTiledFit final : public ModelTiledFit {
 public:
  PerTexelTiledFit(ModelPtr model, const MapFitOptions& options, const ObservationMapSpec& spec, RectFit fit)
      : model_(std::move(model)), options_(options), spec_(spec), fit_(std::move(fit)) {}

  /// The model's fit_map on `rect`'s texels (none when `work` is null: the options are checked, nothing fitted).
  Result<ParameterMap> fit_rect(const TileRect& rect, const TileWork* work) const {
    ObservationMapSpec tile_spec = spec_;
    tile_spec.texels_s = rect.width;
    tile_spec.texels_t = rect.height;
    MapFitContext context{options_, tile_spec, work ? work->workers : 1, {}};
    context.for_each_texel = [&](int, int, const TexelVisitor& visit) -> Status {
      if (!work) return Status::ok();
      return work->for_each_texel(
          [&](int worker, int s, int t, const TexelObservations& fit, const TexelObservations& held) {
            visit(worker, s - rect.s0, t - rect.t0, fit, held);
          });
    };
    return fit_ ? fit_(context, rect, spec_) : model_->fit_map(context);
  }

  Result<TileBytes> fit_tile(int, const TileWork& work, const TileBytes*) override {
    auto map = fit_rect(work.rect, &work);
    if (!map) return map.error();
    const ExrImage& image = map->image();
    TileBytes record;
    BytesOut out(record);
    out.put<uint32_t>(static_cast<uint32_t>(image.channel_names.size()));
    for (size_t c = 0; c < image.channel_names.size(); ++c) {
      out.put_string(image.channel_names[c]);
      const cv::Mat& plane = image.channels[c];
      for (int y = 0; y < plane.rows; ++y) out.put_bytes(plane.ptr<float>(y), sizeof(float) * plane.cols);
    }
    return record;
  }

  Result<ParameterMap> assemble(const std::vector<TileRect>& tiles,
                                const std::function<Result<TileBytes>(int tile)>& record) override {
    ParameterMap map(model_, spec_.texels_s, spec_.texels_t, spec_.width_mm, spec_.height_mm);
    for (const TileRect& rect : tiles) {
      auto bytes = record(rect.index);
      if (!bytes) return bytes.error();
      BytesIn in(bytes.value());
      const uint32_t channels = in.get<uint32_t>();
      for (uint32_t c = 0; c < channels && !in.failed(); ++c) {
        const std::string name = in.get_string();
        if (in.failed()) break;
        // The tile maps add the same channels in the same order (holdout, loo) as the single-process map.
        map.add_channel(name);
        cv::Mat& plane = map.image().channels[static_cast<size_t>(map.image().find(name))];
        for (int y = 0; y < rect.height; ++y)
          in.get_bytes(plane.ptr<float>(rect.t0 + y) + rect.s0, sizeof(float) * rect.width);
      }
      VDRIG_TRY(in.finish("tile " + std::to_string(rect.index)));
    }
    return map;
  }

 private:
  ModelPtr model_;
  MapFitOptions options_;
  ObservationMapSpec spec_;
  RectFit fit_;  // empty: the model's fit_map
};

}  // namespace

Result<std::unique_ptr<ModelTiledFit>> per_texel_tiled_fit(ModelPtr model, const MapFitOptions& options,
                                                           const ObservationMapSpec& spec) {
  return per_texel_tiled_fit(std::move(model), options, spec, nullptr);
}

Result<std::unique_ptr<ModelTiledFit>> per_texel_tiled_fit(ModelPtr model, const MapFitOptions& options,
                                                           const ObservationMapSpec& spec, RectFit fit_rect) {
  auto fit = std::make_unique<PerTexelTiledFit>(std::move(model), options, spec, std::move(fit_rect));
  // The options are checked by the model's fit_map on a 1 x 1 map with no texel visited.
  auto checked = fit->fit_rect(TileRect{0, 0, 0, 1, 1}, nullptr);
  if (!checked) return checked.error();
  return std::unique_ptr<ModelTiledFit>(std::move(fit));
}

Result<std::unique_ptr<ModelTiledFit>> ReflectanceModel::tiled_fit(const MapFitOptions& options,
                                                                   const ObservationMapSpec& spec) const {
  return per_texel_tiled_fit(shared_from_this(), options, spec);
}

std::string fit_options_fingerprint(const MapFitOptions& o) {
  // {} formats doubles as the shortest text that reads back to the same value: equal text, equal options.
  std::string s = "model=" + (o.model ? o.model->name() : std::string("none"));
  s += fmt::format(";min_observations={};held_out=", o.min_observations);
  std::vector<int> held = o.held_out;
  std::sort(held.begin(), held.end());
  held.erase(std::unique(held.begin(), held.end()), held.end());
  for (size_t i = 0; i < held.size(); ++i) s += (i ? "," : "") + std::to_string(held[i]);
  s += fmt::format(";shared_lights={}", o.shared_lights);
  // Everything else the fit reads is the model's to say (its own options, the lights of a shared-lights pass): a
  // model's new option goes into its options_fingerprint, beside the option itself, not here.
  if (o.model) s += ";" + o.model->family() + "=" + o.model->options_fingerprint(o);
  return s;
}

}  // namespace vdrig::fitting
