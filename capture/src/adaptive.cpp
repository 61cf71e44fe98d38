#include "vdrig/capture/adaptive.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <mutex>
#include <span>

#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/route.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace {

std::mutex& factory_mutex() {
  static std::mutex m;
  return m;
}
ViewPlannerFactory& factory() {
  static ViewPlannerFactory f;
  return f;
}

bool parse_number(std::string_view text, double* out) {
  const std::string s(text);
  char* end = nullptr;
  *out = std::strtod(s.c_str(), &end);
  return !s.empty() && end == s.c_str() + s.size() && std::isfinite(*out);
}

bool parse_int(std::string_view text, int64_t* out) {
  const auto r = std::from_chars(text.data(), text.data() + text.size(), *out);
  return r.ec == std::errc() && r.ptr == text.data() + text.size();
}

}  // namespace

std::string AdaptiveSettings::base_scheme() const {
  if (!base.empty()) return base;
  // Half of the views uniform: the planner's picks help where a highlight needs them, but a fit also needs the
  // grazing and in-between directions that no highlight asks for (docs/results.md, "Adaptive sampling").
  const int n = std::max(1, max_views / 2);
  const int rings = std::max(1, static_cast<int>(std::lround(std::sqrt(kPi * n / 8.0))));
  return fmt::format("spiral:{}:{}@{:g}", n, rings, max_zenith_deg);
}

bool AdaptiveSettings::is_valid(std::string* why) const {
  std::vector<std::string> reasons;
  if (max_views < 2 || max_views > 5000) reasons.push_back("N (the most views) must be in 2..5000");
  if (batch < 1 || batch > 100) reasons.push_back("batch must be in 1..100");
  if (ahead < 1 || ahead > 100) reasons.push_back("ahead (batches planned and routed at once) must be in 1..100");
  if (!(max_move_s >= 0)) reasons.push_back("time_s (move-time budget) must be >= 0 (0: none)");
  if (res < 2 || res > 128) reasons.push_back("res (coarse map texels per side) must be in 2..128");
  if (!(max_zenith_deg > 0 && max_zenith_deg <= 90)) reasons.push_back("zenith must be in (0, 90]");
  if (!(min_gain >= 0 && min_gain < 1)) reasons.push_back("gain must be in [0, 1)");
  if (patience < 1 || patience > 100) reasons.push_back("patience must be in 1..100");
  if (!(coverage_weight >= 0 && coverage_weight <= 100)) reasons.push_back("coverage must be in [0, 100]");
  if (!(move_weight_s > 0)) reasons.push_back("move_s must be > 0");
  if (model != "phong" && model != "ggx")
    reasons.push_back("model must be phong or ggx (the planner's per-texel model), got \"" + model + "\"");
  const std::string base_spec = base_scheme();
  if (is_adaptive_scheme(base_spec)) {
    reasons.push_back("base must be a fixed scheme, not adaptive");
  } else if (auto b = generate(base_spec); !b) {
    reasons.push_back("base: " + b.error().message);
  } else if (static_cast<int>(b->directions.size()) >= max_views) {
    reasons.push_back("base \"" + base_spec + "\" has " + std::to_string(b->directions.size()) +
                      " directions, not fewer than N = " + std::to_string(max_views));
  }
  if (reasons.empty()) return true;
  if (why) {
    *why = reasons[0];
    for (size_t i = 1; i < reasons.size(); ++i) *why += "; " + reasons[i];
  }
  return false;
}

std::string AdaptiveSettings::to_spec() const {
  const AdaptiveSettings d;
  std::string s = "adaptive:" + std::to_string(max_views);
  if (base != d.base) s += ",base=" + base;
  if (batch != d.batch) s += ",batch=" + std::to_string(batch);
  if (max_move_s != d.max_move_s) s += fmt::format(",time_s={:g}", max_move_s);
  if (res != default_res(model)) s += ",res=" + std::to_string(res);
  if (max_zenith_deg != d.max_zenith_deg) s += fmt::format(",zenith={:g}", max_zenith_deg);
  if (min_gain != d.min_gain) s += fmt::format(",gain={:g}", min_gain);
  if (patience != d.patience) s += ",patience=" + std::to_string(patience);
  if (coverage_weight != d.coverage_weight) s += fmt::format(",coverage={:g}", coverage_weight);
  if (move_weight_s != d.move_weight_s) s += fmt::format(",move_s={:g}", move_weight_s);
  if (seed != d.seed) s += ",seed=" + std::to_string(seed);
  if (!camera.empty()) s += ",camera=" + camera;
  if (ahead != d.ahead) s += ",ahead=" + std::to_string(ahead);
  if (model != d.model) s += ",model=" + model;
  return s;
}

