#include "vdrig/cluster/distributed_fit.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <cstring>

#include "vdrig/core/log.hpp"

namespace vdrig::cluster {
namespace {

// Message tags of the master/worker loop.
constexpr int kTagReady = 1;   // worker -> 0: ready for a tile (empty)
constexpr int kTagDone = 2;    // worker -> 0: u32 tile, then the tile's summary (shared lights: its lobe rays)
constexpr int kTagFailed = 3;  // worker -> 0: u32 tile, then the error's text
constexpr int kTagTile = 4;    // 0 -> worker: u32 tile to fit
constexpr int kTagEnd = 5;     // 0 -> worker: no more tiles in this pass

Bytes with_tile(uint32_t tile, const Bytes& rest = {}) {
  Bytes b(4 + rest.size());
  std::memcpy(b.data(), &tile, 4);
  if (!rest.empty()) std::memcpy(b.data() + 4, rest.data(), rest.size());
  return b;
}
uint32_t tile_of(const Bytes& b) {
  uint32_t k = 0;
  if (b.size() >= 4) std::memcpy(&k, b.data(), 4);
  return k;
}

/// The pass's record of tile k: fitted (pass > 0: from the previous pass's record) and stored.
Result<Bytes> fit_and_record(fitting::TiledMapFit& fit, const TileStore& store, int pass, int k) {
  std::optional<Bytes> previous;
  if (pass > 0) {
    auto prior = store.read(pass - 1, k);
    if (!prior) return prior.error();
    previous = std::move(prior.value());
  }
  auto record = fit.fit_tile(pass, k, previous ? &*previous : nullptr);
  if (!record) return record.error();
  VDRIG_TRY(store.write(pass, k, record.value()));
  return record;
}

}  // namespace

std::string fit_fingerprint(const fitting::ObsMapReader& obs, const fitting::MapFitOptions& options) {
  const fitting::ObsFileHeader& h = obs.header();
  return fitting::fit_options_fingerprint(options) +
         fmt::format(";obs={}x{}x{},mm:{}x{},tile:{},compression:{},bytes:{},index:{:016x}", h.spec.texels_s,
                     h.spec.texels_t, h.views, h.spec.width_mm, h.spec.height_mm, h.tile_size,
                     static_cast<int>(h.compression), h.file_bytes, h.index_checksum);
}

Result<std::optional<fitting::ParameterMap>> fit_distributed(Comm& comm, const fitting::ObsMapReader& obs,
                                                             const fitting::MapFitOptions& options,
                                                             const DistributedFitOptions& d) {
  auto logger = log::get("cluster");
  const int rank = comm.rank(), ranks = comm.size();
  auto fit = fitting::TiledMapFit::create(obs, options);
  if (!fit) return fit.error();
  auto store = TileStore::open(d.tiles_root, fit_fingerprint(obs, options), rank == 0);
  if (!store) return store.error();
  // Rank 0 has written fit.txt before any worker records a tile.
  VDRIG_TRY(comm.barrier());
  const int tiles = fit->tiles(), passes = fit->passes();
  int recorded = 0;  // by this rank, for the test hook

  for (int pass = 0; pass < passes; ++pass) {
    const bool gather = pass + 1 < passes;
    if (rank == 0) {
      std::vector<Bytes> summaries(gather ? tiles : 0);
      std::vector<int> pending;
      for (int k = 0; k < tiles; ++k) {
        auto record = store->read(pass, k);
        if (!record) {
          if (record.error().code != ErrorCode::kNotFound)
            logger->warn("{}; the tile is fitted again", record.error().message);
          pending.push_back(k);
          continue;
        }
        if (gather) {
          auto summary = fit->summary(pass, k, record.value());
          if (!summary) return summary.error();
          summaries[static_cast<size_t>(k)] = std::move(summary.value());
        }
      }
      logger->info("pass {}/{}: {} of {} tiles already recorded in {}, {} to fit on {}", pass + 1, passes,
                   tiles - static_cast<int>(pending.size()), tiles, store->folder().string(), pending.size(),
                   ranks == 1 ? "rank 0" : fmt::format("{} worker ranks", ranks - 1));
      int done = 0;
      const int total = static_cast<int>(pending.size());
      if (ranks == 1) {
        for (int k : pending) {
          auto record = fit_and_record(fit.value(), store.value(), pass, k);
          if (!record)
            return make_error(record.error().code,
                              fmt::format("rank 0, pass {}, tile {}: {}", pass + 1, k, record.error().message));
          if (gather) {
            auto summary = fit->summary(pass, k, record.value());
            if (!summary) return summary.error();
            summaries[static_cast<size_t>(k)] = std::move(summary.value());
          }
          if (d.on_tile) d.on_tile(pass, ++done, total);
        }
      } else {
        // The dispatcher: who holds which tile is logged as it is handed out, so that the log of a job ended by a
        // lost rank names the rank and its tile.
        std::vector<int> holding(static_cast<size_t>(ranks), -1);
        size_t next = 0;
        int active = ranks - 1;
        while (active > 0) {
          auto m = comm.receive(-1);
          if (!m) return m.error();
          if (m->tag == kTagFailed) {
            const std::string why(m->bytes.begin() + std::min<size_t>(4, m->bytes.size()), m->bytes.end());
            return make_error(ErrorCode::kIo, fmt::format("rank {} failed on tile {} (pass {}): {}", m->from,
                                                          tile_of(m->bytes), pass + 1, why));
          }
          if (m->tag == kTagDone) {
            const int k = static_cast<int>(tile_of(m->bytes));
            if (gather) summaries[static_cast<size_t>(k)] = Bytes(m->bytes.begin() + 4, m->bytes.end());
            holding[static_cast<size_t>(m->from)] = -1;
            logger->debug("pass {} tile {} recorded by rank {}", pass + 1, k, m->from);
            if (d.on_tile) d.on_tile(pass, ++done, total);
          }
          if (next < pending.size()) {
            const int k = pending[next++];
            holding[static_cast<size_t>(m->from)] = k;
            logger->info("pass {} tile {} -> rank {}", pass + 1, k, m->from);
            VDRIG_TRY(comm.send(m->from, kTagTile, with_tile(static_cast<uint32_t>(k))));
          } else {
            VDRIG_TRY(comm.send(m->from, kTagEnd, {}));
            --active;
          }
        }
      }
      if (gather) {
        auto state = fit->pass_state(pass, summaries);
        if (!state) return state.error();
        auto shared = comm.broadcast(state.value(), 0);
        if (!shared) return shared.error();
        VDRIG_TRY(fit->set_pass_state(pass, shared.value()));
      }
    } else {
      VDRIG_TRY(comm.send(0, kTagReady, {}));
      for (;;) {
        auto m = comm.receive(0);
        if (!m) return m.error();
        if (m->tag == kTagEnd) break;
        const int k = static_cast<int>(tile_of(m->bytes));
        auto record = fit_and_record(fit.value(), store.value(), pass, k);
        Result<Bytes> summary = Bytes{};
        if (record && gather) summary = fit->summary(pass, k, record.value());
        if (!record || !summary) {
          const std::string why = !record ? record.error().message : summary.error().message;
          Bytes text(why.begin(), why.end());
          VDRIG_TRY(comm.send(0, kTagFailed, with_tile(static_cast<uint32_t>(k), text)));
          // Rank 0 ends the job; wait for that rather than race it with an exit of our own.
          return make_error(ErrorCode::kIo, fmt::format("rank {}, tile {}: {}", rank, k, why));
        }
        if (d.test_exit_after_tiles > 0 && ++recorded >= d.test_exit_after_tiles) {
          // TEST HOOK: a rank lost mid-fit (no MPI_Finalize, no reply to rank 0).
          logger->warn("test hook: rank {} exits after recording {} tiles", rank, recorded);
          logger->flush();
          ::_exit(42);
        }
        VDRIG_TRY(comm.send(0, kTagDone, with_tile(static_cast<uint32_t>(k), summary.value())));
      }
      if (gather) {
        auto shared = comm.broadcast({}, 0);
        if (!shared) return shared.error();
        VDRIG_TRY(fit->set_pass_state(pass, shared.value()));
      }
    }
  }
  if (rank != 0) return std::optional<fitting::ParameterMap>();
  auto map = fit->assemble([&](int k) { return store->read(passes - 1, k); });
  if (!map) return map.error();
  return std::optional<fitting::ParameterMap>(std::move(map.value()));
}

}  // namespace vdrig::cluster
