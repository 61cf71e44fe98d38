// PNG, JPEG and TIFF with libpng, libjpeg and libtiff directly, not OpenCV's imgcodecs: Debian's imgcodecs links
// GDAL, GDCM, HDF5, Poppler and ~100 more libraries, which cost every vdrig process ~0.15 s CPU and ~50 MB before
// main (issue #25).
//
// Both libraries report errors by calling a function that must not return: here it records the message and
// longjmps back to the setjmp of the call that failed. The functions holding a setjmp keep only trivially
// destructible locals (a longjmp skips destructors); what they produce lives in a state struct of the caller, and
// their C++ work (allocations, strings) is in helpers that are not inlined into them: GCC's -Wclobbered flags a
// std::string's inlined internals as live across the setjmp, and the ASan build fails on it.
#include <jerror.h>
#include <png.h>
#include <tiffio.h>
#include <zlib.h>

#include <bit>
#include <csetjmp>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"
// jpeglib.h needs size_t and FILE declared first.
#include <jpeglib.h>

namespace vdrig {
namespace {

// decode_image's limits (documented in image_io.hpp): the largest sensors vdrig drives are well inside.
constexpr uint64_t kMaxSide = 16384;
constexpr uint64_t kMaxPixels = 100'000'000;

bool too_large(uint64_t width, uint64_t height) {
  return width > kMaxSide || height > kMaxSide || width * height > kMaxPixels;
}

Error size_refused(const std::string& name, uint64_t width, uint64_t height, const char* format) {
  return make_error(ErrorCode::kInvalidArgument, name + " is a " + std::to_string(width) + "x" +
                                                     std::to_string(height) + " " + format + "; at most " +
                                                     std::to_string(kMaxSide) + " px a side and " +
                                                     std::to_string(kMaxPixels / 1000000) + " Mpx are read");
}

constexpr bool kLittleEndian = std::endian::native == std::endian::little;

// ---- PNG decoding

struct PngDecode {
  std::string_view bytes;
  size_t at = 0;
  ImageDecode mode = ImageDecode::kUnchanged;
  char error[256] = "";  // libpng's message when false is returned (a C string: see the top of the file)
  bool refused = false;
  uint64_t width = 0, height = 0;
  cv::Mat image;
  std::vector<png_bytep> rows;
  png_structp png = nullptr;  // here, not locals of png_decode: they live across its setjmp
  png_infop info = nullptr;
};

void set_error(char (&error)[256], const char* message) { std::snprintf(error, sizeof error, "%s", message); }

void png_on_error(png_structp png, png_const_charp message) {
  set_error(static_cast<PngDecode*>(png_get_error_ptr(png))->error, message);
  png_longjmp(png, 1);
}
void png_on_warning(png_structp /*png*/, png_const_charp /*message*/) {}  // e.g. an unknown sRGB profile

void png_read_bytes(png_structp png, png_bytep out, size_t n) {
  auto* d = static_cast<PngDecode*>(png_get_io_ptr(png));
  if (d->bytes.size() - d->at < n) png_error(png, "truncated: the file ends early");
  std::memcpy(out, d->bytes.data() + d->at, n);
  d->at += n;
}

/// The image and its row pointers, outside png_decode (see the top of the file).
[[gnu::noinline]] void allocate(PngDecode& d, int rows, int cols, int type) {
  d.image.create(rows, cols, type);
  d.rows.resize(static_cast<size_t>(rows));
  for (int r = 0; r < rows; ++r) d.rows[static_cast<size_t>(r)] = d.image.ptr<png_byte>(r);
}

/// Channels and depth as OpenCV's IMREAD_UNCHANGED (grey 1 channel, colour BGR, alpha or a tRNS chunk on colour
/// BGRA, depth kept) or IMREAD_COLOR (8-bit BGR). False with d.error or d.refused.
bool png_decode(PngDecode& d) {
  d.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &d, png_on_error, png_on_warning);
  if (!d.png) {
    set_error(d.error, "out of memory");
    return false;
  }
  d.info = png_create_info_struct(d.png);
  if (!d.info || setjmp(png_jmpbuf(d.png))) {
    png_destroy_read_struct(&d.png, &d.info, nullptr);
    if (d.error[0] == 0) set_error(d.error, "out of memory");
    return false;
  }
  const png_structp png = d.png;
  const png_infop info = d.info;
  png_set_read_fn(png, &d, png_read_bytes);
  png_read_info(png, info);
  png_uint_32 width = 0, height = 0;
  int depth = 0, color = 0;
  png_get_IHDR(png, info, &width, &height, &depth, &color, nullptr, nullptr, nullptr);
  d.width = width;
  d.height = height;
  if (too_large(width, height)) {
    d.refused = true;
    png_destroy_read_struct(&d.png, &d.info, nullptr);
    return false;
  }
  const bool trns = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
  const bool grey = (color & PNG_COLOR_MASK_COLOR) == 0;
  if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (grey && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (d.mode == ImageDecode::kBgr8) {
    if (depth == 16) png_set_strip_16(png);  // the high byte, as OpenCV
    if (color & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(png);
    if (grey) png_set_gray_to_rgb(png);
  } else {
    if (color == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);  // BGRA, as OpenCV
    if (!grey && trns) png_set_tRNS_to_alpha(png);
    if (depth == 16 && kLittleEndian) png_set_swap(png);
  }
  if (!grey || color == PNG_COLOR_TYPE_GRAY_ALPHA || d.mode == ImageDecode::kBgr8) png_set_bgr(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const int channels = png_get_channels(png, info);
  const int out_depth = png_get_bit_depth(png, info);
  if ((channels != 1 && channels != 3 && channels != 4) || (out_depth != 8 && out_depth != 16)) {
    std::snprintf(d.error, sizeof d.error, "unexpected layout after conversion: %d channels of %d bits", channels,
                  out_depth);
    png_destroy_read_struct(&d.png, &d.info, nullptr);
    return false;
  }
  allocate(d, static_cast<int>(height), static_cast<int>(width),
           CV_MAKETYPE(out_depth == 16 ? CV_16U : CV_8U, channels));
  png_read_image(png, d.rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&d.png, &d.info, nullptr);
  return true;
}

// ---- JPEG decoding

struct JpegDecode {
  struct Errors {
    jpeg_error_mgr pub;  // first: libjpeg's cinfo->err points here
    std::jmp_buf jump;
    JpegDecode* self;
  };
  std::string_view bytes;
  ImageDecode mode = ImageDecode::kUnchanged;
  jpeg_decompress_struct cinfo{};
  Errors errors{};
  char error[256] = "";
  bool refused = false;
  bool truncated = false;
  uint64_t width = 0, height = 0;
  cv::Mat image;
  std::vector<uint8_t> cmyk_row;
};

void jpeg_on_error(j_common_ptr cinfo) {
  auto* errors = reinterpret_cast<JpegDecode::Errors*>(cinfo->err);
  char text[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, text);
  set_error(errors->self->error, text);
  std::longjmp(errors->jump, 1);
}

/// Warnings let the decoder go on (a stray byte before a marker is common in MJPEG frames), except the end of the
/// data before the image's end: libjpeg would fill the rest with grey, a truncated file taken as a photograph.
void jpeg_on_message(j_common_ptr cinfo, int level) {
  if (level == -1 && cinfo->err->msg_code == JWRN_JPEG_EOF)
    reinterpret_cast<JpegDecode::Errors*>(cinfo->err)->self->truncated = true;
}

/// Adobe's inverted CMYK to BGR, the conversion OpenCV applies.
void cmyk_to_bgr(const uint8_t* cmyk, uint8_t* bgr, int width) {
  for (int x = 0; x < width; ++x, cmyk += 4, bgr += 3) {
    const int k = cmyk[3];
    bgr[2] = static_cast<uint8_t>(k - (((255 - cmyk[0]) * k) >> 8));
    bgr[1] = static_cast<uint8_t>(k - (((255 - cmyk[1]) * k) >> 8));
    bgr[0] = static_cast<uint8_t>(k - (((255 - cmyk[2]) * k) >> 8));
  }
}

/// The image (and a CMYK row), outside jpeg_decode (see the top of the file).
[[gnu::noinline]] void allocate(JpegDecode& d, int rows, int cols, int type, bool cmyk) {
  d.image.create(rows, cols, type);
  if (cmyk) d.cmyk_row.resize(static_cast<size_t>(cols) * 4);
}

/// Grey stays one channel in kUnchanged mode, everything else becomes 8-bit BGR (as OpenCV). False with d.error,
/// d.refused or d.truncated.
bool jpeg_decode(JpegDecode& d) {
  d.cinfo.err = jpeg_std_error(&d.errors.pub);
  d.errors.pub.error_exit = jpeg_on_error;
  d.errors.pub.emit_message = jpeg_on_message;
  d.errors.self = &d;
  if (setjmp(d.errors.jump)) {
    jpeg_destroy_decompress(&d.cinfo);
    return false;
  }
  jpeg_decompress_struct& cinfo = d.cinfo;
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, reinterpret_cast<const unsigned char*>(d.bytes.data()), d.bytes.size());
  jpeg_read_header(&cinfo, TRUE);
  d.width = cinfo.image_width;
  d.height = cinfo.image_height;
  if (too_large(d.width, d.height)) {
    d.refused = true;
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  const bool cmyk = cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK;
  const bool grey = cinfo.jpeg_color_space == JCS_GRAYSCALE && d.mode == ImageDecode::kUnchanged;
  cinfo.out_color_space = cmyk ? JCS_CMYK : grey ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_start_decompress(&cinfo);
  const int width = static_cast<int>(cinfo.output_width);
  allocate(d, static_cast<int>(cinfo.output_height), width, grey ? CV_8UC1 : CV_8UC3, cmyk);
  while (cinfo.output_scanline < cinfo.output_height) {
    const int r = static_cast<int>(cinfo.output_scanline);
    JSAMPROW row = cmyk ? d.cmyk_row.data() : d.image.ptr<JSAMPLE>(r);
    if (jpeg_read_scanlines(&cinfo, &row, 1) != 1) break;
    if (cmyk) cmyk_to_bgr(d.cmyk_row.data(), d.image.ptr<uint8_t>(r), width);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return !d.truncated;
}

/// 8-bit BGR from an image as kUnchanged returns it (1, 3 or 4 channels, 8 or 16 bits): IMREAD_COLOR's layout.
cv::Mat to_bgr8(const cv::Mat& image) {
  cv::Mat eight = image;
  if (image.depth() == CV_16U) {
    eight.create(image.size(), CV_MAKETYPE(CV_8U, image.channels()));
    const size_t values = static_cast<size_t>(image.cols) * image.channels();
    for (int y = 0; y < image.rows; ++y) {
      const uint16_t* in = image.ptr<uint16_t>(y);
      uint8_t* out = eight.ptr<uint8_t>(y);
      for (size_t i = 0; i < values; ++i) out[i] = static_cast<uint8_t>(in[i] >> 8);  // the high byte, as OpenCV
    }
  }
  if (eight.channels() == 3) return eight;
  cv::Mat bgr(eight.size(), CV_8UC3);
  const int grey[] = {0, 0, 0, 1, 0, 2}, bgra[] = {0, 0, 1, 1, 2, 2};
  cv::mixChannels(&eight, 1, &bgr, 1, eight.channels() == 1 ? grey : bgra, 3);
  return bgr;
}

// ---- TIFF decoding (libtiff reports errors through a handler that returns: no longjmp here)

struct TiffDecode {
  std::string_view bytes;
  uint64_t at = 0;
  std::string error;
};

int tiff_on_error(TIFF* /*tif*/, void* user, const char* module, const char* format, va_list args) {
  char text[512];
  std::vsnprintf(text, sizeof text, format, args);
  auto* d = static_cast<TiffDecode*>(user);
  if (d->error.empty()) d->error = std::string(module ? module : "libtiff") + ": " + text;
  return 1;
}
int tiff_on_warning(TIFF* /*tif*/, void* /*user*/, const char* /*module*/, const char* /*format*/, va_list /*args*/) {
  return 1;  // unknown tags and the like: the reader goes on
}
tmsize_t tiff_read(thandle_t handle, void* out, tmsize_t n) {
  auto* d = static_cast<TiffDecode*>(handle);
  const uint64_t left = d->at < d->bytes.size() ? d->bytes.size() - d->at : 0;
  const uint64_t copied = std::min<uint64_t>(left, static_cast<uint64_t>(n));
  std::memcpy(out, d->bytes.data() + d->at, copied);
  d->at += copied;
  return static_cast<tmsize_t>(copied);
}
tmsize_t tiff_write(thandle_t /*handle*/, void* /*data*/, tmsize_t /*n*/) { return 0; }
toff_t tiff_seek(thandle_t handle, toff_t offset, int whence) {
  auto* d = static_cast<TiffDecode*>(handle);
  const uint64_t base = whence == SEEK_CUR ? d->at : whence == SEEK_END ? d->bytes.size() : 0;
  d->at = base + offset;
  return d->at;
}
int tiff_close(thandle_t /*handle*/) { return 0; }
toff_t tiff_size(thandle_t handle) { return static_cast<TiffDecode*>(handle)->bytes.size(); }
int tiff_map(thandle_t handle, void** base, toff_t* size) {
  auto* d = static_cast<TiffDecode*>(handle);
  *base = const_cast<char*>(d->bytes.data());
  *size = d->bytes.size();
  return 1;
}
void tiff_unmap(thandle_t /*handle*/, void* /*base*/, toff_t /*size*/) {}

/// The first image of a TIFF as kUnchanged: 8- or 16-bit unsigned grey or RGB(A) strips read as they are (grey
/// 1 channel, grey + alpha and RGBA as BGRA, RGB as BGR); anything else (tiles, palettes, YCbCr, CMYK, 1-bit...)
/// through libtiff's RGBA reader, 8-bit BGR or BGRA.
Result<cv::Mat> tiff_decode(std::string_view bytes, const std::string& name) {
  TiffDecode d;
  d.bytes = bytes;
  auto corrupt = [&](const std::string& what) {
    return make_error(ErrorCode::kCorrupt, "cannot decode " + name + " (TIFF): " + (d.error.empty() ? what : d.error));
  };
  TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
  TIFFOpenOptionsSetErrorHandlerExtR(options, tiff_on_error, &d);
  TIFFOpenOptionsSetWarningHandlerExtR(options, tiff_on_warning, &d);
  std::unique_ptr<TIFF, void (*)(TIFF*)> tif(TIFFClientOpenExt(name.c_str(), "rm", &d, tiff_read, tiff_write, tiff_seek,
                                                               tiff_close, tiff_size, tiff_map, tiff_unmap, options),
                                             TIFFClose);
  TIFFOpenOptionsFree(options);
  if (!tif) return corrupt("not readable");
  uint32_t width = 0, height = 0;
  uint16_t spp = 1, bps = 1, photometric = 0, planar = PLANARCONFIG_CONTIG, format = SAMPLEFORMAT_UINT;
  TIFFGetField(tif.get(), TIFFTAG_IMAGEWIDTH, &width);
  TIFFGetField(tif.get(), TIFFTAG_IMAGELENGTH, &height);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_BITSPERSAMPLE, &bps);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_PLANARCONFIG, &planar);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLEFORMAT, &format);
  TIFFGetField(tif.get(), TIFFTAG_PHOTOMETRIC, &photometric);
  if (width == 0 || height == 0) return corrupt("no image size");
  if (too_large(width, height)) return size_refused(name, width, height, "TIFF");
  const int h = static_cast<int>(height), w = static_cast<int>(width);
  const bool grey = photometric == PHOTOMETRIC_MINISBLACK && (spp == 1 || spp == 2);
  const bool rgb = photometric == PHOTOMETRIC_RGB && (spp == 3 || spp == 4);
  if ((grey || rgb) && (bps == 8 || bps == 16) && format == SAMPLEFORMAT_UINT && planar == PLANARCONFIG_CONTIG &&
      !TIFFIsTiled(tif.get())) {
    const int depth = bps == 16 ? CV_16U : CV_8U;
    cv::Mat row(1, w, CV_MAKETYPE(depth, spp));
    if (static_cast<size_t>(TIFFScanlineSize(tif.get())) != row.total() * row.elemSize())
      return corrupt("unexpected scanline size");
    cv::Mat image(h, w, CV_MAKETYPE(depth, spp == 2 ? 4 : spp));
    // Scanline channels to the image's: RGB(A) to BGR(A), grey + alpha to BGRA.
    const int to_bgr[] = {0, 2, 1, 1, 2, 0, 3, 3}, grey_alpha[] = {0, 0, 0, 1, 0, 2, 1, 3};
    for (int y = 0; y < h; ++y) {
      if (TIFFReadScanline(tif.get(), row.data, static_cast<uint32_t>(y), 0) < 0) return corrupt("row unreadable");
      cv::Mat out = image.row(y);
      if (spp == 1)
        row.copyTo(out);
      else
        cv::mixChannels(&row, 1, &out, 1, spp == 2 ? grey_alpha : to_bgr, static_cast<size_t>(spp == 2 ? 4 : spp));
    }
    return image;
  }
  std::vector<uint32_t> raster(static_cast<size_t>(w) * h);
  if (!TIFFReadRGBAImageOriented(tif.get(), width, height, raster.data(), ORIENTATION_TOPLEFT, 0))
    return corrupt("unsupported layout");
  uint16_t extra = 0;
  uint16_t* extra_types = nullptr;
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_EXTRASAMPLES, &extra, &extra_types);
  const bool alpha = extra > 0;
  cv::Mat image(h, w, alpha ? CV_8UC4 : CV_8UC3);
  for (int y = 0; y < h; ++y) {
    uint8_t* out = image.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x, out += image.channels()) {
      const uint32_t p = raster[static_cast<size_t>(y) * w + x];
      out[0] = static_cast<uint8_t>(TIFFGetB(p));
      out[1] = static_cast<uint8_t>(TIFFGetG(p));
      out[2] = static_cast<uint8_t>(TIFFGetR(p));
      if (alpha) out[3] = static_cast<uint8_t>(TIFFGetA(p));
    }
  }
  return image;
}