nlohmann::json AdaptiveSettings::to_json() const {
  return {{"spec", to_spec()},
          {"max_views", max_views},
          {"base", base_scheme()},
          {"batch", batch},
          {"time_s", max_move_s},
          {"res", res},
          {"zenith_deg", max_zenith_deg},
          {"gain", min_gain},
          {"patience", patience},
          {"coverage", coverage_weight},
          {"move_s", move_weight_s},
          {"seed", seed},
          {"camera", camera},
          {"ahead", ahead},
          {"model", model}};
}

bool is_adaptive_scheme(std::string_view spec) { return spec.rfind("adaptive:", 0) == 0; }

Result<AdaptiveSettings> parse_adaptive_scheme(std::string_view spec) {
  auto bad = [&](const std::string& why) {
    return make_error(ErrorCode::kInvalidArgument, "sampling scheme \"" + std::string(spec) + "\": " + why);
  };
  if (!is_adaptive_scheme(spec)) return bad("not an adaptive scheme (adaptive:N[,key=value]...)");
  std::string_view rest = spec.substr(9);
  std::vector<std::string_view> items;
  while (true) {
    const size_t comma = rest.find(',');
    items.push_back(rest.substr(0, comma));
    if (comma == std::string_view::npos) break;
    rest = rest.substr(comma + 1);
  }
  AdaptiveSettings a;
  int64_t n = 0;
  if (!parse_int(items[0], &n)) return bad("N must be a whole number of views, got \"" + std::string(items[0]) + "\"");
  a.max_views = static_cast<int>(std::clamp<int64_t>(n, -1, 1 << 30));
  std::vector<std::string> reasons;
  bool res_given = false;
  for (size_t i = 1; i < items.size(); ++i) {
    const std::string_view item = items[i];
    const size_t eq = item.find('=');
    if (eq == std::string_view::npos) {
      reasons.push_back("\"" + std::string(item) + "\" is not key=value");
      continue;
    }
    const std::string key(item.substr(0, eq));
    const std::string_view value = item.substr(eq + 1);
    double x = 0;
    int64_t k = 0;
    auto number = [&](double* field) {
      if (parse_number(value, &x))
        *field = x;
      else
        reasons.push_back(key + " must be a number, got \"" + std::string(value) + "\"");
    };
    auto whole = [&](int* field) {
      if (parse_int(value, &k))
        *field = static_cast<int>(std::clamp<int64_t>(k, -1, 1 << 30));
      else
        reasons.push_back(key + " must be a whole number, got \"" + std::string(value) + "\"");
    };
    if (key == "base")
      a.base = std::string(value);
    else if (key == "batch")
      whole(&a.batch);
    else if (key == "time_s")
      number(&a.max_move_s);
    else if (key == "res") {
      whole(&a.res);
      res_given = true;
    } else if (key == "zenith")
      number(&a.max_zenith_deg);
    else if (key == "gain")
      number(&a.min_gain);
    else if (key == "patience")
      whole(&a.patience);
    else if (key == "coverage")
      number(&a.coverage_weight);
    else if (key == "move_s")
      number(&a.move_weight_s);
    else if (key == "camera")
      a.camera = std::string(value);
    else if (key == "ahead")
      whole(&a.ahead);
    else if (key == "model")
      a.model = std::string(value);
    else if (key == "seed") {
      if (parse_int(value, &k) && k >= 0)
        a.seed = static_cast<uint64_t>(k);
      else
        reasons.push_back("seed must be a whole number >= 0");
    } else {
      reasons.push_back("unknown key \"" + key +
                        "\" (base, batch, time_s, res, zenith, gain, patience, coverage, move_s, seed, camera, ahead, "
                        "model)");
    }
  }
  if (!res_given) a.res = AdaptiveSettings::default_res(a.model);
  std::string why;
  if (!a.is_valid(&why)) reasons.push_back(why);
  if (!reasons.empty()) {
    std::string all = reasons[0];
    for (size_t i = 1; i < reasons.size(); ++i) all += "; " + reasons[i];
    return bad(all);
  }
  return a;
}

void register_view_planner_factory(ViewPlannerFactory f) {
  std::lock_guard lock(factory_mutex());
  factory() = std::move(f);
}

Result<std::unique_ptr<ViewPlanner>> make_view_planner() {
  std::lock_guard lock(factory_mutex());
  if (!factory())
    return make_error(ErrorCode::kUnsupported,
                      "adaptive sampling needs a build with the fitting pipeline (Ceres): this one captures fixed "
                      "schemes only");
  return factory()();
}

