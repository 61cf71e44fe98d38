// Private to rti/: an RTI stack's photographs opened at once and read a band of rows at a time (JPEG through
// libjpeg's scanline interface, so a decoder holds a few rows, not the image; other formats decoded whole), shared
// by the one-pass fits (stack_fit.cpp) and the rbf basis (pca_basis.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/rti/import.hpp"
#include "vdrig/rti/light_positions.hpp"

namespace vdrig::rti {

class RowSource;

/// Value tables of the three channels (R G B) for 8- or 16-bit codes (linear_table.hpp).
using ValueTables = std::array<std::vector<float>, 3>;

/// A stack's .lp (`stack` itself, or the single .lp in the folder `stack`) and its images, every one checked to
/// exist (kNotFound naming it) before any is decoded.
struct StackList {
  std::filesystem::path lp_file;
  std::vector<LightPosition> lights;
};
Result<StackList> list_stack(const std::filesystem::path& stack);

/// Images of a stack, all open, read from the top a band of rows at a time.
class StackRows {
 public:
  /// Opens images `views` of `list` (indices into list.lights, in this order). Errors: kInvalidArgument for an
  /// image whose size differs from the first's, a crop outside the images, an 8-bit JPEG with another response's
  /// bits; kCorrupt/kIo from the decoders, naming the file.
  static Result<StackRows> open(const StackList& list, const std::vector<int>& views, const Linearisation& lin,
                                const std::optional<cv::Rect>& crop);
  StackRows(StackRows&&) noexcept;
  StackRows& operator=(StackRows&&) noexcept;
  ~StackRows();

  int width() const { return crop_.width; }
  int height() const { return crop_.height; }
  int images() const { return static_cast<int>(sources_.size()); }

  /// The next `rows` rows of every image (as fitted values), decoded on `threads` threads: image j's value of
  /// channel c (R G B) at texel x of the band (x counts the band's texels row by row) goes to
  /// out[j * image_stride + x * texel_stride + c].
  Status read_rows(int rows, float* out, std::ptrdiff_t image_stride, std::ptrdiff_t texel_stride, int threads);
  /// The same for image j alone (images may be read concurrently, each by one thread): out[x * texel_stride + c].
  Status read_image_rows(int j, int rows, float* out, std::ptrdiff_t texel_stride);

 private:
  StackRows();
  std::unique_ptr<ValueTables> tables8_;  // the JPEG sources' (their pointer stays valid when this moves)
  std::vector<std::unique_ptr<RowSource>> sources_;
  cv::Rect crop_;
};

/// Runs body(i) for i in [0, n) on `threads` threads (the calling one included), each taking every threads-th i.
template <typename Body>
void parallel_for_strided(int n, int threads, const Body& body) {
  std::vector<std::thread> pool;
  for (int w = 1; w < threads; ++w)
    pool.emplace_back([&, w] {
      for (int i = w; i < n; i += threads) body(i);
    });
  for (int i = 0; i < n; i += threads) body(i);
  for (auto& t : pool) t.join();
}

}  // namespace vdrig::rti
