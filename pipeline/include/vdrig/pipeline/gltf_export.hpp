// A fitted BRDF map as a glTF 2.0 material (`vdrig export MAP --format gltf --out DIR`): one quad of the sample's
// physical size carrying the material, for Blender, three.js and the other renderers that speak glTF's
// metallic-roughness BRDF. Only BRDF models (fitting/ggx_model.hpp) are exported; a view-only model (Phong lobes,
// SH, HSH, PTM: radiance under the session's light, not a material) is refused with the reason.
//
// DIR/<name>.gltf, DIR/<name>.bin (the quad), and PNG textures beside them:
//  - <name>_basecolor.png: the albedo, sRGB-encoded 8 bit (glTF: baseColorTexture is sRGB), clamped to [0, 1];
//  - <name>_metallicroughness.png: linear 8 bit, roughness in G, metallic 0 in B (R unused, 0);
//  - <name>_specular.png (only when some texel's F0 is not 0.04 within kF0Tolerance): KHR_materials_specular's
//    specularColorTexture, F0 / max F0 sRGB-encoded in 16 bit (8-bit sRGB reads wrong in Blender 3.4: docs/blender.md),
//    specularColorFactor max F0 / 0.04: glTF's F0 = 0.04 x factor x texture is the fitted F0 (specularFactor 1, F90 1);
//  - <name>_normal.png (ggx:iso+n, aniso+n): normalTexture, linear 8 bit, the shading normal in tangent space as glTF
//    encodes it (0.5 + 0.5 n): red along the surface's +x, green along its -y (glTF's green points up the image,
//    toward smaller v), blue the geometric normal; the quad then carries an explicit TANGENT (+x, w = -1);
//  - <name>_anisotropy.png (ggx:aniso, aniso+n): KHR_materials_anisotropy's anisotropyTexture, linear 8 bit: RG the
//    rougher direction in the same tangent space (0.5 + 0.5 (cos angle, -sin angle)), B the strength with
//    alpha_t = mix(alpha_b, 1, strength^2); the metallic-roughness texture then holds roughness.b (glTF's alpha_b).
// GltfContainer::kBinary (`--format glb`) writes the same as one DIR/<name>.glb: the JSON chunk, then one BIN chunk
// holding the quad and the PNGs (images by bufferView and mimeType, no URIs).
// Geometry: glTF is Y-up; the surface frame (x right, y, z the normal) maps to glTF (x, z, -y), the quad centred at
// the origin, normal +Y. UV (0, 0) is the image's first row and column (glTF's convention), which is the parameter
// map's texel (0, 0) at the surface's smallest x and y, so u = (x + W/2) / W, v = (y + H/2) / H.
// What glTF's BRDF does differently (docs/models.md, "BRDF models"): its dielectric diffuse is weighted by 1 - F
// (albedo scaling); vdrig's is not.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::pipeline {

/// Separate files (NAME.gltf, NAME.bin, PNGs) or one self-contained NAME.glb (binary glTF: the same JSON, the
/// buffer and the PNGs in its BIN chunk).
enum class GltfContainer { kSeparateFiles, kBinary };

struct GltfExport {
  std::filesystem::path gltf;                  // the .gltf (or .glb) file
  std::vector<std::filesystem::path> written;  // every file written (gltf, bin, textures)
  bool specular_extension = false;             // KHR_materials_specular was needed (F0 not 0.04)
  int clipped_texels = 0;                      // texels whose albedo exceeded 1 in some channel (clamped)
};

/// F0 within this of 0.04 everywhere: plain metallic-roughness, no KHR_materials_specular.
inline constexpr double kF0Tolerance = 0.005;

/// Writes `map` as DIR/<name>.gltf with its buffer and textures (the folder is made when missing; files are written
/// atomically). kInvalidArgument naming the model and why for a map of a view-only model; kIo when a file cannot
/// be written.
Result<GltfExport> export_gltf(const fitting::ParameterMap& map, const std::filesystem::path& dir,
                               const std::string& name = "material",
                               GltfContainer container = GltfContainer::kSeparateFiles);

}  // namespace vdrig::pipeline