bool is_tiff(std::string_view bytes) {
  const std::string_view magic = bytes.substr(0, 4);  // classic TIFF, then BigTIFF, little- and big-endian
  return magic == std::string_view("II*\0", 4) || magic == std::string_view("MM\0*", 4) ||
         magic == std::string_view("II+\0", 4) || magic == std::string_view("MM\0+", 4);
}

// ---- PNG encoding

struct PngEncode {
  std::string bytes;
  char error[256] = "";
  std::vector<png_bytep> rows;
  png_structp png = nullptr;  // here, not locals of png_encode: they live across its setjmp
  png_infop info = nullptr;
};

void png_on_encode_error(png_structp png, png_const_charp message) {
  set_error(static_cast<PngEncode*>(png_get_error_ptr(png))->error, message);
  png_longjmp(png, 1);
}

void png_write_bytes(png_structp png, png_bytep data, size_t n) {
  static_cast<PngEncode*>(png_get_io_ptr(png))->bytes.append(reinterpret_cast<const char*>(data), n);
}
void png_flush(png_structp /*png*/) {}

bool png_encode(PngEncode& e, const cv::Mat& image, PngCompression compression) {
  e.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &e, png_on_encode_error, png_on_warning);
  if (!e.png) {
    set_error(e.error, "out of memory");
    return false;
  }
  e.info = png_create_info_struct(e.png);
  if (!e.info || setjmp(png_jmpbuf(e.png))) {
    png_destroy_write_struct(&e.png, &e.info);
    if (e.error[0] == 0) set_error(e.error, "out of memory");
    return false;
  }
  const png_structp png = e.png;
  const png_infop info = e.info;
  png_set_write_fn(png, &e, png_write_bytes, png_flush);
  const int channels = image.channels();
  const int color = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
  const int depth = image.depth() == CV_16U ? 16 : 8;
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows), depth, color,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // zlib level 1 and its RLE strategy, as OpenCV wrote them; kFastest also keeps only the SUB filter (OpenCV's
  // default path) where libpng would otherwise try every filter on every row.
  png_set_compression_level(png, Z_BEST_SPEED);
  png_set_compression_strategy(png, Z_RLE);
  if (compression == PngCompression::kFastest) png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_write_info(png, info);
  if (channels >= 3) png_set_bgr(png);
  if (depth == 16 && kLittleEndian) png_set_swap(png);
  png_write_image(png, e.rows.data());
  png_write_end(png, info);
  png_destroy_write_struct(&e.png, &e.info);
  return true;
}

