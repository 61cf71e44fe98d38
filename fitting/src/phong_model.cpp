#include "vdrig/fitting/phong_model.hpp"

#include <algorithm>
#include <atomic>
#include <limits>

#include <fmt/format.h>

#include "tile_bytes.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/tiled_fit.hpp"

namespace vdrig::fitting {
namespace {

const char* kRgb[3] = {"R", "G", "B"};
const char* kXyz[3] = {"x", "y", "z"};
constexpr int kMaxLobes = 4;

std::string lobe_channel(const char* base, int k, const char* c) {
  return std::string(base) + std::to_string(k) + "." + c;
}

/// Parameter offsets of the layout of PhongModel::channels().
struct Layout {
  int lobes;
  bool shared;
  int per_lobe() const { return shared ? 6 : 7; }
  int ks(int k, int c) const { return 3 + per_lobe() * k + c; }
  int direction(int k, int c) const { return 3 + per_lobe() * k + 3 + c; }
  int shininess(int k) const { return shared ? 3 + 6 * lobes : 3 + 7 * k + 6; }
};

Result<ModelPtr> parse_phong(const std::string& settings) {
  const auto colon = settings.find(':');
  std::string lobes = settings.substr(0, colon);
  const std::string option = colon == std::string::npos ? "" : settings.substr(colon + 1);
  if (!option.empty() && option != "per-lobe-m")
    return make_error(ErrorCode::kInvalidArgument, "unknown option \"" + option + "\"");
  if (lobes.empty()) lobes = "1";
  const bool shared = option.empty();
  if (lobes == "auto") return ModelPtr(std::make_shared<PhongModel>(0, true, shared));
  if (lobes.size() != 1 || lobes[0] < '1' || lobes[0] > '0' + kMaxLobes)
    return make_error(ErrorCode::kInvalidArgument, "lobes must be 1..4 or auto");
  return ModelPtr(std::make_shared<PhongModel>(lobes[0] - '0', false, shared));
}

/// A texel's Phong fit, kept until the map's lobe count is known (phong:auto) and the shared-lights pass has run.
struct StagedPhong {
  PhongParams params;
  FitQuality quality;
  Vec3d holdout = Vec3d::Zero();
  double bic = std::numeric_limits<double>::infinity();  // of the fit as minimised (phong_bic)
  bool shared_lights = false;                            // directions from the estimated lights
  int capped_lobes = 0;                                  // lobes whose shininess the sampling bounds (PhongFit)
};

/// BIC of a fit of `obs` (as phong_bic: RSS of the residuals as minimised = 2 cost, n = 3 x observations).
double fit_bic(const PhongFit& fit, const TexelObservations& obs, int parameters) {
  const int n = static_cast<int>(3 * obs.size());
  double sq = 0;
  for (size_t i = 0; i < obs.size(); ++i) sq += obs.radiance[i].cast<double>().squaredNorm();
  return phong_bic(2.0 * fit.cost, n, parameters, std::sqrt(sq / std::max(1, n)));
}

/// The rays toward the lights of one texel's fitted lobes that carry energy (lights.hpp), in lobe order.
std::vector<LobeRay> texel_lobe_rays(const StagedPhong& st, int s, int t, const ObservationMapSpec& spec) {
  std::vector<LobeRay> rays;
  const PhongParams& p = st.params;
  for (const PhongLobe& lobe : p.lobes)
    // A lobe far below the diffuse level is the fit's way of saying "no highlight": its direction is noise.
    if (lobe.ks.maxCoeff() > 1e-3 * std::max(p.kd.maxCoeff(), 1e-12))
      rays.push_back(
          lobe_ray(texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm), lobe.direction));
  return rays;
}

/// At most `max_rays` of them, an even subsample (RANSAC needs many rays, not all of a 512 x 512 map's).
std::vector<LobeRay> subsample_rays(std::vector<LobeRay> rays, size_t max_rays) {
  if (rays.size() <= max_rays) return rays;
  std::vector<LobeRay> subsample;
  for (size_t k = 0; k < max_rays; ++k) subsample.push_back(rays[k * rays.size() / max_rays]);
  return subsample;
}

/// Rays toward the lights from every texel, in texel order (t * S + s), subsampled.
std::vector<LobeRay> lobe_rays(const std::vector<StagedPhong>& staged, const ObservationMapSpec& spec,
                               size_t max_rays) {
  std::vector<LobeRay> rays;
  for (size_t i = 0; i < staged.size(); ++i) {
    const int s = static_cast<int>(i % spec.texels_s), t = static_cast<int>(i / spec.texels_s);
    for (const LobeRay& r : texel_lobe_rays(staged[i], s, t, spec)) rays.push_back(r);
  }
  return subsample_rays(std::move(rays), max_rays);
}

}  // namespace