Status check_adaptive_capture(const std::string& scheme, const std::filesystem::path& session_dir,
                              const nlohmann::json& rig_config) {
  auto settings = parse_adaptive_scheme(scheme);
  if (!settings) return settings.error();
  auto planner = make_view_planner();
  if (!planner) return planner.error();
  return planner.value()->check(settings.value(), session_dir, rig_config);
}

double AdaptiveProgress::planned_move_s() const {
  double t = base_move_s;
  for (const auto& b : batches) t += b.move_s;
  return t;
}

AdaptiveProgress adaptive_progress(const Session& session) {
  AdaptiveProgress p;
  const auto& extra = session.manifest().extra;
  if (extra.contains("route")) p.base_move_s = extra["route"].value("planned_time_s", 0.0);
  auto number = [](const nlohmann::json& line, const char* key) {
    const auto it = line.find(key);
    return it != line.end() && it->is_number() ? it->get<double>() : 0.0;
  };
  for (const auto& line : session.adaptive_lines()) {
    // The lines were checked when the journal was replayed (views numbered on); the other fields are read leniently:
    // a hand-edited journal must not stop a capture.
    if (line.value("type", "") == "adaptive_stopped") {
      const auto reason = line.find("reason");
      p.stopped = reason != line.end() && reason->is_string() ? reason->get<std::string>() : "stopped";
      continue;
    }
    AdaptiveBatch b;
    b.batch = static_cast<int>(number(line, "batch"));
    b.predicted_error = number(line, "predicted_error");
    b.move_s = number(line, "move_s");
    if (const auto info = line.find("info"); info != line.end()) b.info = *info;
    for (const auto& v : line.at("views")) b.views.push_back(v.at("index").get<int>());
    p.batches.push_back(std::move(b));
  }
  return p;
}

Result<Manifest> plan_adaptive_manifest(const PlanRequest& request) {
  auto settings = parse_adaptive_scheme(request.scheme);
  if (!settings) return settings.error();
  PlanRequest base = request;
  base.scheme = settings->base_scheme();
  auto m = plan_manifest(base);
  if (!m) return m.error();
  if (static_cast<int>(m->views.size()) >= settings->max_views)
    return make_error(ErrorCode::kInvalidArgument, "base scheme has as many reachable views as N");
  const double base_move_s = m->extra["route"].value("planned_time_s", 0.0);
  if (settings->max_move_s > 0 && base_move_s > settings->max_move_s)
    return make_error(
        ErrorCode::kInvalidArgument,
        fmt::format("sampling scheme \"{}\": the base scheme's moves take {:.1f} s, more than time_s = {:g} "
                    "s; give a smaller base or a larger budget",
                    request.scheme, base_move_s, settings->max_move_s));
  m->scheme = settings->to_spec();
  m->extra["adaptive"] = settings->to_json();
  return m;
}

namespace {

/// Why the loop stops before planning batch `next`, or nothing.
std::optional<std::string> stop_reason(const AdaptiveSettings& a, const AdaptiveProgress& p, int views) {
  if (views >= a.max_views) return "view budget: " + std::to_string(views) + " of " + std::to_string(a.max_views);
  if (a.max_move_s > 0 && p.planned_move_s() >= a.max_move_s)
    return fmt::format("time budget: {:.1f} s of moves planned of {:g} s", p.planned_move_s(), a.max_move_s);
  // The predicted error: batch k's figure is the fit's before batch k-1, measured at batch k-1's views (for k = 1,
  // on every fourth base view held out). It has stopped improving when it changed by less than min_gain (relative,
  // floor 1e-3) from batch to batch over the last `patience` batches: a rise is news (the views found what the fit
  // had not seen), so it counts as change, not as convergence.
  const auto& b = p.batches;
  if (static_cast<int>(b.size()) > a.patience) {
    bool flat = true;
    for (size_t i = b.size() - a.patience; i < b.size(); ++i) {
      const double before = b[i - 1].predicted_error, now = b[i].predicted_error;
      flat = flat && std::abs(now - before) <= a.min_gain * std::max(before, 1e-3);
    }
    if (flat)
      return fmt::format("converged: predicted held-out error {:.4g} changed by less than {:g} % over {} batches",
                         b.back().predicted_error, 100 * a.min_gain, a.patience);
  }
  return std::nullopt;
}

}  // namespace