// ---- JPEG encoding

struct JpegEncode {
  struct Errors {
    jpeg_error_mgr pub;  // first: libjpeg's cinfo->err points here
    std::jmp_buf jump;
    JpegEncode* self;
  };
  jpeg_compress_struct cinfo{};
  Errors errors{};
  char error[256] = "";
  unsigned char* buffer = nullptr;  // jpeg_mem_dest's, freed by the caller
  unsigned long size = 0;
};

void jpeg_on_encode_error(j_common_ptr cinfo) {
  auto* errors = reinterpret_cast<JpegEncode::Errors*>(cinfo->err);
  char text[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, text);
  set_error(errors->self->error, text);
  std::longjmp(errors->jump, 1);
}

/// libjpeg's defaults (4:2:0 chroma for colour, as OpenCV's imencode), BGR or grey rows straight from the image.
bool jpeg_encode(JpegEncode& e, const cv::Mat& image, int quality) {
  e.cinfo.err = jpeg_std_error(&e.errors.pub);
  e.errors.pub.error_exit = jpeg_on_encode_error;
  e.errors.self = &e;
  if (setjmp(e.errors.jump)) {
    jpeg_destroy_compress(&e.cinfo);
    return false;
  }
  jpeg_compress_struct& cinfo = e.cinfo;
  jpeg_create_compress(&cinfo);
  jpeg_mem_dest(&cinfo, &e.buffer, &e.size);
  cinfo.image_width = static_cast<JDIMENSION>(image.cols);
  cinfo.image_height = static_cast<JDIMENSION>(image.rows);
  cinfo.input_components = image.channels();
  cinfo.in_color_space = image.channels() == 1 ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = const_cast<JSAMPLE*>(image.ptr<JSAMPLE>(static_cast<int>(cinfo.next_scanline)));
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  jpeg_destroy_compress(&cinfo);
  return true;
}