PhongModel::PhongModel(int lobes, bool auto_lobes, bool shared_shininess)
    : lobes_(lobes), auto_lobes_(auto_lobes), shared_shininess_(shared_shininess) {
  VDRIG_CHECK(lobes >= (auto_lobes ? 0 : 1) && lobes <= kMaxLobes, "PhongModel: lobes out of range");
}

ModelPtr PhongModel::with_lobes(int lobes) const {
  return std::make_shared<PhongModel>(lobes, auto_lobes_, shared_shininess_);
}

std::string PhongModel::name() const {
  return "phong:" + (auto_lobes_ ? std::string("auto") : std::to_string(lobes_)) +
         (shared_shininess_ ? "" : ":per-lobe-m");
}

std::vector<std::string> PhongModel::channels() const {
  std::vector<std::string> names;
  for (auto c : kRgb) names.push_back(std::string("kd.") + c);
  for (int k = 0; k < lobes_; ++k) {
    for (auto c : kRgb) names.push_back(lobe_channel("ks", k, c));
    for (auto c : kXyz) names.push_back(lobe_channel("r", k, c));
    if (!shared_shininess_) names.push_back("m" + std::to_string(k));
  }
  if (shared_shininess_) names.push_back("m");
  if (auto_lobes_) names.push_back("lobes");
  return names;
}

void PhongModel::write_attributes(std::map<std::string, double>& number_attributes) const {
  number_attributes["vdrig.lobes"] = lobes_;
  number_attributes["vdrig.shared_m"] = shared_shininess_ ? 1 : 0;
}

Result<ModelPtr> PhongModel::with_attributes(const std::map<std::string, double>& number_attributes) const {
  if (!auto_lobes_) return shared_from_this();
  const auto it = number_attributes.find("vdrig.lobes");
  // Checked as a double first: casting NaN or 1e300 to int is undefined behaviour (found by fuzz_parameter_map).
  const double lobes = it == number_attributes.end() ? 0.0 : it->second;
  if (!(lobes >= 1 && lobes <= kMaxLobes)) return make_error(ErrorCode::kCorrupt, "bad vdrig.lobes");
  return with_lobes(static_cast<int>(lobes));
}

PhongParams PhongModel::params_of(std::span<const double> p) const {
  VDRIG_CHECK(static_cast<int>(p.size()) == parameter_count(), "PhongModel: wrong parameter count");
  const Layout at{lobes_, shared_shininess_};
  PhongParams params;
  for (int c = 0; c < 3; ++c) params.kd[c] = p[c];
  for (int k = 0; k < lobes_; ++k) {
    PhongLobe l;
    for (int c = 0; c < 3; ++c) {
      l.ks[c] = p[at.ks(k, c)];
      l.direction[c] = p[at.direction(k, c)];
    }
    l.shininess = p[at.shininess(k)];
    params.lobes.push_back(l);
  }
  return params;
}

