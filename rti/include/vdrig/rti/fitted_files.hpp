// Reading fitted RTI files that other programs (relight-cli, RTIBuilder, PTMfitter) or vdrig wrote into parameter
// maps (fitting/parameter_map.hpp), so that `vdrig view`, `render`, `compare` and `rti export` work on them:
//  - .ptm, PTM 1.2: PTM_FORMAT_RGB -> ptm:rgb, PTM_FORMAT_LRGB -> ptm:lrgb (uncompressed only; the JPEG-compressed
//    PTM formats are refused by name);
//  - .rti, "#HSH1.2" (RTIViewer's hemispherical harmonics, file type 3), 4 or 9 terms -> hsh:2 or hsh:3, converted
//    from RTIViewer's HSH basis into vdrig's (export.hpp's vdrig_to_rti_hsh, inverted);
//  - relight's web format (a folder with info.json and plane_<k>.jpg, or the info.json itself), type "ptm" or "hsh"
//    in colour space "rgb" -> ptm:rgb, hsh:2, hsh:3; type "rbf" in "mrgb" (relight's default, pca_basis.hpp) ->
//    a least-squares fit of `rbf_model` to what OpenLIME shows at the basis's lights (lossy: rbf_parameter_map).
//    Other compressed bases (bilinear, colour spaces mycc, ycc, lrgb) are refused naming what was found.
// The layouts are those docs/rti.md gives (the readers of OpenLIME, relight's src/rti.cpp and src/legacy_rti.cpp);
// values are in [0, 1] units (code / 255), as vdrig's own RTI fits of codes. Texel (s, t) is image column s and row
// H - 1 - t, as in import.hpp; the map's size in mm is its size in pixels.
#pragma once

#include <filesystem>
#include <string>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::rti {

/// True when `path` names a fitted file this reader takes (by its name: .ptm, .rti, info.json, or a folder holding
/// an info.json); the stack importer takes the rest (.lp files and folders with one).
bool is_fitted_file(const std::filesystem::path& path);

/// Reads a fitted file. Errors: kNotFound (missing file, missing plane), kCorrupt (a truncated or malformed file:
/// the message names the field), kUnsupported for formats named above as refused, kInvalidArgument for sizes out
/// of range (more than 16384 texels a side).
Result<fitting::ParameterMap> read_fitted_file(const std::filesystem::path& path,
                                               const std::string& rbf_model = "hsh:3");

}  // namespace vdrig::rti