Status run_adaptive_session(rig::Rig& rig, Session& session, ViewPlanner& planner, const AdaptiveOptions& options) {
  auto logger = log::get("capture");
  const auto& extra = session.manifest().extra;
  if (!extra.contains("adaptive"))
    return make_error(ErrorCode::kInvalidArgument, "session " + session.dir().string() + " is not adaptive");
  auto settings = parse_adaptive_scheme(extra["adaptive"].value("spec", std::string()));
  if (!settings) return settings.error();
  auto geometry = geometry_from_rig_config(session.manifest().rig_config);
  if (!geometry) return geometry.error();
  VDRIG_TRY(session.lock());
  const rig::StageSpec stage = rig.stage->spec();
  bool first = true;
  while (true) {
    // Every view planned so far (a resumed session: those of the batches already journaled) before the next plan.
    // Homed once (run_session), then each batch captured from where the stage is.
    Status captured = Status::ok();
    if (first) {
      captured = run_session(rig, session, options.capture, /*park=*/false);
      first = false;
    } else if (session.completed_view_count() < static_cast<int>(session.manifest().views.size())) {
      captured = run_capture(rig, session, options.capture);
    }
    if (!captured) {
      // Paused or aborted: the stage is fine, park it as run_session does. Any other fault leaves the axes where
      // they are (a park would move whichever axis still answers).
      if (captured.error().code == ErrorCode::kCancelled) (void)rig.stage->move_to(PanTilt{0.0, 0.0});
      return captured;
    }
    AdaptiveProgress progress = adaptive_progress(session);
    if (progress.stopped) break;
    const int views = static_cast<int>(session.manifest().views.size());
    std::optional<std::string> why = stop_reason(settings.value(), progress, views);
    BatchPlan plan;
    std::vector<PlannedView> chosen;
    double move_s = 0;
    if (!why) {
      BatchRequest req;
      req.session = &session;
      req.settings = settings.value();
      req.batch = static_cast<int>(progress.batches.size()) + 1;
      req.max_views = std::min(settings->ahead * settings->batch, settings->max_views - views);
      req.from = session.manifest().views.back().target;
      req.geometry = geometry.value();
      req.stage = stage;
      if (!progress.batches.empty()) req.previous_batch = progress.batches.back().views;
      auto planned = planner.plan_batch(req);
      if (!planned) return planned.error();
      plan = std::move(planned.value());
      if (static_cast<int>(plan.directions.size()) > req.max_views) plan.directions.resize(req.max_views);
      const TargetPlan targets = plan_targets(geometry.value(), stage, plan.directions, req.from.pan_rad);
      std::vector<PanTilt> pts;
      for (const auto& t : targets.reachable) pts.push_back(t.pan_tilt);
      // The plan is of `ahead` batches; the batch is the next `batch` views along their route from where the stage
      // is, visited in that order, and the next batch replans the rest with the new views: the stage follows one
      // tour of what is still worth taking rather than a tour per batch that ends anywhere (docs/sampling.md).
      const Route route = plan_route(stage, req.from, pts);
      const size_t batch_size = std::min<size_t>(route.order.size(), static_cast<size_t>(settings->batch));
      // The time budget: the batch is cut where its moves would pass it.
      PanTilt at = req.from;
      for (size_t k : std::span(route.order).first(batch_size)) {
        const double m = move_time_s(stage, at, pts[k]);
        if (settings->max_move_s > 0 && progress.planned_move_s() + move_s + m > settings->max_move_s) break;
        move_s += m;
        at = pts[k];
        chosen.push_back({views + static_cast<int>(chosen.size()), targets.reachable[k].direction, pts[k]});
      }
      if (chosen.empty())
        why = plan.directions.empty() ? "nothing left to learn: the planner chose no view"
                                      : "time budget: the next view's move would pass it";
    }
    if (why) {
      nlohmann::json info = {{"views", views}, {"move_s", progress.planned_move_s()}};
      if (!progress.batches.empty()) info["predicted_error"] = progress.batches.back().predicted_error;
      logger->info("adaptive sampling stops after {} views: {}", views, *why);
      VDRIG_TRY(session.append_adaptive_stop(*why, info));
      if (options.on_batch) options.on_batch(adaptive_progress(session));
      break;
    }
    const int batch_number = static_cast<int>(progress.batches.size()) + 1;
    logger->info("adaptive batch {}: {} views ({:.1f} s of moves), predicted held-out error {:.4g}", batch_number,
                 chosen.size(), move_s, plan.predicted_error);
    // Journaled before the rig moves: a crash from here on resumes with these very views.
    VDRIG_TRY(session.append_planned_views(
        chosen,
        {{"batch", batch_number}, {"predicted_error", plan.predicted_error}, {"move_s", move_s}, {"info", plan.info}}));
    if (options.on_batch) options.on_batch(adaptive_progress(session));
  }
  const Status p = rig.stage->move_to(PanTilt{0.0, 0.0});
  if (!p) logger->warn("parking the axes failed: {}", p.describe());
  return Status::ok();
}

}  // namespace vdrig::capture
