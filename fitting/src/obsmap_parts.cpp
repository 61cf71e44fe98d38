// assemble_obsmap_parts: the part files of an MPI build (cluster/, one per range of tile rows) joined into the file
// one writer would have written (docs/scale.md, docs/obsmap.md "Parts").
#include <unistd.h>

#include <algorithm>
#include <cstring>

#include "obsmap_checksum.hpp"
#include "obsmap_format.hpp"
#include "positional_file_io.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::fitting {
namespace fs = std::filesystem;
using namespace obsmap_format;

Status assemble_obsmap_parts(const std::vector<fs::path>& parts, const fs::path& path) {
  struct Part {
    fs::path path;
    UniqueFd fd;
    std::vector<char> header, index;
    uint32_t first = 0, end = 0;
  };
  if (parts.empty()) return make_error(ErrorCode::kInvalidArgument, "no observation-map parts to assemble");
  std::vector<Part> in(parts.size());
  for (size_t i = 0; i < parts.size(); ++i) {
    Part& p = in[i];
    p.path = parts[i];
    auto fd = open_for_reading(p.path);
    if (!fd) return fd.error();
    p.fd = std::move(fd.value());
    p.header.resize(kHeaderBytes);
    VDRIG_TRY(read_at(p.fd.get(), p.path, p.header.data(), kHeaderBytes, 0));
    auto corrupt = [&](const std::string& why) {
      return make_error(ErrorCode::kCorrupt, p.path.string() + ": " + why);
    };
    if (std::memcmp(p.header.data(), kPartMagic, 8) != 0) return corrupt("not an observation-map part");
    if (!obsmap_checksum_matches(get<uint64_t>(p.header, kAtHeaderChecksum), p.header.data(), kAtHeaderChecksum))
      return corrupt("header checksum");
    // Every field but the rows, the index's place and the checksums must be the first part's.
    if (i > 0 && (std::memcmp(p.header.data(), in[0].header.data(), kAtIndexOffset) != 0))
      return corrupt("a part of another observation map than " + in[0].path.string());
    p.first = get<uint32_t>(p.header, kAtPartFirstRow);
    p.end = get<uint32_t>(p.header, kAtPartEndRow);
    p.index.resize(get<uint64_t>(p.header, kAtIndexBytes));
    VDRIG_TRY(read_at(p.fd.get(), p.path, p.index.data(), p.index.size(), get<uint64_t>(p.header, kAtIndexOffset)));
    if (!obsmap_checksum_matches(get<uint64_t>(p.header, kAtIndexChecksum), p.index.data(), p.index.size()))
      return corrupt("index checksum");
  }
  const std::vector<char>& h0 = in[0].header;
  const ObservationMapSpec spec{get<int32_t>(h0, kAtTexelsS), get<int32_t>(h0, kAtTexelsT), get<double>(h0, kAtWidthMm),
                                get<double>(h0, kAtHeightMm)};
  const int views = get<int32_t>(h0, kAtViews);
  const TileGrid grid(spec.texels_s, spec.texels_t, get<int32_t>(h0, kAtTileSize));
  const auto compression = static_cast<ObsCompression>(get<uint32_t>(h0, kAtCompression));
  if (in[0].index.size() != kIndexEntryBytes * static_cast<size_t>(grid.count()))
    return make_error(ErrorCode::kCorrupt, in[0].path.string() + ": index size disagrees with the tile count");
  // Which part holds each tile row: exactly one.
  std::vector<int> owner(static_cast<size_t>(grid.tiles_t), -1);
  for (size_t i = 0; i < in.size(); ++i)
    for (uint32_t r = in[i].first; r < in[i].end && r < owner.size(); ++r) {
      if (owner[r] >= 0)
        return make_error(ErrorCode::kInvalidArgument, "tile row " + std::to_string(r) + " is in two parts");
      owner[r] = static_cast<int>(i);
    }
  for (size_t r = 0; r < owner.size(); ++r)
    if (owner[r] < 0) return make_error(ErrorCode::kInvalidArgument, "no part holds tile row " + std::to_string(r));

  fs::path tmp;
  auto created = create_temporary_beside(path, &tmp);
  if (!created) return created.error();
  UniqueFd out = std::move(created.value());
  struct Cleanup {
    const fs::path& p;
    bool keep = false;
    ~Cleanup() {
      if (!keep) ::unlink(p.c_str());
    }
  } cleanup{tmp};
  uint64_t offset = kHeaderBytes;
  std::vector<char> index(kIndexEntryBytes * static_cast<size_t>(grid.count()), 0), stored;
  for (int k = 0; k < grid.count(); ++k) {
    const Part& p = in[static_cast<size_t>(owner[static_cast<size_t>(k / grid.tiles_s)])];
    const uint64_t at = get<uint64_t>(p.index, kIndexEntryBytes * k),
                   n = get<uint64_t>(p.index, kIndexEntryBytes * k + 8);
    const uint64_t hash = get<uint64_t>(p.index, kIndexEntryBytes * k + 16);
    if (n > (uint64_t{1} << 32))
      return make_error(ErrorCode::kCorrupt, p.path.string() + ": tile " + std::to_string(k) + " too large");
    stored.resize(n);
    VDRIG_TRY(read_at(p.fd.get(), p.path, stored.data(), n, at));
    if (!obsmap_checksum_matches(hash, stored.data(), n))
      return make_error(ErrorCode::kCorrupt, p.path.string() + ": tile " + std::to_string(k) + " checksum mismatch");
    VDRIG_TRY(write_at(out.get(), tmp, stored.data(), n, offset));
    put<uint64_t>(index, kIndexEntryBytes * k, offset);
    put<uint64_t>(index, kIndexEntryBytes * k + 8, n);
    put<uint64_t>(index, kIndexEntryBytes * k + 16, hash);
    offset += n;
  }
  VDRIG_TRY(write_at(out.get(), tmp, index.data(), index.size(), offset));
  const std::vector<char> header = make_header(kMagic, spec, views, grid, compression, offset, index);
  VDRIG_TRY(write_at(out.get(), tmp, header.data(), header.size(), 0));
  out.reset();
  // fsync, rename over `path` (refused when it is a link or not a regular file), fsync of the folder.
  cleanup.keep = true;  // commit_temporary removes the temporary itself when it fails
  VDRIG_TRY(commit_temporary(tmp, path));
  log::get("fitting")->info("observation map {} assembled from {} parts: {:.1f} MB", path.string(), parts.size(),
                            (offset + index.size()) / 1e6);
  return Status::ok();
}

}  // namespace vdrig::fitting
