#include "vdrig/fitting/parameter_map.hpp"

#include <cstdio>

#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/sh.hpp"

namespace vdrig::fitting {
namespace {

const char* kRgb[3] = {"R", "G", "B"};
const char* kXyz[3] = {"x", "y", "z"};

std::string lobe_channel(const char* base, int k, const char* c) {
  return std::string(base) + std::to_string(k) + "." + c;
}

std::string sh_channel(const ModelDescriptor& m, int c, int i) {
  char idx[16];
  std::snprintf(idx, sizeof idx, "%02d", i);
  return std::string(m.kind == "hsh" ? "hsh." : "sh.") + kRgb[c] + "." + idx;
}

std::vector<std::string> model_channels(const ModelDescriptor& m) {
  std::vector<std::string> names;
  if (m.kind == "phong") {
    for (auto c : kRgb) names.push_back(std::string("kd.") + c);
    for (int k = 0; k < m.lobes; ++k) {
      for (auto c : kRgb) names.push_back(lobe_channel("ks", k, c));
      for (auto c : kXyz) names.push_back(lobe_channel("r", k, c));
      if (!m.shared_shininess) names.push_back("m" + std::to_string(k));
    }
    if (m.shared_shininess) names.push_back("m");
    if (m.auto_lobes) names.push_back("lobes");
  } else {
    for (int c = 0; c < 3; ++c)
      for (int i = 0; i < m.coefficients_per_channel(); ++i) names.push_back(sh_channel(m, c, i));
  }
  for (auto c : kRgb) names.push_back(std::string("rms.") + c);
  for (auto c : kRgb) names.push_back(std::string("mpe.") + c);
  names.push_back("n");
  return names;
}

}  // namespace

Result<ModelDescriptor> ModelDescriptor::parse(const std::string& spec) {
  ModelDescriptor m;
  const auto colon = spec.find(':');
  m.kind = spec.substr(0, colon);
  const std::string rest = colon == std::string::npos ? "" : spec.substr(colon + 1);
  auto bad = [&](const std::string& why) {
    return make_error(
        ErrorCode::kInvalidArgument,
        "model \"" + spec + "\": " + why + " (expected phong:K|phong:auto|sh-zh:N|sh-lsop:N|sh-ls:N|hsh:N)");
  };
  try {
    if (m.kind == "phong") {
      std::string lobes = rest.substr(0, rest.find(':'));
      if (rest.find(":per-lobe-m") != std::string::npos) m.shared_shininess = false;
      if (lobes.empty()) lobes = "1";
      m.auto_lobes = lobes == "auto";
      m.lobes = m.auto_lobes ? 0 : std::stoi(lobes);
      if (m.lobes < 0 || m.lobes > 4) return bad("lobes must be 1..4 or auto");
    } else if (m.kind == "sh-zh" || m.kind == "sh-lsop" || m.kind == "sh-ls" || m.kind == "hsh") {
      m.bands = std::stoi(rest);
      if (m.bands < 1 || m.bands > 10) return bad("bands must be 1..10");
      m.lobes = 0;
    } else {
      return bad("unknown model");
    }
  } catch (const std::exception&) {
    return bad("not a number");
  }
  return m;
}

std::string ModelDescriptor::to_string() const {
  if (kind == "phong")
    return "phong:" + (auto_lobes || lobes == 0 ? std::string("auto") : std::to_string(lobes)) +
           (shared_shininess ? "" : ":per-lobe-m");
  return kind + ":" + std::to_string(bands);
}

ParameterMap::ParameterMap(const ModelDescriptor& model, int S, int T, double width_mm, double height_mm)
    : model_(model), width_mm_(width_mm), height_mm_(height_mm) {
  VDRIG_CHECK(model.kind != "phong" || model.lobes >= 1, "a Phong map needs a resolved lobe count");
  for (const auto& name : model_channels(model)) image_.add(name, cv::Mat(T, S, CV_32FC1, cv::Scalar(0)));
  image_.string_attributes["vdrig.model"] = model.kind;
  image_.string_attributes["vdrig.model_spec"] = model.to_string();
  image_.number_attributes["vdrig.lobes"] = model.lobes;
  image_.number_attributes["vdrig.shared_m"] = model.shared_shininess ? 1 : 0;
  image_.number_attributes["vdrig.bands"] = model.bands;
  image_.number_attributes["vdrig.surface_width_mm"] = width_mm;
  image_.number_attributes["vdrig.surface_height_mm"] = height_mm;
  image_.number_attributes["vdrig.parameter_map_version"] = kParameterMapFormatVersion;
  index_coefficients();
}

void ParameterMap::index_coefficients() {
  // Looked up once: a file read back may hold the channels in any order, and per-texel lookups by name would cost
  // O(channels) each.
  coeff_channel_.clear();
  if (model_.kind == "phong") return;
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < model_.coefficients_per_channel(); ++i) {
      coeff_channel_.push_back(image_.find(sh_channel(model_, c, i)));
      VDRIG_CHECK(coeff_channel_.back() >= 0, "parameter map lacks channel " + sh_channel(model_, c, i));
    }
}

