// Writing fitted parameter maps (fitting/parameter_map.hpp) in the formats RTI viewers read (docs/rti.md has the
// byte layouts and how to view each):
//  - .ptm, PTM 1.2 (HP Labs' "PTM File Format" 1.2): PTM_FORMAT_RGB from a ptm:rgb map, PTM_FORMAT_LRGB from a
//    ptm:lrgb map; RTIViewer and OpenLIME's PTM layers read it.
//  - .rti, "#HSH1.2" (RTIViewer's hemispherical-harmonics file, as RTIBuilder writes it) from an hsh:2 or hsh:3 map,
//    the coefficients converted into RTIViewer's HSH basis (rti_hsh_basis).
//  - relight's web format (info.json + plane_<k>.jpg), as OpenLIME's RTI layer loads it, from ptm:rgb or hsh:N.
// Values: the viewers work in 8-bit display codes, so radiance r is written as the code 255 r (1.0 = code 255);
// the viewers show the value itself as the display code (OpenLIME decodes it with srgb2linear and re-encodes it for
// the screen), so the map must hold fitted codes: `vdrig rti import`'s default `--response codes`. Rows are written
// bottom to top (texel row t = 0 first) in .ptm, top to bottom in .rti and the JPEG planes (as the viewers read
// them). relight's PTM planes are in its order (1, x, y, x^2, xy, y^2), the .ptm file's in PTM 1.2's.
//
// Quantisation: every coefficient k gets a range [lo_k, hi_k] over the map (and over R, G, B where the format
// shares one scale); .ptm stores a = (byte - bias_k) scale_k with an integer bias, .rti a = byte / 255 scale_k +
// bias_k, relight a = (byte / 255 - bias_k) scale_k. The error per coefficient is at most one quantisation step
// (half a step inside the range; .ptm's integer bias can move the ends by half a step).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::rti {

enum class ExportFormat { kPtm, kRti, kRelight };

/// "ptm", "rti", "relight"; kInvalidArgument otherwise.
Result<ExportFormat> parse_export_format(const std::string& text);

struct ExportOptions {
  int jpeg_quality = 95;  // relight planes, 1..100
};

/// Writes `map` to `out` (a file for ptm and rti, a folder for relight). kInvalidArgument when the map's model has
/// no such format (e.g. phong to .ptm); kIo/kNoSpace when writing fails.
Status export_map(const fitting::ParameterMap& map, ExportFormat format, const std::filesystem::path& out,
                  const ExportOptions& options = {});

/// RTIViewer's HSH basis (terms = 4 or 9) at a unit direction (theta = zenith, phi = atan2(y, x)), in its order:
/// 1/sqrt(2 pi), sqrt(6/pi) cos(phi) sqrt(z - z^2), sqrt(3/(2 pi)) (2z - 1), ...
void rti_hsh_basis(int terms, const Vec3d& v, double* out);

/// The terms x terms matrix taking vdrig's HSH coefficients (hsh.hpp) of `bands` (2 or 3) bands to RTIViewer's.
Eigen::MatrixXd vdrig_to_rti_hsh(int bands);

}  // namespace vdrig::rti