std::vector<double> PhongModel::parameters_of(const PhongParams& params) const {
  VDRIG_CHECK(static_cast<int>(params.lobes.size()) <= lobes_, "Phong lobes exceed the map's");
  const Layout at{lobes_, shared_shininess_};
  std::vector<double> p(static_cast<size_t>(parameter_count()), 0.0);
  for (int c = 0; c < 3; ++c) p[c] = params.kd[c];
  for (int k = 0; k < lobes_; ++k) {
    // A texel that needs fewer lobes than the map stores has zero energy in the rest.
    const PhongLobe lobe = k < static_cast<int>(params.lobes.size()) ? params.lobes[k] : PhongLobe{};
    for (int c = 0; c < 3; ++c) {
      p[at.ks(k, c)] = lobe.ks[c];
      p[at.direction(k, c)] = lobe.direction[c];
    }
    if (!shared_shininess_) p[at.shininess(k)] = lobe.shininess;
  }
  if (shared_shininess_) p[at.shininess(0)] = params.lobes.empty() ? 1.0 : params.lobes[0].shininess;
  if (auto_lobes_) p.back() = static_cast<double>(params.lobes.size());
  return p;
}

std::string PhongModel::check_parameters(std::span<const double> parameters) const {
  const Layout layout{lobes_, shared_shininess_};
  for (int k = 0; k < (shared_shininess_ ? 1 : lobes_); ++k) {
    const double m = parameters[layout.shininess(k)];
    if (m < 0) return "Phong exponent " + channels()[layout.shininess(k)] + " is negative (" + std::to_string(m) + ")";
  }
  return {};
}

Vec3d PhongModel::evaluate(std::span<const double> parameters, const Vec3d& v) const {
  return params_of(parameters).evaluate(v);
}

std::string PhongModel::glsl(const std::function<std::string(int parameter)>& parameter) const {
  const Layout at{lobes_, shared_shininess_};
  auto vec3 = [&](int i0, int i1, int i2) {
    return "vec3(" + parameter(i0) + ", " + parameter(i1) + ", " + parameter(i2) + ")";
  };
  std::string s = "vec3 model(ivec2 t, vec3 v) {\n";
  s += "  vec3 I = " + vec3(0, 1, 2) + ";\n";
  for (int k = 0; k < lobes_; ++k) {
    s += "  {\n    vec3 r = " + vec3(at.direction(k, 0), at.direction(k, 1), at.direction(k, 2)) + ";\n";
    s += "    vec3 ks = " + vec3(at.ks(k, 0), at.ks(k, 1), at.ks(k, 2)) + ";\n";
    s +=
        "    float c = dot(v, r);\n    if (c > 0.0) I += ks * exp(" + parameter(at.shininess(k)) + " * log(c));\n  }\n";
  }
  s += "  return I;\n}\n";
  return s;
}

namespace {

/// What fit_map and the tiled fit share: the checked options and the per-texel steps of both passes.
struct PhongMapFit {
  const PhongModel* model = nullptr;
  MapFitOptions options;  // a copy: the tiled fit outlives the caller's
  ObservationMapSpec spec;
  PhongFitOptions phong;
  bool auto_lobes = false;

