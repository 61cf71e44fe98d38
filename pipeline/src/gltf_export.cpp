#include "vdrig/pipeline/gltf_export.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/ggx_model.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

namespace {

constexpr double kDielectricF0 = 0.04;  // glTF's F0 of a dielectric (ior 1.5)

/// Linear [0, 1] to the sRGB transfer curve (IEC 61966-2-1), 8 bit.
uint8_t srgb_code(double linear) {
  const double x = std::clamp(linear, 0.0, 1.0);
  const double e = x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
  return static_cast<uint8_t>(std::lround(255.0 * e));
}

/// Linear [0, 1] to the sRGB transfer curve, 16 bit (KHR_materials_specular's specularColorTexture: see export_gltf).
uint16_t srgb_code16(double linear) {
  const double x = std::clamp(linear, 0.0, 1.0);
  const double e = x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
  return static_cast<uint16_t>(std::lround(65535.0 * e));
}

uint8_t linear_code(double x) { return static_cast<uint8_t>(std::lround(255.0 * std::clamp(x, 0.0, 1.0))); }

void append_floats(std::string& bytes, std::initializer_list<float> values) {
  for (float v : values) {
    char b[4];
    std::memcpy(b, &v, 4);  // glTF buffers are little-endian, as every platform vdrig builds on
    bytes.append(b, 4);
  }
}

}  // namespace

