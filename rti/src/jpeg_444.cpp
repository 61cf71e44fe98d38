#include "jpeg_444.hpp"

#include <jpeglib.h>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace vdrig::rti {

Result<std::string> encode_jpeg_444(const cv::Mat& bgr, int quality) {
  if (bgr.type() != CV_8UC3 || bgr.empty())
    return make_error(ErrorCode::kInvalidArgument, "encode_jpeg_444: needs a non-empty CV_8UC3 image");
  jpeg_compress_struct cinfo{};
  jpeg_error_mgr jerr{};
  cinfo.err = jpeg_std_error(&jerr);
  // libjpeg's default error handler exits the process; nothing here can fail on valid memory input, so that is
  // only reached on a broken invariant.
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = static_cast<JDIMENSION>(bgr.cols);
  cinfo.image_height = static_cast<JDIMENSION>(bgr.rows);
  cinfo.input_components = 3;
  cinfo.in_color_space = JCS_RGB;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  for (int c = 0; c < 3; ++c) {
    cinfo.comp_info[c].h_samp_factor = 1;
    cinfo.comp_info[c].v_samp_factor = 1;
  }
  jpeg_start_compress(&cinfo, TRUE);
  std::vector<unsigned char> row(static_cast<size_t>(bgr.cols) * 3);
  while (cinfo.next_scanline < cinfo.image_height) {
    const auto* src = bgr.ptr<uint8_t>(static_cast<int>(cinfo.next_scanline));
    for (int x = 0; x < bgr.cols; ++x)
      for (int c = 0; c < 3; ++c) row[3 * x + c] = src[3 * x + 2 - c];
    JSAMPROW rows[1] = {row.data()};
    jpeg_write_scanlines(&cinfo, rows, 1);
  }
  jpeg_finish_compress(&cinfo);
  std::string out(reinterpret_cast<const char*>(buffer), size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return out;
}

}  // namespace vdrig::rti