float& ParameterMap::at(const std::string& channel, int s, int t) {
  const int i = image_.find(channel);
  VDRIG_CHECK(i >= 0, "parameter map has no channel " + channel);
  return image_.channels[i].at<float>(t, s);
}

float ParameterMap::at(const std::string& channel, int s, int t) const {
  const int i = image_.find(channel);
  VDRIG_CHECK(i >= 0, "parameter map has no channel " + channel);
  return image_.channels[i].at<float>(t, s);
}

void ParameterMap::set_phong(int s, int t, const PhongParams& p) {
  VDRIG_CHECK(model_.kind == "phong" && static_cast<int>(p.lobes.size()) <= model_.lobes,
              "Phong lobes exceed the map's");
  for (int c = 0; c < 3; ++c) at(std::string("kd.") + kRgb[c], s, t) = static_cast<float>(p.kd[c]);
  for (int k = 0; k < model_.lobes; ++k) {
    // A texel that needs fewer lobes than the map stores has zero energy in the rest.
    const PhongLobe lobe = k < static_cast<int>(p.lobes.size()) ? p.lobes[k] : PhongLobe{};
    for (int c = 0; c < 3; ++c) {
      at(lobe_channel("ks", k, kRgb[c]), s, t) = static_cast<float>(lobe.ks[c]);
      at(lobe_channel("r", k, kXyz[c]), s, t) = static_cast<float>(lobe.direction[c]);
    }
    if (!model_.shared_shininess) at("m" + std::to_string(k), s, t) = static_cast<float>(lobe.shininess);
  }
  if (model_.shared_shininess) at("m", s, t) = static_cast<float>(p.lobes.empty() ? 1.0 : p.lobes[0].shininess);
}

PhongParams ParameterMap::phong(int s, int t) const {
  PhongParams p;
  for (int c = 0; c < 3; ++c) p.kd[c] = at(std::string("kd.") + kRgb[c], s, t);
  for (int k = 0; k < model_.lobes; ++k) {
    PhongLobe l;
    for (int c = 0; c < 3; ++c) {
      l.ks[c] = at(lobe_channel("ks", k, kRgb[c]), s, t);
      l.direction[c] = at(lobe_channel("r", k, kXyz[c]), s, t);
    }
    l.shininess = model_.shared_shininess ? at("m", s, t) : at("m" + std::to_string(k), s, t);
    p.lobes.push_back(l);
  }
  return p;
}

void ParameterMap::set_quality(int s, int t, const FitQuality& q) {
  for (int c = 0; c < 3; ++c) {
    at(std::string("rms.") + kRgb[c], s, t) = static_cast<float>(q.rms[c]);
    at(std::string("mpe.") + kRgb[c], s, t) = static_cast<float>(q.mean_percent[c]);
  }
  at("n", s, t) = static_cast<float>(q.samples);
}