bool is_png(std::string_view bytes) {
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  return bytes.size() >= 8 && std::memcmp(bytes.data(), kSignature, 8) == 0;
}

bool is_jpeg(std::string_view bytes) {
  return bytes.size() >= 3 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
         static_cast<unsigned char>(bytes[1]) == 0xD8 && static_cast<unsigned char>(bytes[2]) == 0xFF;
}

}  // namespace

Result<cv::Mat> decode_image(std::string_view bytes, const std::string& name, ImageDecode mode) {
  if (is_png(bytes)) {
    // The size from IHDR before libpng sees it: a header claiming a huge image is refused by its size even when its
    // CRC is wrong (libpng would call it corrupt), and libpng's own limit (1e6 px a side) is far above ours.
    if (bytes.size() >= 24 && bytes.substr(12, 4) == "IHDR") {
      auto be32 = [&](size_t at) {
        uint64_t v = 0;
        for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
        return v;
      };
      if (too_large(be32(16), be32(20))) return size_refused(name, be32(16), be32(20), "PNG");
    }
    PngDecode d;
    d.bytes = bytes;
    d.mode = mode;
    if (png_decode(d)) return std::move(d.image);
    if (d.refused) return size_refused(name, d.width, d.height, "PNG");
    return make_error(ErrorCode::kCorrupt, "cannot decode " + name + " (PNG): " + std::string(d.error));
  }
  if (is_jpeg(bytes)) {
    auto d = std::make_unique<JpegDecode>();  // libjpeg's state is ~1 kB with the jump buffer; not on the stack
    d->bytes = bytes;
    d->mode = mode;
    if (jpeg_decode(*d)) return std::move(d->image);
    if (d->refused) return size_refused(name, d->width, d->height, "JPEG");
    if (d->truncated) return make_error(ErrorCode::kCorrupt, "cannot decode " + name + " (JPEG): truncated");
    return make_error(ErrorCode::kCorrupt, "cannot decode " + name + " (JPEG): " + std::string(d->error));
  }
  if (is_tiff(bytes)) {
    auto image = tiff_decode(bytes, name);
    if (!image || mode == ImageDecode::kUnchanged) return image;
    return to_bgr8(image.value());
  }
  return make_error(ErrorCode::kCorrupt, "cannot decode " + name + ": neither PNG, JPEG nor TIFF");
}

