#include "vdrig/core/image_io.hpp"
#include "vdrig/core/image_codec.hpp"

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "vdrig/core/file_read.hpp"

namespace vdrig {
namespace fs = std::filesystem;

int ExrImage::find(const std::string& name) const {
  for (size_t i = 0; i < channel_names.size(); ++i)
    if (channel_names[i] == name) return static_cast<int>(i);
  return -1;
}

void ExrImage::add(const std::string& name, cv::Mat plane) {
  VDRIG_CHECK(plane.type() == CV_32FC1, "ExrImage planes are CV_32FC1: " + name);
  if (channels.empty()) {
    width = plane.cols;
    height = plane.rows;
  }
  VDRIG_CHECK(plane.cols == width && plane.rows == height, "ExrImage plane size mismatch: " + name);
  VDRIG_CHECK(find(name) < 0, "duplicate ExrImage channel: " + name);
  channel_names.push_back(name);
  channels.push_back(plane.isContinuous() ? plane : plane.clone());
}

void ExrImage::add_bgr(const cv::Mat& bgr) {
  VDRIG_CHECK(bgr.type() == CV_32FC3, "ExrImage::add_bgr needs a CV_32FC3 image");
  cv::Mat planes[3];
  cv::split(bgr, planes);  // B, G, R
  add("R", planes[2]);
  add("G", planes[1]);
  add("B", planes[0]);
}

namespace {

/// OpenEXR's output stream over a descriptor we opened (create_new_file: O_EXCL | O_NOFOLLOW). OpenEXR's own
/// file stream opens the path itself with truncation and follows links, which a planted link would redirect.
class DescriptorOStream final : public Imf::OStream {
 public:
  DescriptorOStream(int fd, const fs::path& path) : Imf::OStream(path.c_str()), fd_(fd), path_(path) {}
  void write(const char data[], int n) override {
    if (const int err = write_all(fd_, data, static_cast<size_t>(n)); err != 0)
      throw std::runtime_error(error_from_errno(err, "write " + path_.string()).message);
  }
  uint64_t tellp() override {
    const off_t at = ::lseek(fd_, 0, SEEK_CUR);
    if (at < 0) throw std::runtime_error(error_from_errno(errno, "seek " + path_.string()).message);
    return static_cast<uint64_t>(at);
  }
  void seekp(uint64_t pos) override {
    if (::lseek(fd_, static_cast<off_t>(pos), SEEK_SET) < 0)
      throw std::runtime_error(error_from_errno(errno, "seek " + path_.string()).message);
  }

 private:
  int fd_;
  fs::path path_;
};

}  // namespace

Status write_exr(const fs::path& path, const ExrImage& image, ExrPixelType type) {
  if (image.channels.empty())
    return make_error(ErrorCode::kInvalidArgument, "no channels to write to " + path.string());
  VDRIG_TRY(check_replaceable(path));
  const fs::path tmp = temporary_sibling(path);
  auto created = create_new_file(tmp);
  if (!created) return created.error();
  const int fd = created.value();
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    const Imf::PixelType pt = type == ExrPixelType::kHalf ? Imf::HALF : Imf::FLOAT;
    header.insert("vdrig.format_version", Imf::IntAttribute(1));
    // An image read back carries the header's own attributes too (vdrig.format_version, an int; pixelAspectRatio and
    // screenWindowWidth, floats): inserting them again as doubles made OpenEXR throw, so a map read from a file could
    // not be written again. The header's attributes are the writer's; only the others are copied.
    for (const auto& [k, v] : image.string_attributes)
      if (header.find(k) == header.end()) header.insert(k, Imf::StringAttribute(v));
    for (const auto& [k, v] : image.number_attributes)
      if (header.find(k) == header.end()) header.insert(k, Imf::DoubleAttribute(v));
    for (const auto& name : image.channel_names) header.channels().insert(name, Imf::Channel(pt));
    // OpenEXR does not convert pixel types on write (only on read): half channels need half slices. cv::Mat's
    // CV_16F is IEEE binary16, the same layout as Imath::half.
    Imf::FrameBuffer fb;
    std::vector<cv::Mat> halves;
    halves.reserve(image.channels.size());
    for (size_t i = 0; i < image.channels.size(); ++i) {
      const cv::Mat& c = image.channels[i];
      if (type == ExrPixelType::kHalf) {
        halves.emplace_back();
        c.convertTo(halves.back(), CV_16F);
        fb.insert(image.channel_names[i], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(halves.back().data),
                                                     sizeof(uint16_t), halves.back().step[0]));
        continue;
      }
      fb.insert(image.channel_names[i],
                Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(c.ptr<float>())), sizeof(float),
                           c.step[0]));
    }
    {
      DescriptorOStream stream(fd, tmp);
      Imf::OutputFile out(stream, header);
      out.setFrameBuffer(fb);
      out.writePixels(image.height);
    }
    ::close(fd);
  } catch (const std::exception& e) {
    ::close(fd);
    std::error_code ec;
    fs::remove(tmp, ec);
    const bool full = std::strstr(e.what(), "No space") != nullptr;
    return make_error(full ? ErrorCode::kNoSpace : ErrorCode::kIo, "writing " + path.string() + ": " + e.what());
  }
  return commit_temporary(tmp, path);
}

