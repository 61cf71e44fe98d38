#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {
namespace {

const char* kRgb[3] = {"R", "G", "B"};

/// The quality channels every map has after the model's own.
std::vector<std::string> quality_channels() {
  std::vector<std::string> names;
  for (auto c : kRgb) names.push_back(std::string("rms.") + c);
  for (auto c : kRgb) names.push_back(std::string("mpe.") + c);
  names.push_back("n");
  return names;
}

/// A texel's parameters as something measure_quality can evaluate.
struct TexelModel {
  const ReflectanceModel& model;
  std::span<const double> parameters;
  Vec3d evaluate(const Vec3d& v) const { return model.evaluate(parameters, v); }
};

}  // namespace

FitQuality measure_quality(const ReflectanceModel& model, std::span<const double> parameters,
                           const TexelObservations& obs) {
  return measure_quality(TexelModel{model, parameters}, obs);
}

ParameterMap::ParameterMap(ModelPtr model, int S, int T, double width_mm, double height_mm)
    : model_(std::move(model)), width_mm_(width_mm), height_mm_(height_mm) {
  VDRIG_CHECK(model_ && model_->storable(), "a parameter map needs a storable model (phong:auto with its lobe count)");
  for (const auto& name : model_->channels()) image_.add(name, cv::Mat(T, S, CV_32FC1, cv::Scalar(0)));
  for (const auto& name : quality_channels()) image_.add(name, cv::Mat(T, S, CV_32FC1, cv::Scalar(0)));
  image_.string_attributes["vdrig.model"] = model_->family();
  image_.string_attributes["vdrig.model_spec"] = model_->name();
  model_->write_attributes(image_.number_attributes);
  image_.number_attributes["vdrig.surface_width_mm"] = width_mm;
  image_.number_attributes["vdrig.surface_height_mm"] = height_mm;
  image_.number_attributes["vdrig.parameter_map_version"] = kParameterMapFormatVersion;
  index_parameters();
}

void ParameterMap::index_parameters() {
  // Looked up once: a file read back may hold the channels in any order, and per-texel lookups by name would cost
  // O(channels) each.
  parameter_channel_.clear();
  for (const auto& name : model_->channels()) {
    parameter_channel_.push_back(image_.find(name));
    VDRIG_CHECK(parameter_channel_.back() >= 0, "parameter map lacks channel " + name);
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

std::vector<double> ParameterMap::parameters(int s, int t) const {
  std::vector<double> p(parameter_channel_.size());
  for (size_t i = 0; i < p.size(); ++i) p[i] = image_.channels[parameter_channel_[i]].at<float>(t, s);
  return p;
}

void ParameterMap::set_parameters(int s, int t, std::span<const double> p) {
  VDRIG_CHECK(p.size() == parameter_channel_.size(), "set_parameters: " + std::to_string(p.size()) +
                                                         " values for a model of " +
                                                         std::to_string(parameter_channel_.size()) + " parameters");
  for (size_t i = 0; i < p.size(); ++i)
    image_.channels[parameter_channel_[i]].at<float>(t, s) = static_cast<float>(p[i]);
}

void ParameterMap::set_quality(int s, int t, const FitQuality& q) {
  for (int c = 0; c < 3; ++c) {
    at(std::string("rms.") + kRgb[c], s, t) = static_cast<float>(q.rms[c]);
    at(std::string("mpe.") + kRgb[c], s, t) = static_cast<float>(q.mean_percent[c]);
  }
  at("n", s, t) = static_cast<float>(q.samples);
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

Vec3d ParameterMap::evaluate(int s, int t, const Vec3d& v) const {
  const std::vector<double> p = parameters(s, t);
  return model_->evaluate(p, v);
}

Status ParameterMap::write(const std::filesystem::path& path, ExrPixelType type) const {
  return write_exr(path, image_, type);
}

namespace {

Status check_model_values(const ParameterMap& map, const std::filesystem::path& path) {
  // Every value is already known to be finite; the model judges its own ranges.
  for (int t = 0; t < map.texels_t(); ++t)
    for (int s = 0; s < map.texels_s(); ++s) {
      const std::string problem = map.model().check_parameters(map.parameters(s, t));
      if (!problem.empty())
        return make_error(ErrorCode::kCorrupt,
                          path.string() + ": texel " + std::to_string(s) + "," + std::to_string(t) + ": " + problem);
    }
  return Status::ok();
}

}  // namespace

Result<ParameterMap> ParameterMap::read(const std::filesystem::path& path) {
  auto img = read_exr(path, kMaxReadBytes);
  if (!img) return img.error();
  const auto& sa = img->string_attributes;
  const auto& na = img->number_attributes;
  auto spec_it = sa.find("vdrig.model_spec");
  if (spec_it == sa.end() || !na.count("vdrig.surface_width_mm") || !na.count("vdrig.surface_height_mm"))
    return make_error(ErrorCode::kCorrupt, path.string() + " is not a vdrig parameter map (no vdrig.model_spec)");
  auto named = parse_model(spec_it->second);
  if (!named) return make_error(ErrorCode::kCorrupt, path.string() + ": " + named.error().message);
  auto model = (*named)->with_attributes(na);
  if (!model) return make_error(ErrorCode::kCorrupt, path.string() + ": " + model.error().message);
  ParameterMap map;
  map.model_ = model.value();
  map.width_mm_ = na.at("vdrig.surface_width_mm");
  map.height_mm_ = na.at("vdrig.surface_height_mm");
  std::vector<std::string> names = map.model_->channels();
  for (const auto& name : quality_channels()) names.push_back(name);
  for (const auto& name : names)
    if (img->find(name) < 0) return make_error(ErrorCode::kCorrupt, path.string() + ": missing channel " + name);
  // A NaN or infinite parameter renders garbage: refuse the map, naming the first one.
  for (size_t c = 0; c < img->channels.size(); ++c) {
    cv::Point at;
    if (!cv::checkRange(img->channels[c], true, &at))
      return make_error(ErrorCode::kCorrupt, path.string() + ": channel " + img->channel_names[c] +
                                                 " is not finite at texel " + std::to_string(at.x) + "," +
                                                 std::to_string(at.y));
  }
  map.image_ = std::move(img.value());
  map.index_parameters();
  VDRIG_TRY(check_model_values(map, path));
  return map;
}

}  // namespace vdrig::fitting