Result<std::string> encode_png(const cv::Mat& image, PngCompression compression) {
  if (image.empty()) return make_error(ErrorCode::kInvalidArgument, "PNG encoding: empty image");
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    return make_error(ErrorCode::kInvalidArgument, "PNG encoding: needs 8- or 16-bit data");
  if (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)
    return make_error(ErrorCode::kInvalidArgument,
                      "PNG encoding: needs 1, 3 or 4 channels, not " + std::to_string(image.channels()));
  PngEncode e;
  e.rows.resize(static_cast<size_t>(image.rows));
  for (int r = 0; r < image.rows; ++r) e.rows[static_cast<size_t>(r)] = const_cast<png_bytep>(image.ptr<png_byte>(r));
  if (!png_encode(e, image, compression))
    return make_error(ErrorCode::kIo, "PNG encoding failed: " + std::string(e.error));
  return std::move(e.bytes);
}

Result<std::string> encode_jpeg(const cv::Mat& image, int quality) {
  if (image.empty() || (image.type() != CV_8UC1 && image.type() != CV_8UC3))
    return make_error(ErrorCode::kInvalidArgument, "JPEG encoding: needs a non-empty 8-bit grey or BGR image");
  if (quality < 1 || quality > 100)
    return make_error(ErrorCode::kInvalidArgument, "JPEG quality " + std::to_string(quality) + ": expected 1..100");
  JpegEncode e;
  const bool ok = jpeg_encode(e, image, quality);
  std::string bytes = ok ? std::string(reinterpret_cast<const char*>(e.buffer), e.size) : std::string();
  std::free(e.buffer);
  if (!ok) return make_error(ErrorCode::kIo, "JPEG encoding failed: " + std::string(e.error));
  return bytes;
}

}  // namespace vdrig
