// Reflectance models: the one interface every model of a parameter map implements, and the registry that turns a
// model name ("phong:2", "sh-ls:6", ...) into a configured model. docs/models.md describes how to add a model.
//
// A model instance is immutable and fully configured by its name (lobe count, band count, fitting method); it is
// shared between maps, fits and renderers as a ModelPtr (always made with std::make_shared: the model hands out
// shared_from_this()). A texel's parameters are `parameter_count()` doubles in
// the order of `channels()`; the parameter map stores them as float channels of those names, so the names are the
// file format and must not change for an existing model.
#pragma once

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/obsmap.hpp"

namespace vdrig::fitting {

class ParameterMap;
class LinearFitOperator;
struct FitQuality;
struct MapFitOptions;
struct MapFitContext;
class ModelTiledFit;

class ReflectanceModel;
using ModelPtr = std::shared_ptr<const ReflectanceModel>;

/// A view-dependent term of a texel with a peak direction, as ReflectanceModel::lobes describes it: what callers that
/// compare a fit with a Phong-form truth (pipeline's eval) or look for a highlight (the texel inspector) need.
struct LobeSummary {
  Vec3d peak_rgb = Vec3d::Zero();    // the lobe's radiance at its peak, beyond the diffuse part (Phong: Ks)
  Vec3d direction = Vec3d::UnitZ();  // its peak direction, unit (Phong: r)
  double phong_exponent = 1.0;       // the Phong exponent m of the same width (Phong: m)
};

/// The basis a linear model's coefficients are in, for exporters to formats defined by their basis (rti/: .ptm,
/// .rti, relight): kNone for a model that is not a combination of one of these bases.
struct ModelBasis {
  enum class Kind { kNone, kPtmRgb, kPtmLrgb, kSh, kHsh };
  Kind kind = Kind::kNone;
  int bands = 0;  // kSh, kHsh: bands (bands^2 coefficients per colour); parameters are then per colour, in order
};

class ReflectanceModel : public std::enable_shared_from_this<ReflectanceModel> {
 public:
  ReflectanceModel() = default;
  ReflectanceModel(const ReflectanceModel& other) : std::enable_shared_from_this<ReflectanceModel>(other) {}
  ReflectanceModel& operator=(const ReflectanceModel&) = delete;
  virtual ~ReflectanceModel() = default;

  /// The registry name: the part of the model name before the first ':' ("phong", "sh-ls", "hsh"). Stored in a
  /// map's header as vdrig.model.
  virtual std::string family() const = 0;
  /// The full model name; ModelRegistry::parse(name()) gives an equal model. Stored as vdrig.model_spec.
  virtual std::string name() const = 0;

  /// Names of the parameter channels of one texel, in parameter order; unique, and none of the quality channels
  /// ParameterMap adds (rms.*, mpe.*, n, holdout.*). Empty while the model is not storable (see storable()).
  virtual std::vector<std::string> channels() const = 0;
  /// channels().size(), counted once (a model is immutable): evaluate() asks for it per call.
  int parameter_count() const {
    int count = parameter_count_.load(std::memory_order_relaxed);
    if (count < 0) {
      count = static_cast<int>(channels().size());
      parameter_count_.store(count, std::memory_order_relaxed);  // threads racing here store the same value
    }
    return count;
  }
  /// False for a model whose name leaves its channel layout open until a fit or a file decides it (phong:auto
  /// before the lobe count is known): such a model can be fitted but no map can hold it.
  virtual bool storable() const { return true; }

  /// Header attributes a map of this model carries besides vdrig.model and vdrig.model_spec.
  virtual void write_attributes(std::map<std::string, double>& number_attributes) const;
  /// The model as stored in a map with these header attributes (phong:auto reads its lobe count); kCorrupt when
  /// they are missing or inconsistent. The default: this model, unchanged.
  virtual Result<ModelPtr> with_attributes(const std::map<std::string, double>& number_attributes) const;

  /// RGB radiance toward unit direction v (surface frame) of a texel with these parameters
  /// (parameters.size() == parameter_count()).
  virtual Vec3d evaluate(std::span<const double> parameters, const Vec3d& v) const = 0;

  /// The problem with one texel's stored parameters (all finite) as a phrase ("m is negative (-2)"), or "" when the
  /// model can render them. ParameterMap::read refuses a map with any such texel rather than render garbage.
  virtual std::string check_parameters(std::span<const double> /*parameters*/) const { return {}; }

  // What the model says about a texel, so that no caller guesses it from the family's name (docs/models.md).