Result<ExrImage> read_exr(const fs::path& path, size_t max_bytes) {
  // OpenEXR opens the path itself: refuse a directory or FIFO first (a FIFO would block it forever).
  VDRIG_TRY(check_regular_file(path));
  try {
    Imf::InputFile in(path.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    ExrImage img;
    img.width = dw.max.x - dw.min.x + 1;
    img.height = dw.max.y - dw.min.y + 1;
    if (max_bytes != 0) {
      size_t channels = 0;
      for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) ++channels;
      const double bytes = static_cast<double>(img.width) * img.height * static_cast<double>(channels) * sizeof(float);
      if (bytes > static_cast<double>(max_bytes))
        return make_error(ErrorCode::kInvalidArgument,
                          path.string() + ": " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                              " with " + std::to_string(channels) + " channels needs " +
                              std::to_string(static_cast<long long>(bytes / (1 << 20))) + " MiB; at most " +
                              std::to_string(max_bytes >> 20) + " MiB are read");
    }
    Imf::FrameBuffer fb;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
      cv::Mat plane(img.height, img.width, CV_32FC1);
      char* base = reinterpret_cast<char*>(plane.ptr<float>()) -
                   (static_cast<ptrdiff_t>(dw.min.x) + static_cast<ptrdiff_t>(dw.min.y) * img.width) *
                       static_cast<ptrdiff_t>(sizeof(float));
      fb.insert(it.name(), Imf::Slice(Imf::FLOAT, base, sizeof(float), plane.step[0]));
      img.channel_names.emplace_back(it.name());
      img.channels.push_back(plane);
    }
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    for (auto it = in.header().begin(); it != in.header().end(); ++it) {
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
        img.string_attributes[it.name()] = s->value();
      else if (const auto* d = dynamic_cast<const Imf::DoubleAttribute*>(&it.attribute()))
        img.number_attributes[it.name()] = d->value();
      else if (const auto* f = dynamic_cast<const Imf::FloatAttribute*>(&it.attribute()))
        img.number_attributes[it.name()] = f->value();
      else if (const auto* n = dynamic_cast<const Imf::IntAttribute*>(&it.attribute()))
        img.number_attributes[it.name()] = n->value();
    }
    return img;
  } catch (const std::exception& e) {
    return make_error(ErrorCode::kCorrupt, "reading " + path.string() + ": " + e.what());
  }
}

Status write_png(const fs::path& path, const cv::Mat& image) {
  if (image.empty()) return make_error(ErrorCode::kInvalidArgument, "empty image for " + path.string());
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    return make_error(ErrorCode::kInvalidArgument, "PNG needs 8- or 16-bit data: " + path.string());
  auto bytes = encode_png(image);
  if (!bytes) return make_error(bytes.error().code, bytes.error().message + " (" + path.string() + ")");
  return write_file_atomic(path, bytes.value());
}

namespace {

// read_png's file limit (documented in image_io.hpp); decode_image checks the pixel counts.
constexpr size_t kMaxImageFileBytes = size_t{1} << 30;

}  // namespace

Result<cv::Mat> read_png(const fs::path& path) {
  // Read through the regular-file check (a FIFO frame would hang a reader that opens the path itself).
  auto bytes = read_regular_file(path, kMaxImageFileBytes);
  if (!bytes) return bytes.error();
  return decode_image(bytes.value(), path.string());
}

}  // namespace vdrig
