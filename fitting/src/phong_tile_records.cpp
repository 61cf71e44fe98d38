// PhongModel's tiled fit (tiled_fit.hpp): a tile's record is its staged texels at full precision; with shared lights
// the pass state between the passes is the lights, estimated from every tile's lobe rays in map texel order, as
// fit_map gathers them, so that the assembled map is fit_map's bit for bit.
#include <algorithm>

#include "phong_map_fit.hpp"
#include "tile_bytes.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/tiled_fit.hpp"
namespace vdrig::fitting {
using namespace phong_map_fit;
namespace {

void put_staged(BytesOut& out, const StagedPhong& st) {
  for (int c = 0; c < 3; ++c) out.put<double>(st.params.kd[c]);
  out.put<uint8_t>(static_cast<uint8_t>(st.params.lobes.size()));
  for (const PhongLobe& l : st.params.lobes) {
    for (int c = 0; c < 3; ++c) out.put<double>(l.ks[c]);
    for (int c = 0; c < 3; ++c) out.put<double>(l.direction[c]);
    out.put<double>(l.shininess);
  }
  for (int c = 0; c < 3; ++c) out.put<double>(st.quality.rms[c]);
  for (int c = 0; c < 3; ++c) out.put<double>(st.quality.mean_percent[c]);
  out.put<int32_t>(st.quality.samples);
  for (int c = 0; c < 3; ++c) out.put<double>(st.holdout[c]);
  out.put<double>(st.bic);
  out.put<uint8_t>(st.shared_lights ? 1 : 0);
  out.put<uint8_t>(static_cast<uint8_t>(st.capped_lobes));
}

StagedPhong get_staged(BytesIn& in) {
  StagedPhong st;
  for (int c = 0; c < 3; ++c) st.params.kd[c] = in.get<double>();
  const int lobes = in.get<uint8_t>();
  for (int k = 0; k < lobes && k < kMaxLobes && !in.failed(); ++k) {
    PhongLobe l;
    for (int c = 0; c < 3; ++c) l.ks[c] = in.get<double>();
    for (int c = 0; c < 3; ++c) l.direction[c] = in.get<double>();
    l.shininess = in.get<double>();
    st.params.lobes.push_back(l);
  }
  if (lobes > kMaxLobes) in.fail();
  for (int c = 0; c < 3; ++c) st.quality.rms[c] = in.get<double>();
  for (int c = 0; c < 3; ++c) st.quality.mean_percent[c] = in.get<double>();
  st.quality.samples = in.get<int32_t>();
  for (int c = 0; c < 3; ++c) st.holdout[c] = in.get<double>();
  st.bic = in.get<double>();
  st.shared_lights = in.get<uint8_t>() != 0;
  st.capped_lobes = in.get<uint8_t>();
  return st;
}

/// A tile's staged texels, row-major inside the tile.
Result<std::vector<StagedPhong>> read_staged(const TileRect& rect, const TileBytes& record) {
  BytesIn in(record);
  std::vector<StagedPhong> staged;
  const size_t n = static_cast<size_t>(rect.width) * rect.height;
  staged.reserve(n);
  for (size_t j = 0; j < n && !in.failed(); ++j) staged.push_back(get_staged(in));
  VDRIG_TRY(in.finish("Phong tile " + std::to_string(rect.index)));
  return staged;
}

TileBytes write_staged(const std::vector<StagedPhong>& staged) {
  TileBytes record;
  BytesOut out(record);
  for (const StagedPhong& st : staged) put_staged(out, st);
  return record;
}

class PhongTiledFit final : public ModelTiledFit {
 public:
  explicit PhongTiledFit(PhongMapFit f) : f_(std::move(f)) {}

  int passes() const override { return f_.options.shared_lights ? 2 : 1; }

  Result<TileBytes> fit_tile(int pass, const TileWork& work, const TileBytes* previous) override {
    const TileRect& r = work.rect;
    std::vector<StagedPhong> staged;
    if (pass == 0) {
      staged.resize(static_cast<size_t>(r.width) * r.height);
    } else {
      VDRIG_CHECK(previous, "the refit pass needs the tile's first-pass record");
      auto prior = read_staged(r, *previous);
      if (!prior) return prior.error();
      // No light found: every texel keeps its own fit (as fit_map, which then skips the refit).
      if (lights_.empty()) return *previous;
      staged = std::move(prior.value());
    }
    auto at = [&](int s, int t) -> StagedPhong& {
      return staged[static_cast<size_t>(t - r.t0) * r.width + (s - r.s0)];
    };
    VDRIG_TRY(
        work.for_each_texel([&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
          if (pass == 0)
            f_.fit_free(texel, held, &at(s, t));
          else
            f_.refit(s, t, texel, held, lights_, &at(s, t));
        }));
    return write_staged(staged);
  }