Result<GltfExport> export_gltf(const fitting::ParameterMap& map, const fs::path& dir, const std::string& name,
                               GltfContainer container) {
  const auto* ggx = dynamic_cast<const fitting::GgxModel*>(&map.model());
  if (!ggx)
    return make_error(ErrorCode::kInvalidArgument,
                      "model " + map.model().name() +
                          " is view-only (the radiance toward each view under the session's light, not a "
                          "material): glTF carries a BRDF; fit the session with a BRDF model (vdrig fit --model "
                          "ggx:iso --light X,Y,Z) and export that map");
  // The name makes file names and glTF URIs: plain characters only, so that no file lands outside DIR.
  if (name.empty() || name.front() == '.' ||
      name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-") != std::string::npos)
    return make_error(ErrorCode::kInvalidArgument,
                      "export name \"" + name + "\": letters, digits, '.', '_' and '-' only, not starting with '.'");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return make_error(ErrorCode::kIo, "cannot create " + dir.string() + ": " + ec.message());

  const int S = map.texels_s(), T = map.texels_t();
  GltfExport result;
  // Image row y is texel row t = y (texel (0, 0) at the surface's smallest x and y), which glTF's UV (0, 0), the
  // image's first row, addresses: no flip.
  cv::Mat base(T, S, CV_8UC3), mr(T, S, CV_8UC3), spec(T, S, CV_16UC3), normal(T, S, CV_8UC3),
      anisotropy(T, S, CV_8UC3);
  const bool normals = ggx->has_shading_normal(), aniso = ggx->is_anisotropic(), tangents = normals || aniso;
  double f0_max = 0.0;
  bool f0_dielectric = true;
  for (int t = 0; t < T; ++t)
    for (int s = 0; s < S; ++s) {
      const fitting::GgxMaterial m = fitting::GgxModel::material(map.parameters(s, t));
      f0_max = std::max(f0_max, m.f0.maxCoeff());
      f0_dielectric = f0_dielectric && (m.f0.array() - kDielectricF0).abs().maxCoeff() <= kF0Tolerance;
      if (m.albedo.maxCoeff() > 1.0) ++result.clipped_texels;
      // OpenCV's order is BGR.
      base.at<cv::Vec3b>(t, s) = cv::Vec3b(srgb_code(m.albedo.z()), srgb_code(m.albedo.y()), srgb_code(m.albedo.x()));
      const fitting::GgxMaterial full = ggx->texel_material(map.parameters(s, t));
      // glTF's roughness is the smoother direction's (KHR_materials_anisotropy: alpha_b = roughness^2).
      const double roughness = aniso && full.roughness_b > 0.0 ? full.roughness_b : m.roughness;
      mr.at<cv::Vec3b>(t, s) = cv::Vec3b(0, linear_code(roughness), 0);  // B metallic 0, G roughness, R unused
      if (aniso) {
        // KHR_materials_anisotropy: RG the direction in tangent space (as the normal map's: green along the
        // surface's -y), B the strength with alpha_t = mix(alpha_b, 1, strength^2).
        const double at = full.roughness * full.roughness, ab = roughness * roughness;
        const double strength = ab < 1.0 ? std::sqrt(std::clamp((at - ab) / (1.0 - ab), 0.0, 1.0)) : 0.0;
        anisotropy.at<cv::Vec3b>(t, s) = cv::Vec3b(linear_code(strength), linear_code(0.5 - 0.5 * std::sin(full.angle)),
                                                   linear_code(0.5 + 0.5 * std::cos(full.angle)));
      }
      if (normals) {
        // Tangent space (gltf_export.hpp): red along the surface's +x (u), green along its -y (glTF's green points
        // up the image, toward smaller v, i.e. smaller t), blue the geometric normal.
        const Vec3d n = ggx->texel_material(map.parameters(s, t)).normal;
        normal.at<cv::Vec3b>(t, s) =
            cv::Vec3b(linear_code(0.5 + 0.5 * n.z()), linear_code(0.5 - 0.5 * n.y()), linear_code(0.5 + 0.5 * n.x()));
      }
    }
  result.specular_extension = !f0_dielectric && f0_max > 0.0;
  // specularColorTexture is sRGB (the extension's README); 16 bit rather than 8 because Blender 3.4's importer bakes
  // its Specular from `image.pixels`, which are the encoded values of an 8-bit image (F0 / max F0 = 0.04 read as 0.22)
  // but linear ones of a 16-bit image (loaded as float and decoded): the same sRGB data then reads right in Blender and
  // in every renderer that follows the extension (docs/blender.md). The spec's other per-texel form, specularTexture
  // (A, linear), is no way out: it scales F90 as well as F0, and Blender 3.4's conversion ignores it.
  if (result.specular_extension)
    for (int t = 0; t < T; ++t)
      for (int s = 0; s < S; ++s) {
        const Vec3d f0 = fitting::GgxModel::material(map.parameters(s, t)).f0 / f0_max;
        spec.at<cv::Vec3w>(t, s) = cv::Vec3w(srgb_code16(f0.z()), srgb_code16(f0.y()), srgb_code16(f0.x()));
      }

  // The quad: surface (x, y) at glTF (x, 0, -y), metres; counter-clockwise seen from +Y (its normal).
  const float w = static_cast<float>(map.width_mm() / 1000.0), h = static_cast<float>(map.height_mm() / 1000.0);
  std::string bin;
  append_floats(bin, {-w / 2, 0, h / 2, w / 2, 0, h / 2, w / 2, 0, -h / 2, -w / 2, 0, -h / 2});  // POSITION
  append_floats(bin, {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0});                                      // NORMAL
  append_floats(bin, {0, 0, 1, 0, 1, 1, 0, 1});                                                  // TEXCOORD_0
  for (uint16_t i : {0, 1, 2, 0, 2, 3}) bin.append(reinterpret_cast<const char*>(&i), 2);        // 140 bytes
  // TANGENT (normal maps only): +x, w = -1, so that glTF's bitangent cross(N, T) w = glTF +Z = the surface's -y, the
  // direction of the normal map's green channel. Explicit, because the quad's UVs are mirrored (v grows with y while
  // glTF's image rows run down): a renderer deriving tangents from UVs must get the same frame, and stating it
  // removes one way of getting it wrong.
  if (tangents) append_floats(bin, {1, 0, 0, -1, 1, 0, 0, -1, 1, 0, 0, -1, 1, 0, 0, -1});  // 64 bytes, 204 in all

  const std::string bin_name = name + ".bin", base_name = name + "_basecolor.png",
                    mr_name = name + "_metallicroughness.png", spec_name = name + "_specular.png",
                    normal_name = name + "_normal.png", anisotropy_name = name + "_anisotropy.png";
  Json gltf;
  gltf["asset"] = {{"version", "2.0"}, {"generator", "vdrig export"}};
  if (result.specular_extension) gltf["extensionsUsed"].push_back("KHR_materials_specular");
  if (aniso) gltf["extensionsUsed"].push_back("KHR_materials_anisotropy");
  gltf["scene"] = 0;
  gltf["scenes"] = Json::array({{{"nodes", {0}}}});
  gltf["nodes"] = Json::array({{{"mesh", 0}, {"name", name}}});
  Json attributes = {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}};
  if (tangents) attributes["TANGENT"] = 4;
  gltf["meshes"] = Json::array(
      {{{"name", name}, {"primitives", Json::array({{{"attributes", attributes}, {"indices", 3}, {"material", 0}}})}}});
  gltf["buffers"] = Json::array({{{"uri", bin_name}, {"byteLength", bin.size()}}});
  // One buffer view per accessor (several accessors in one view would need a byteStride).
  gltf["bufferViews"] = Json::array({
      {{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 48}, {"target", 34962}},    // ARRAY_BUFFER
      {{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 48}, {"target", 34962}},   //
      {{"buffer", 0}, {"byteOffset", 96}, {"byteLength", 32}, {"target", 34962}},   //
      {{"buffer", 0}, {"byteOffset", 128}, {"byteLength", 12}, {"target", 34963}},  // ELEMENT_ARRAY_BUFFER
  });
  if (tangents)
    gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", 140}, {"byteLength", 64}, {"target", 34962}});
  gltf["accessors"] = Json::array({
      {{"bufferView", 0},
       {"componentType", 5126},
       {"count", 4},
       {"type", "VEC3"},
       {"min", {-w / 2, 0.0f, -h / 2}},
       {"max", {w / 2, 0.0f, h / 2}}},
      {{"bufferView", 1}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}},
      {{"bufferView", 2}, {"componentType", 5126}, {"count", 4}, {"type", "VEC2"}},
      {{"bufferView", 3}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}},
  });
  if (tangents)
    gltf["accessors"].push_back({{"bufferView", 4}, {"componentType", 5126}, {"count", 4}, {"type", "VEC4"}});
  // Texels are samples of the surface: linear filtering, clamped at the sample's edges.
  gltf["samplers"] = Json::array({{{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33071}}});
  Json images = Json::array({{{"uri", base_name}}, {{"uri", mr_name}}});
  Json textures = Json::array({{{"sampler", 0}, {"source", 0}}, {{"sampler", 0}, {"source", 1}}});
  Json material = {{"name", name},
                   {"pbrMetallicRoughness",
                    {{"baseColorTexture", {{"index", 0}}},
                     {"metallicFactor", 0.0},
                     {"roughnessFactor", 1.0},
                     {"metallicRoughnessTexture", {{"index", 1}}}}}};
  if (result.specular_extension) {
    images.push_back({{"uri", spec_name}});
    textures.push_back({{"sampler", 0}, {"source", 2}});
    const double k = f0_max / kDielectricF0;
    material["extensions"] = {
        {"KHR_materials_specular",
         {{"specularFactor", 1.0}, {"specularColorFactor", {k, k, k}}, {"specularColorTexture", {{"index", 2}}}}}};
  }
  if (normals) {
    images.push_back({{"uri", normal_name}});
    textures.push_back({{"sampler", 0}, {"source", images.size() - 1}});
    material["normalTexture"] = {{"index", textures.size() - 1}};
  }
  if (aniso) {
    images.push_back({{"uri", anisotropy_name}});
    textures.push_back({{"sampler", 0}, {"source", images.size() - 1}});
    material["extensions"]["KHR_materials_anisotropy"] = {{"anisotropyStrength", 1.0},
                                                          {"anisotropyRotation", 0.0},
                                                          {"anisotropyTexture", {{"index", textures.size() - 1}}}};
  }
  gltf["images"] = images;
  gltf["textures"] = textures;
  gltf["materials"] = Json::array({material});

  // The textures in images' order.
  std::vector<std::pair<std::string, const cv::Mat*>> pngs = {{base_name, &base}, {mr_name, &mr}};
  if (result.specular_extension) pngs.emplace_back(spec_name, &spec);
  if (normals) pngs.emplace_back(normal_name, &normal);
  if (aniso) pngs.emplace_back(anisotropy_name, &anisotropy);

  if (container == GltfContainer::kBinary) {
    // GLB (glTF 2.0, "Binary glTF Layout"): a 12-byte header, the JSON chunk (padded with spaces) and one BIN chunk
    // (padded with zeros) holding the quad and the PNGs, each image in a bufferView of its own at a 4-byte boundary.
    for (size_t k = 0; k < pngs.size(); ++k) {
      auto bytes = encode_png(*pngs[k].second);
      if (!bytes) return bytes.error();
      bin.append((4 - bin.size() % 4) % 4, '\0');
      gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes->size()}});
      gltf["images"][k] = {{"bufferView", gltf["bufferViews"].size() - 1}, {"mimeType", "image/png"}};
      bin += *bytes;
    }
    bin.append((4 - bin.size() % 4) % 4, '\0');
    gltf["buffers"] = Json::array({{{"byteLength", bin.size()}}});
    std::string json = gltf.dump();
    json.append((4 - json.size() % 4) % 4, ' ');
    std::string glb;
    auto put_u32 = [&glb](uint32_t v) {
      char b[4];
      std::memcpy(b, &v, 4);  // little-endian, as every platform vdrig builds on
      glb.append(b, 4);
    };
    put_u32(0x46546C67u);  // "glTF"
    put_u32(2);
    put_u32(static_cast<uint32_t>(12 + 8 + json.size() + 8 + bin.size()));
    put_u32(static_cast<uint32_t>(json.size()));
    put_u32(0x4E4F534Au);  // "JSON"
    glb += json;
    put_u32(static_cast<uint32_t>(bin.size()));
    put_u32(0x004E4942u);  // "BIN"
    glb += bin;
    result.gltf = dir / (name + ".glb");
    VDRIG_TRY(write_file_atomic(result.gltf, glb));
    result.written = {result.gltf};
    return result;
  }

  result.gltf = dir / (name + ".gltf");
  VDRIG_TRY(write_file_atomic(dir / bin_name, bin));
  result.written = {dir / bin_name};
  for (const auto& [file, image] : pngs) {
    VDRIG_TRY(write_png(dir / file, *image));
    result.written.push_back(dir / file);
  }
  VDRIG_TRY(write_file_atomic(result.gltf, gltf.dump(1) + "\n"));
  result.written.push_back(result.gltf);
  return result;
}

}  // namespace vdrig::pipeline