  /// True when the model has a term that does not depend on the direction (Phong's Kd): diffuse_part() gives it.
  virtual bool has_diffuse_part() const { return false; }
  /// That term's RGB radiance for a texel (has_diffuse_part() only; others: a broken invariant). Callers of models
  /// without one take the lowest radiance over the hemisphere instead.
  virtual Vec3d diffuse_part(std::span<const double> parameters) const;
  /// The texel's lobes as the map stores them (a lobe with zero peak included), in the model's order; empty for a
  /// model that has no lobes (SH, HSH, PTM). With has_diffuse_part(), pipeline's eval compares both with the
  /// simulator's Phong-form truth.
  virtual std::vector<LobeSummary> lobes(std::span<const double> /*parameters*/) const { return {}; }
  /// The direction of the texel's largest radiance. The default: the direction of the lobe with the largest
  /// peak_rgb sum when it is > 0, else the brightest (mean over RGB) direction of a 1-degree zenith x 2-degree
  /// azimuth grid of the hemisphere by evaluate().
  virtual Vec3d peak_direction(std::span<const double> parameters) const;

  /// A plausible texel for tests and examples (parameter_count() values), different for different seeds: one that
  /// check_parameters() accepts, with radiance of order 1 and well above 0 over the upper hemisphere (so that relative
  /// comparisons, e.g. GLSL against evaluate(), are meaningful). Needs storable().
  virtual std::vector<double> sample_parameters(unsigned seed) const = 0;
  /// A storable model of the same form for tests (phong:auto: with 2 lobes); the default: this model.
  virtual ModelPtr storable_sample() const { return shared_from_this(); }

  /// The basis of the parameters for exporters (rti/export.hpp); the default: none.
  virtual ModelBasis coefficient_basis() const { return {}; }

  /// GLSL source of `vec3 model(ivec2 t, vec3 v)`: the same radiance as evaluate() for texel t toward unit v, where
  /// `parameter(i)` is a GLSL float expression reading parameter i of texel t. The viewer compiles it into its
  /// fragment shader.
  virtual std::string glsl(const std::function<std::string(int parameter)>& parameter) const = 0;

  /// True when the fit is a fixed linear operator of the observed values for a given set of directions, so texels
  /// that share their directions share one operator (fit_operator) and are fitted as one matrix product.
  virtual bool linear_in_shared_directions() const { return false; }
  /// That operator (parameter_count() / 3 rows per colour channel, one column per direction) for the fit options;
  /// kUnsupported for models that are not linear_in_shared_directions(), kInvalidArgument for invalid options.
  virtual Result<LinearFitOperator> fit_operator(const std::vector<Vec3d>& directions,
                                                 const MapFitOptions& options) const;
  /// True when the map fit also fills the leave-one-out channels loo.R/G/B: the RMS over a texel's samples of the
  /// residual at each sample of the fit made without it (closed form from the hat matrix for linear fits).
  virtual bool reports_leave_one_out() const { return false; }

  /// The problem with the map fit options for this model (kInvalidArgument with the reason), checked by every fit
  /// before it starts; a model checks the options it reads (its own MapFitOptions::model_options and the map-level
  /// ones). The default refuses shared_lights (a pass that needs lobes).
  virtual Status check_options(const MapFitOptions& options) const;
  /// Every option this model's fit reads, as text (equal text for equal fits): appended to fit_options_fingerprint
  /// (tiled_fit.hpp), which tells a restarted or distributed fit whether recorded tiles belong to it. An option
  /// missing here would let a restart reuse tiles fitted otherwise, and `vdrig fit` rejects a command-line option
  /// that leaves it unchanged. The default: "" (a model without options).
  virtual std::string options_fingerprint(const MapFitOptions& /*options*/) const { return {}; }

  /// Fits every texel of the context's observation map into a parameter map of this model (or of the model the
  /// fit resolves it to, e.g. phong:auto with its lobe count). Checks the options that concern this model
  /// (kInvalidArgument with the reason); fills the quality channels (ParameterMap::set_quality, set_holdout_rms).
  /// Models whose texels are fitted independently implement it with fit_map_per_texel.
  virtual Result<ParameterMap> fit_map(const MapFitContext& context) const = 0;

  /// The same fit cut into tile jobs (tiled_fit.hpp: distributed and restartable fits), giving the same map bit for
  /// bit; kInvalidArgument for options fit_map would refuse. The default, per_texel_tiled_fit, is right for models
  /// whose fit_map is fit_map_per_texel; a model with passes over the whole map (Phong's shared lights) or a
  /// position-dependent fit overrides it. `spec` is the map's.
  virtual Result<std::unique_ptr<ModelTiledFit>> tiled_fit(const MapFitOptions& options,
                                                           const ObservationMapSpec& spec) const;