  /// The tile's lobe rays (lobe_rays' selection), each after its texel's index (u64) in the map.
  Result<TileBytes> summary(int, const TileRect& r, const TileBytes& record) const override {
    auto staged = read_staged(r, record);
    if (!staged) return staged.error();
    TileBytes out_bytes;
    BytesOut out(out_bytes);
    const ObservationMapSpec& spec = f_.spec;
    for (int j = 0; j < r.width * r.height; ++j) {
      const int s = r.s0 + j % r.width, t = r.t0 + j / r.width;
      for (const LobeRay& ray : texel_lobe_rays(staged.value()[static_cast<size_t>(j)], s, t, spec)) {
        out.put<uint64_t>(static_cast<uint64_t>(t) * spec.texels_s + s);
        for (int c = 0; c < 3; ++c) out.put<double>(ray.origin_mm[c]);
        for (int c = 0; c < 3; ++c) out.put<double>(ray.toward_light[c]);
        out.put<double>(ray.weight);
      }
    }
    return out_bytes;
  }

  /// The lights from every tile's rays in map texel order (as lobe_rays lists them), as fit_map estimates them.
  Result<TileBytes> pass_state(int, const std::vector<TileBytes>& summaries) override {
    std::vector<std::pair<uint64_t, LobeRay>> keyed;
    for (size_t k = 0; k < summaries.size(); ++k) {
      BytesIn in(summaries[k]);
      while (!in.at_end() && !in.failed()) {
        std::pair<uint64_t, LobeRay> e;
        e.first = in.get<uint64_t>();
        for (int c = 0; c < 3; ++c) e.second.origin_mm[c] = in.get<double>();
        for (int c = 0; c < 3; ++c) e.second.toward_light[c] = in.get<double>();
        e.second.weight = in.get<double>();
        keyed.push_back(e);
      }
      VDRIG_TRY(in.finish("lobe rays of tile " + std::to_string(k)));
    }
    // Stable: the rays of one texel keep their lobe order.
    std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<LobeRay> rays;
    rays.reserve(keyed.size());
    for (const auto& e : keyed) rays.push_back(e.second);
    auto lights =
        estimate_and_log_lights(subsample_rays(std::move(rays), kMaxLobeRays), f_.light_options(), &lights_attribute_);
    if (!lights) return lights.error();
    TileBytes state;
    BytesOut out(state);
    out.put_string(lights_attribute_);
    out.put<uint32_t>(static_cast<uint32_t>(lights->size()));
    for (const EstimatedLight& l : lights.value()) {
      for (int c = 0; c < 3; ++c) out.put<double>(l.position_mm[c]);
      out.put<uint8_t>(l.at_infinity ? 1 : 0);
      for (int c = 0; c < 3; ++c) out.put<double>(l.direction[c]);
      out.put<int32_t>(l.inliers);
      out.put<double>(l.rms_angle_rad);
    }
    return state;
  }

  Status set_pass_state(int, const TileBytes& state) override {
    BytesIn in(state);
    lights_attribute_ = in.get_string();
    const uint32_t n = in.get<uint32_t>();
    lights_.clear();
    for (uint32_t i = 0; i < n && !in.failed() && i < 64; ++i) {
      EstimatedLight l;
      for (int c = 0; c < 3; ++c) l.position_mm[c] = in.get<double>();
      l.at_infinity = in.get<uint8_t>() != 0;
      for (int c = 0; c < 3; ++c) l.direction[c] = in.get<double>();
      l.inliers = in.get<int32_t>();
      l.rms_angle_rad = in.get<double>();
      lights_.push_back(l);
    }
    return in.finish("shared lights state");
  }

  Result<ParameterMap> assemble(const std::vector<TileRect>& tiles,
                                const std::function<Result<TileBytes>(int tile)>& record) override {
    const ObservationMapSpec& spec = f_.spec;
    std::vector<StagedPhong> staged(static_cast<size_t>(spec.texels_s) * spec.texels_t);
    int replaced = 0;
    for (const TileRect& r : tiles) {
      auto bytes = record(r.index);
      if (!bytes) return bytes.error();
      auto tile = read_staged(r, bytes.value());
      if (!tile) return tile.error();
      for (int j = 0; j < r.width * r.height; ++j) {
        const StagedPhong& st = tile.value()[static_cast<size_t>(j)];
        replaced += st.shared_lights ? 1 : 0;
        staged[static_cast<size_t>(r.t0 + j / r.width) * spec.texels_s + r.s0 + j % r.width] = st;
      }
    }
    if (!lights_.empty())
      log::get("fitting")->info("shared lights: {} of {} texels fitted with the lights' directions", replaced,
                                staged.size());
    return f_.build_map([&](int i) -> const StagedPhong& { return staged[static_cast<size_t>(i)]; }, lights_attribute_);
  }

 private:
  PhongMapFit f_;
  std::vector<EstimatedLight> lights_;
  std::string lights_attribute_;
};

}  // namespace

Result<std::unique_ptr<ModelTiledFit>> PhongModel::tiled_fit(const MapFitOptions& options,
                                                             const ObservationMapSpec& spec) const {
  auto f = PhongMapFit::make(*this, options, spec);
  if (!f) return f.error();
  return std::unique_ptr<ModelTiledFit>(std::make_unique<PhongTiledFit>(std::move(f.value())));
}

}  // namespace vdrig::fitting