  /// The options checked as fit_map has always checked them.
  static Result<PhongMapFit> make(const PhongModel& model, const MapFitOptions& options,
                                  const ObservationMapSpec& spec) {
    PhongMapFit f;
    f.model = &model;
    f.options = options;
    f.spec = spec;
    f.auto_lobes = model.auto_lobes();
    f.phong = options.phong;
    f.phong.lobes = f.auto_lobes ? kMaxLobes : model.lobes();
    f.phong.shared_shininess = model.shared_shininess();
    std::string why;
    if (!f.phong.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
    if (options.shared_lights) {
      if (!options.phong.fixed_directions.empty())
        return make_error(ErrorCode::kInvalidArgument, "shared_lights sets each texel's directions itself");
      if (!options.lights.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
    }
    if (f.auto_lobes && !options.phong.fixed_directions.empty())
      return make_error(ErrorCode::kInvalidArgument, "phong:auto does not take fixed directions");
    return f;
  }

  /// Pass 1: the texel on its own.
  void fit_free(const TexelObservations& texel, const TexelObservations& held, StagedPhong* st) const {
    const bool enough = static_cast<int>(texel.size()) >= options.min_observations;
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    if (enough) {
      const PhongFit fit = auto_lobes ? fit_phong_auto(texel, phong, kMaxLobes) : fit_phong(texel, phong);
      st->params = fit.params;
      q = fit.quality;
      if (held.size()) hq = measure_quality(fit.params, held);
      st->bic = fit_bic(fit, texel,
                        phong_parameter_count(static_cast<int>(fit.params.lobes.size()), phong.shared_shininess,
                                              !phong.fixed_directions.empty()));
      st->capped_lobes = fit.capped_lobes;
    }
    st->quality = q;
    st->holdout = hq.rms;
  }

  /// Pass 2: the texel refitted with its lobes at the lights' mirror directions; true when the refit replaced *st.
  bool refit(int s, int t, const TexelObservations& texel, const TexelObservations& held,
             const std::vector<EstimatedLight>& lights, StagedPhong* st) const {
    if (static_cast<int>(texel.size()) < options.min_observations) return false;
    const Vec3d p = texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
    PhongFitOptions fixed = phong;
    fixed.lobes = static_cast<int>(lights.size());
    fixed.fixed_directions.clear();
    for (const EstimatedLight& l : lights) fixed.fixed_directions.push_back(mirror_direction_at(l, p));
    // A light below the texel's horizon leaves no highlight to fit: keep the free fit.
    for (const Vec3d& d : fixed.fixed_directions)
      if (!(d.z() >= 0.0)) return false;
    const PhongFit fit = fit_phong(texel, fixed);
    const double bic = fit_bic(
        fit, texel, phong_parameter_count(static_cast<int>(fit.params.lobes.size()), fixed.shared_shininess, true));
    if (!(bic <= st->bic)) return false;
    st->capped_lobes = fit.capped_lobes;
    st->params = fit.params;
    st->quality = fit.quality;
    st->holdout = held.size() ? measure_quality(fit.params, held).rms : Vec3d::Zero();
    st->bic = bic;
    st->shared_lights = true;
    return true;
  }

  LightEstimationOptions light_options() const {
    LightEstimationOptions l = options.lights;
    l.max_lights = std::min(l.max_lights, auto_lobes ? kMaxLobes : phong.lobes);
    return l;
  }

  /// The map of the staged texels (staged(i) is texel i = t * S + s).
  ParameterMap build_map(const std::function<const StagedPhong&(int i)>& staged,
                         const std::string& lights_attribute) const {
    const int total = spec.texels_s * spec.texels_t;
    int map_lobes = model->lobes();
    if (auto_lobes) {
      map_lobes = 1;
      for (int i = 0; i < total; ++i) map_lobes = std::max(map_lobes, static_cast<int>(staged(i).params.lobes.size()));
    }
    const auto m = std::static_pointer_cast<const PhongModel>(model->with_lobes(map_lobes));
    ParameterMap map(m, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
    const bool shared_lights = options.shared_lights;
    const bool holding_out = !options.held_out.empty();
    if (shared_lights) {
      map.add_channel("shared_lights");
      map.image().string_attributes["vdrig.shared_lights"] = lights_attribute;
    }
    // Where the map guesses: lobes whose width the sampling bounds (phong.hpp, "Between the samples").
    const bool support_bounded = phong.lobe_support > 0;
    if (support_bounded) map.add_channel(kCappedLobesChannel);
    for (int i = 0; i < total; ++i) {
      const int s = i % spec.texels_s, t = i / spec.texels_s;
      const StagedPhong& st = staged(i);
      map.set_parameters(s, t, m->parameters_of(st.params));
      if (shared_lights) map.at("shared_lights", s, t) = st.shared_lights ? 1.0f : 0.0f;
      if (support_bounded) map.at(kCappedLobesChannel, s, t) = static_cast<float>(st.capped_lobes);
      map.set_quality(s, t, st.quality);
      if (holding_out) map.set_holdout_rms(s, t, st.holdout);
    }
    return map;
  }
};

/// The lights from the lobe rays (estimate_point_lights), logged; "vdrig.shared_lights" of them in *attribute.
Result<std::vector<EstimatedLight>> estimate_and_log_lights(const std::vector<LobeRay>& rays,
                                                            const LightEstimationOptions& options,
                                                            std::string* attribute) {
  auto lights = estimate_point_lights(rays, options);
  if (!lights) return lights.error();
  auto logger = log::get("fitting");
  attribute->clear();
  if (lights->empty()) {
    logger->warn("shared lights: no light explains enough texels' lobes; every texel keeps its own fit");
    return lights;
  }
  for (const EstimatedLight& l : lights.value()) {
    const Vec3d& v = l.at_infinity ? l.direction : l.position_mm;
    *attribute += fmt::format("{}{} {:.3f} {:.3f} {:.3f}", attribute->empty() ? "" : "; ",
                              l.at_infinity ? "direction" : "point", v.x(), v.y(), v.z());
  }
  for (const EstimatedLight& l : lights.value())
    if (l.at_infinity)
      logger->info("shared lights: distant light toward ({:.3f}, {:.3f}, {:.3f}), {} texel lobes, rms {:.2f} deg",
                   l.direction.x(), l.direction.y(), l.direction.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
    else
      logger->info("shared lights: point light at ({:.1f}, {:.1f}, {:.1f}) mm, {} texel lobes, rms {:.2f} deg",
                   l.position_mm.x(), l.position_mm.y(), l.position_mm.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
  return lights;
}

constexpr size_t kMaxLobeRays = 20000;

}  // namespace

Result<ParameterMap> PhongModel::fit_map(const MapFitContext& context) const {
  auto f = PhongMapFit::make(*this, context.options, context.spec);
  if (!f) return f.error();
  const ObservationMapSpec& spec = context.spec;
  const int total = spec.texels_s * spec.texels_t;
  const bool shared_lights = context.options.shared_lights;
  const int passes = shared_lights ? 2 : 1;

  // Texels are staged and the map built at the end: phong:auto learns the map's lobe count only then, and the
  // shared-lights pass may replace a texel's fit.
  std::vector<StagedPhong> staged(total);

  // Pass 1: every texel on its own.
  VDRIG_TRY(context.for_each_texel(
      0, passes, [&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
        f->fit_free(texel, held, &staged[static_cast<size_t>(t) * spec.texels_s + s]);
      }));

  // Pass 2 (shared lights): the lights from every texel's lobes, then each texel refitted with its lobes pointing at
  // them; the refit replaces the free fit where its BIC is lower (it has 2 parameters fewer per lobe, so it wins
  // wherever it fits as well, and loses where the texel's normal or light differs, e.g. a bumpy patch).
  std::string lights_attribute;
  if (shared_lights) {
    auto lights = estimate_and_log_lights(lobe_rays(staged, spec, kMaxLobeRays), f->light_options(), &lights_attribute);
    if (!lights) return lights.error();
    if (!lights->empty()) {
      std::atomic<int> replaced{0};
      VDRIG_TRY(context.for_each_texel(
          1, passes, [&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
            if (f->refit(s, t, texel, held, lights.value(), &staged[static_cast<size_t>(t) * spec.texels_s + s]))
              replaced.fetch_add(1);
          }));
      log::get("fitting")->info("shared lights: {} of {} texels fitted with the lights' directions", replaced.load(),
                                total);
    }
  }
  return f->build_map([&](int i) -> const StagedPhong& { return staged[static_cast<size_t>(i)]; }, lights_attribute);
}

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

void register_phong_model(ModelRegistry& registry) { registry.add({"phong", "phong:K|phong:auto", parse_phong}); }

PhongParams phong_texel(const ParameterMap& map, int s, int t) {
  const auto* phong = dynamic_cast<const PhongModel*>(&map.model());
  VDRIG_CHECK(phong, "phong_texel on a " + map.model().name() + " map");
  return phong->params_of(map.parameters(s, t));
}

void set_phong_texel(ParameterMap& map, int s, int t, const PhongParams& params) {
  const auto* phong = dynamic_cast<const PhongModel*>(&map.model());
  VDRIG_CHECK(phong, "set_phong_texel on a " + map.model().name() + " map");
  map.set_parameters(s, t, phong->parameters_of(params));
}

}  // namespace vdrig::fitting