 private:
  mutable std::atomic<int> parameter_count_{-1};
};

/// The texel fitter of a model whose texels are fitted independently: one per worker thread (it may keep work
/// space between texels).
class TexelFitter {
 public:
  virtual ~TexelFitter() = default;
  /// The parameters (parameter_count() of them) fitted to obs (at least MapFitOptions::min_observations of them).
  virtual std::vector<double> fit(const TexelObservations& obs) = 0;
  /// Optional: the quality of `parameters`, just returned by fit() for the same `obs`, computed more cheaply than
  /// by evaluating the model at every observation (a linear fit keeps its basis matrix), with the leave-one-out RMS
  /// per channel. False (the default): fit_map_per_texel measures the quality itself and reports no LOO.
  virtual bool quality(const TexelObservations& /*obs*/, std::span<const double> /*parameters*/, FitQuality* /*q*/,
                       Vec3d* /*loo_rms*/) {
    return false;
  }
};

/// The leave-one-out channels a model with reports_leave_one_out() adds to its maps.
inline const char* const kLeaveOneOutChannels[3] = {"loo.R", "loo.G", "loo.B"};

/// A texel's observations as handed to a model's map fit: those to fit and the held-out ones.
using TexelVisitor =
    std::function<void(int worker, int s, int t, const TexelObservations& fit, const TexelObservations& held)>;

/// What a model's fit_map works on (made by fit_parameter_map, fit_map.hpp).
struct MapFitContext {
  const MapFitOptions& options;
  ObservationMapSpec spec;
  int workers = 1;
  /// Visits every texel once, in parallel on `workers` threads (worker = 0 .. workers - 1, for per-thread state;
  /// distinct texels run concurrently, one texel never twice at once), tile by tile. `pass` (0, 1, ...) places the
  /// progress of this sweep in MapFitOptions::on_progress given `passes` sweeps in all. Returns the first tile read
  /// error, after which no more texels are visited.
  std::function<Status(int pass, int passes, const TexelVisitor& visit)> for_each_texel;
};

/// fit_map for a model fitted texel by texel in one sweep: make_fitter() is called once per worker; texels with
/// fewer than min_observations observations get zero parameters and n = their count. Models that
/// reports_leave_one_out() get the loo.R/G/B channels from their fitter's quality(). Rejects options that need a
/// model's own second pass (shared_lights).
Result<ParameterMap> fit_map_per_texel(const ModelPtr& model, const MapFitContext& context,
                                       const std::function<std::unique_ptr<TexelFitter>()>& make_fitter);

/// Model names to configured models. Each entry parses the settings after "<family>:" of its family.
class ModelRegistry {
 public:
  struct Entry {
    std::string family;  // "phong"
    std::string syntax;  // how the name is written, for help texts and errors: "phong:K|phong:auto"
    /// Parses the text after "<family>:" ("" when the name has no ':'); kInvalidArgument with the reason.
    std::function<Result<ModelPtr>(const std::string& settings)> parse;
    /// Full names that parse, one per form the syntax allows ("phong:1", "phong:auto:per-lobe-m", ...): the tests run
    /// every model check on each (tests/fitting/test_models.cpp, tests/viewer/test_render_models.cpp).
    std::vector<std::string> examples;
  };

  /// Adds a family; a family registered twice is a broken invariant (VDRIG_CHECK).
  void add(Entry entry);
  /// The model of a full name; kInvalidArgument naming the model, the reason and the accepted syntax when the
  /// family is unknown or its settings are invalid.
  Result<ModelPtr> parse(const std::string& name) const;
  /// Registered families, in registration order.
  std::vector<std::string> families() const;
  /// Every family's examples (Entry::examples), in registration order.
  std::vector<std::string> examples() const;
  /// "phong:K | phong:auto | ... | hsh:N": every family's syntax, for help texts.
  std::string syntax(const std::string& separator = " | ") const;

 private:
  std::vector<Entry> entries_;
};

/// Adds the models vdrig ships (phong, sh-zh, sh-lsop, sh-ls, hsh, ptm, ggx) to `registry`.
void register_builtin_models(ModelRegistry& registry);

/// The process-wide registry holding the built-in models (built on first use; thread-safe).
const ModelRegistry& model_registry();

/// model_registry().parse(name).
Result<ModelPtr> parse_model(const std::string& name);

}  // namespace vdrig::fitting
