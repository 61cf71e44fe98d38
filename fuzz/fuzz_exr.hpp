// What the two EXR targets share.
#pragma once

#include <OpenEXR/ImfHeader.h>

#include "fuzz_support.hpp"

namespace vdrig::fuzz {

/// The scratch file of an EXR target. Images are capped at 1024 x 1024 through OpenEXR's own limit (checked when a
/// header is read): a mutated data window of millions of pixels would spend the run allocating and zeroing planes,
/// and over libFuzzer's 2 GB it is reported as a crash. read_exr has no size limit of its own yet (issue #18:
/// "validate maps on load and state the limit"), so this is a setting of the fuzz run, not of vdrig.
inline std::filesystem::path exr_scratch_file(const std::string& name) {
  Imf::Header::setMaxImageSize(1024, 1024);
  Imf::Header::setMaxTileSize(1024, 1024);
  return scratch_dir() / name;
}

}  // namespace vdrig::fuzz