void ParameterMap::set_sh(int s, int t, const Eigen::MatrixXd& coeffs) {
  VDRIG_CHECK(model_.kind != "phong", "set_sh on a Phong map");
  VDRIG_CHECK(coeffs.rows() == model_.coefficients_per_channel() && coeffs.cols() == 3,
              "set_sh: coefficients must be n^2 x 3");
  const int k = model_.coefficients_per_channel();
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < k; ++i)
      image_.channels[coeff_channel_[c * k + i]].at<float>(t, s) = static_cast<float>(coeffs(i, c));
}

ShExpansion ParameterMap::sh(int s, int t) const {
  VDRIG_CHECK(model_.kind != "phong", "sh() on a Phong map");
  ShExpansion e;
  e.hemispherical = model_.kind == "hsh";
  e.coeffs.resize(model_.coefficients_per_channel(), 3);
  const int k = model_.coefficients_per_channel();
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < k; ++i) e.coeffs(i, c) = image_.channels[coeff_channel_[c * k + i]].at<float>(t, s);
  return e;
}

void ParameterMap::add_channel(const std::string& name) {
  if (!has(name)) image_.add(name, cv::Mat(texels_t(), texels_s(), CV_32FC1, cv::Scalar(0)));
}

void ParameterMap::set_holdout_rms(int s, int t, const Vec3d& rms) {
  for (int c = 0; c < 3; ++c) {
    const std::string name = std::string("holdout.") + kRgb[c];
    add_channel(name);
    at(name, s, t) = static_cast<float>(rms[c]);
  }
}

Vec3d ShExpansion::evaluate(const Vec3d& v) const {
  return hemispherical ? Vec3d(eval_hsh(coeffs, v)) : Vec3d(eval_sh(coeffs, v));
}

Vec3d ParameterMap::evaluate(int s, int t, const Vec3d& v) const {
  if (model_.kind == "phong") return phong(s, t).evaluate(v);
  return sh(s, t).evaluate(v);
}

Status ParameterMap::write(const std::filesystem::path& path, ExrPixelType type) const {
  return write_exr(path, image_, type);
}

Result<ParameterMap> ParameterMap::read(const std::filesystem::path& path) {
  auto img = read_exr(path);
  if (!img) return img.error();
  const auto& sa = img->string_attributes;
  const auto& na = img->number_attributes;
  auto spec_it = sa.find("vdrig.model_spec");
  if (spec_it == sa.end() || !na.count("vdrig.surface_width_mm") || !na.count("vdrig.surface_height_mm"))
    return make_error(ErrorCode::kCorrupt, path.string() + " is not a vdrig parameter map (no vdrig.model_spec)");
  auto model = ModelDescriptor::parse(spec_it->second);
  if (!model) return make_error(ErrorCode::kCorrupt, path.string() + ": " + model.error().message);
  if (model->kind == "phong" && model->lobes == 0) {
    // Checked as a double first: casting NaN or 1e300 to int is undefined behaviour.
    const double lobes = na.count("vdrig.lobes") ? na.at("vdrig.lobes") : 0.0;
    if (!(lobes >= 1 && lobes <= 4)) return make_error(ErrorCode::kCorrupt, path.string() + ": bad vdrig.lobes");
    model->lobes = static_cast<int>(lobes);
  }
  ParameterMap map;
  map.model_ = model.value();
  map.width_mm_ = na.at("vdrig.surface_width_mm");
  map.height_mm_ = na.at("vdrig.surface_height_mm");
  for (const auto& name : model_channels(map.model_))
    if (img->find(name) < 0) return make_error(ErrorCode::kCorrupt, path.string() + ": missing channel " + name);
  map.image_ = std::move(img.value());
  map.index_coefficients();
  return map;
}

}  // namespace vdrig::fitting
