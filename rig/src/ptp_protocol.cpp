#include "ptp_protocol.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <thread>

#include "still_camera.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::rig::ptp {
namespace {

using Clock = std::chrono::steady_clock;

struct Name {
  uint16_t code;
  const char* name;
};

constexpr Name kOperations[] = {
    {kGetDeviceInfo, "GetDeviceInfo"},
    {kOpenSession, "OpenSession"},
    {kCloseSession, "CloseSession"},
    {0x1004, "GetStorageIDs"},
    {0x1005, "GetStorageInfo"},
    {0x1006, "GetNumObjects"},
    {0x1007, "GetObjectHandles"},
    {kGetObjectInfo, "GetObjectInfo"},
    {kGetObject, "GetObject"},
    {0x100A, "GetThumb"},
    {kDeleteObject, "DeleteObject"},
    {kInitiateCapture, "InitiateCapture"},
    {kGetDevicePropDesc, "GetDevicePropDesc"},
    {kGetDevicePropValue, "GetDevicePropValue"},
    {kSetDevicePropValue, "SetDevicePropValue"},
};

constexpr Name kResponses[] = {
    {kOk, "OK"},
    {kGeneralError, "GeneralError"},
    {kSessionNotOpen, "SessionNotOpen"},
    {kInvalidTransactionId, "InvalidTransactionID"},
    {kOperationNotSupported, "OperationNotSupported"},
    {kParameterNotSupported, "ParameterNotSupported"},
    {kIncompleteTransfer, "IncompleteTransfer"},
    {kInvalidStorageId, "InvalidStorageID"},
    {kInvalidObjectHandle, "InvalidObjectHandle"},
    {kDevicePropNotSupported, "DevicePropNotSupported"},
    {0x200B, "InvalidObjectFormatCode"},
    {kStoreFull, "StoreFull"},
    {0x200D, "ObjectWriteProtected"},
    {0x200E, "StoreReadOnly"},
    {kAccessDenied, "AccessDenied"},
    {0x2010, "NoThumbnailPresent"},
    {0x2011, "SelfTestFailed"},
    {0x2012, "PartialDeletion"},
    {kStoreNotAvailable, "StoreNotAvailable"},
    {0x2014, "SpecificationByFormatUnsupported"},
    {0x2015, "NoValidObjectInfo"},
    {0x2016, "InvalidCodeFormat"},
    {0x2017, "UnknownVendorCode"},
    {0x2018, "CaptureAlreadyTerminated"},
    {kDeviceBusy, "DeviceBusy"},
    {0x201A, "InvalidParentObject"},
    {0x201B, "InvalidDevicePropFormat"},
    {kInvalidDevicePropValue, "InvalidDevicePropValue"},
    {kInvalidParameter, "InvalidParameter"},
    {kSessionAlreadyOpen, "SessionAlreadyOpen"},
    {kTransactionCancelled, "TransactionCancelled"},
    {0x2020, "SpecificationOfDestinationUnsupported"},
};

constexpr Name kEvents[] = {
    {0x4001, "CancelTransaction"},
    {kObjectAdded, "ObjectAdded"},
    {0x4003, "ObjectRemoved"},
    {0x4004, "StoreAdded"},
    {0x4005, "StoreRemoved"},
    {kDevicePropChanged, "DevicePropChanged"},
    {0x4007, "ObjectInfoChanged"},
    {0x4008, "DeviceInfoChanged"},
    {0x4009, "RequestObjectTransfer"},
    {kStoreFullEvent, "StoreFull"},
    {0x400B, "DeviceReset"},
    {0x400C, "StorageInfoChanged"},
    {kCaptureComplete, "CaptureComplete"},
    {0x400E, "UnreportedStatus"},
};

std::string hex_code(uint16_t code) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%04x", code);
  return buf;
}

template <size_t N>
std::string name_of(const Name (&table)[N], uint16_t code) {
  for (const auto& n : table)
    if (n.code == code) return std::string(n.name) + " (" + hex_code(code) + ")";
  return hex_code(code);
}

uint32_t le32(const uint8_t* p) { return p[0] | (p[1] << 8) | (p[2] << 16) | (uint32_t(p[3]) << 24); }
uint16_t le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

Error corrupt(const std::string& what) { return make_error(ErrorCode::kCorrupt, "PTP: " + what); }

size_t value_size(uint16_t type) {
  switch (type) {
    case kInt8:
    case kUint8:
      return 1;
    case kInt16:
    case kUint16:
      return 2;
    case kInt32:
    case kUint32:
      return 4;
    case kInt64:
    case kUint64:
      return 8;
    default:
      return 0;
  }
}

}  // namespace

std::string response_name(uint16_t code) { return name_of(kResponses, code); }
std::string operation_name(uint16_t code) { return name_of(kOperations, code); }
std::string event_name(uint16_t code) { return name_of(kEvents, code); }

// ---- containers ----

std::vector<uint8_t> encode_container(const Container& c) {
  Writer w;
  const size_t body = c.type == kData ? c.payload.size() : 4 * c.params.size();
  w.u32(static_cast<uint32_t>(kHeaderBytes + body)).u16(c.type).u16(c.code).u32(c.transaction_id);
  if (c.type == kData)
    w.bytes.insert(w.bytes.end(), c.payload.begin(), c.payload.end());
  else
    for (uint32_t p : c.params) w.u32(p);
  return std::move(w.bytes);
}

Result<Container> decode_container(const uint8_t* data, size_t n) {
  if (n < kHeaderBytes) return corrupt("container of " + std::to_string(n) + " bytes, shorter than the 12-byte header");
  const uint32_t length = le32(data);
  if (length != n)
    return corrupt("container length field says " + std::to_string(length) + " bytes but " + std::to_string(n) +
                   " came");
  Container c;
  c.type = le16(data + 4);
  c.code = le16(data + 6);
  c.transaction_id = le32(data + 8);
  const size_t body = n - kHeaderBytes;
  switch (c.type) {
    case kData:
      c.payload.assign(data + kHeaderBytes, data + n);
      break;
    case kCommand:
    case kResponse:
    case kEvent:
      if (body % 4 != 0 || body / 4 > kMaxParams)
        return corrupt("container type " + std::to_string(c.type) + " with " + std::to_string(body) +
                       " parameter bytes (want 0..5 whole u32)");
      for (size_t i = 0; i < body / 4; ++i) c.params.push_back(le32(data + kHeaderBytes + 4 * i));
      break;
    default:
      return corrupt("unknown container type " + std::to_string(c.type));
  }
  return c;
}

// ---- datasets ----

Writer& Writer::u8(uint8_t v) {
  bytes.push_back(v);
  return *this;
}
Writer& Writer::u16(uint16_t v) { return u8(uint8_t(v)).u8(uint8_t(v >> 8)); }
Writer& Writer::u32(uint32_t v) { return u16(uint16_t(v)).u16(uint16_t(v >> 16)); }
Writer& Writer::u64(uint64_t v) { return u32(uint32_t(v)).u32(uint32_t(v >> 32)); }

Writer& Writer::value(uint16_t data_type, int64_t v) {
  const size_t k = value_size(data_type);
  VDRIG_CHECK(k > 0, "PTP writer: unsupported data type " + hex_code(data_type));
  for (size_t i = 0; i < k; ++i) u8(uint8_t(static_cast<uint64_t>(v) >> (8 * i)));
  return *this;
}

Writer& Writer::string(const std::string& s) {
  if (s.empty()) return u8(0);
  const size_t chars = std::min<size_t>(s.size(), 254);  // the count (NUL included) is one byte
  u8(static_cast<uint8_t>(chars + 1));
  for (size_t i = 0; i < chars; ++i) u16(static_cast<uint8_t>(s[i]));
  return u16(0);
}

Writer& Writer::array16(const std::vector<uint16_t>& v) {
  u32(static_cast<uint32_t>(v.size()));
  for (uint16_t x : v) u16(x);
  return *this;
}

bool Reader::take(size_t k) {
  if (failed_ || n_ - pos_ < k) {
    failed_ = true;
    return false;
  }
  return true;
}

uint8_t Reader::u8() {
  if (!take(1)) return 0;
  return p_[pos_++];
}
uint16_t Reader::u16() {
  if (!take(2)) return 0;
  pos_ += 2;
  return le16(p_ + pos_ - 2);
}
uint32_t Reader::u32() {
  if (!take(4)) return 0;
  pos_ += 4;
  return le32(p_ + pos_ - 4);
}
uint64_t Reader::u64() {
  const uint64_t lo = u32();
  return lo | (uint64_t(u32()) << 32);
}

int64_t Reader::value(uint16_t data_type) {
  switch (data_type) {
    case kInt8:
      return static_cast<int8_t>(u8());
    case kUint8:
      return u8();
    case kInt16:
      return static_cast<int16_t>(u16());
    case kUint16:
      return u16();
    case kInt32:
      return static_cast<int32_t>(u32());
    case kUint32:
      return u32();
    case kInt64:
    case kUint64:
      return static_cast<int64_t>(u64());
    default:
      failed_ = true;
      return 0;
  }
}

std::string Reader::string() {
  const uint8_t count = u8();
  if (count == 0 || !take(2 * size_t(count))) return {};
  std::string out;
  for (uint8_t i = 0; i < count; ++i) {
    const uint16_t c = u16();
    if (c == 0) continue;  // the terminator (and any stray NUL)
    if (c < 0x80) {
      out += static_cast<char>(c);
    } else if (c < 0x800) {
      out += static_cast<char>(0xC0 | (c >> 6));
      out += static_cast<char>(0x80 | (c & 0x3F));
    } else {
      out += static_cast<char>(0xE0 | (c >> 12));
      out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (c & 0x3F));
    }
  }
  return out;
}

std::vector<uint16_t> Reader::array16() {
  const uint32_t count = u32();
  // Check before allocating: a garbage count must not reserve gigabytes.
  if (!take(2 * size_t(count))) return {};
  std::vector<uint16_t> v(count);
  for (auto& x : v) x = u16();
  return v;
}

bool DeviceInfo::supports_operation(uint16_t op) const {
  return std::find(operations.begin(), operations.end(), op) != operations.end();
}
bool DeviceInfo::supports_property(uint16_t prop) const {
  return std::find(properties.begin(), properties.end(), prop) != properties.end();
}

std::vector<uint8_t> DeviceInfo::encode() const {
  Writer w;
  w.u16(standard_version).u32(vendor_extension_id).u16(vendor_extension_version).string(vendor_extension_desc);
  w.u16(functional_mode).array16(operations).array16(events).array16(properties);
  w.array16(capture_formats).array16(image_formats);
  w.string(manufacturer).string(model).string(device_version).string(serial_number);
  return std::move(w.bytes);
}

Result<DeviceInfo> DeviceInfo::decode(const std::vector<uint8_t>& bytes) {
  Reader r(bytes.data(), bytes.size());
  DeviceInfo d;
  d.standard_version = r.u16();
  d.vendor_extension_id = r.u32();
  d.vendor_extension_version = r.u16();
  d.vendor_extension_desc = r.string();
  d.functional_mode = r.u16();
  d.operations = r.array16();
  d.events = r.array16();
  d.properties = r.array16();
  d.capture_formats = r.array16();
  d.image_formats = r.array16();
  d.manufacturer = r.string();
  d.model = r.string();
  d.device_version = r.string();
  d.serial_number = r.string();
  if (r.failed()) return corrupt("DeviceInfo dataset of " + std::to_string(bytes.size()) + " bytes is truncated");
  return d;
}

std::vector<uint8_t> ObjectInfo::encode() const {
  Writer w;
  w.u32(storage_id).u16(format).u16(0).u32(compressed_size);
  w.u16(0).u32(0).u32(0).u32(0);  // no thumbnail
  w.u32(width).u32(height).u32(bit_depth).u32(parent).u16(0).u32(0).u32(0);
  w.string(filename).string("").string("").string("");  // capture date, modification date, keywords
  return std::move(w.bytes);
}

Result<ObjectInfo> ObjectInfo::decode(const std::vector<uint8_t>& bytes) {
  Reader r(bytes.data(), bytes.size());
  ObjectInfo o;
  o.storage_id = r.u32();
  o.format = r.u16();
  r.u16();  // protection status
  o.compressed_size = r.u32();
  r.u16();  // thumb format
  r.u32();  // thumb size
  r.u32();  // thumb width
  r.u32();  // thumb height
  o.width = r.u32();
  o.height = r.u32();
  o.bit_depth = r.u32();
  o.parent = r.u32();
  r.u16();  // association type
  r.u32();  // association desc
  r.u32();  // sequence number
  if (r.failed()) return corrupt("ObjectInfo dataset of " + std::to_string(bytes.size()) + " bytes is truncated");
  // The strings that follow are optional in practice: some cameras end the dataset early.
  o.filename = r.string();
  return o;
}

std::vector<uint8_t> PropDesc::encode() const {
  Writer w;
  w.u16(code).u16(data_type).u8(writable ? 1 : 0).value(data_type, factory_default).value(data_type, current);
  w.u8(static_cast<uint8_t>(form));
  if (form == Form::kRange) {
    w.value(data_type, min).value(data_type, max).value(data_type, step);
  } else if (form == Form::kEnumeration) {
    w.u16(static_cast<uint16_t>(values.size()));
    for (int64_t v : values) w.value(data_type, v);
  }
  return std::move(w.bytes);
}

Result<PropDesc> PropDesc::decode(const std::vector<uint8_t>& bytes) {
  Reader r(bytes.data(), bytes.size());
  PropDesc d;
  d.code = r.u16();
  d.data_type = r.u16();
  if (!r.failed() && value_size(d.data_type) == 0)
    return corrupt("DevicePropDesc of " + hex_code(d.code) + " has data type " + hex_code(d.data_type) +
                   ", not an integer");
  d.writable = r.u8() == 1;
  d.factory_default = r.value(d.data_type);
  d.current = r.value(d.data_type);
  const uint8_t form = r.u8();
  if (form == 1) {
    d.form = Form::kRange;
    d.min = r.value(d.data_type);
    d.max = r.value(d.data_type);
    d.step = r.value(d.data_type);
  } else if (form == 2) {
    d.form = Form::kEnumeration;
    const uint16_t n = r.u16();
    if (!r.failed() && r.remaining() < n * value_size(d.data_type))
      return corrupt("DevicePropDesc enumeration of " + std::to_string(n) + " values is truncated");
    for (uint16_t i = 0; i < n; ++i) d.values.push_back(r.value(d.data_type));
  } else if (form != 0) {
    return corrupt("DevicePropDesc form flag " + std::to_string(form));
  }
  if (r.failed()) return corrupt("DevicePropDesc dataset of " + std::to_string(bytes.size()) + " bytes is truncated");
  return d;
}

std::optional<int64_t> PropDesc::nearest(double want) const {
  if (!(want > 0.0)) return std::nullopt;
  std::vector<int64_t> candidates;
  if (form == Form::kEnumeration) {
    for (int64_t v : values)
      if (v > 0 && !(data_type == kUint32 && v == 0xFFFFFFFF)) candidates.push_back(v);
  } else if (form == Form::kRange) {
    const int64_t lo = std::max<int64_t>(min, 1);
    if (max < lo) return std::nullopt;
    if (step <= 0) {
      candidates.push_back(std::clamp<int64_t>(std::llround(want), lo, max));
    } else {
      // The grid points on either side of `want`, clamped into [lo, max] on the grid.
      const double k = std::floor((want - double(min)) / double(step));
      for (double kk : {k, k + 1}) {
        int64_t v = min + static_cast<int64_t>(std::max(0.0, kk)) * step;
        while (v < lo) v += step;
        while (v > max) v -= step;
        if (v >= lo) candidates.push_back(v);
      }
    }
  } else {
    if (current > 0) candidates.push_back(current);  // no form: the current value is all we know is valid
  }
  const auto i = nearest_stop(std::vector<double>(candidates.begin(), candidates.end()), want);
  if (!i) return std::nullopt;
  return candidates[*i];
}

// ---- session ----

PtpSession::PtpSession(PtpTransport& transport, SessionOptions options)
    : transport_(transport), options_(std::move(options)) {
  VDRIG_CHECK(options_.read_chunk_bytes >= 512 && options_.read_chunk_bytes % 64 == 0,
              "PTP read chunk must be a multiple of the USB packet size");
}

Result<Container> PtpSession::receive_container(uint32_t tid) {
  const size_t chunk = options_.read_chunk_bytes;
  buffer_.resize(chunk);
  size_t got = 0;
  // A zero-length packet before a container ends the previous data phase (sent when its length was a multiple of
  // the packet size); skip a couple of them.
  for (int zlps = 0;; ++zlps) {
    auto r = transport_.receive(buffer_.data(), chunk, options_.timeout_ms);
    if (!r) return r.error();
    got = *r;
    if (got > 0) break;
    if (zlps >= 2) return corrupt("only empty transfers where a container was due");
  }
  if (got < kHeaderBytes)
    return corrupt("transfer of " + std::to_string(got) + " bytes, shorter than the 12-byte container header");
  const uint32_t length = le32(buffer_.data());
  if (length < kHeaderBytes || length > options_.max_object_bytes + kHeaderBytes)
    return corrupt("container length field " + std::to_string(length) + " is impossible");
  if (got > length)
    return corrupt("transfer of " + std::to_string(got) + " bytes holds a container of length " +
                   std::to_string(length));
  // Only a data container may continue in further transfers: a response fits one packet, so a short one was cut.
  if (got < length && le16(buffer_.data() + 4) != kData)
    return corrupt("container type " + std::to_string(le16(buffer_.data() + 4)) + " of length " +
                   std::to_string(length) + " came in a transfer of " + std::to_string(got) + " bytes");
  std::vector<uint8_t> whole(buffer_.begin(), buffer_.begin() + static_cast<ptrdiff_t>(got));
  // A data phase longer than one transfer continues in further transfers (and some cameras send the 12-byte header
  // in a transfer of its own); the container length says when it is complete.
  whole.reserve(length);
  while (whole.size() < length) {
    auto r = transport_.receive(buffer_.data(), chunk, options_.timeout_ms);
    if (!r) return r.error();
    if (*r == 0)
      return corrupt("data phase ended after " + std::to_string(whole.size()) + " of " + std::to_string(length) +
                     " bytes");
    if (whole.size() + *r > length)
      return corrupt("data phase of " + std::to_string(whole.size() + *r) + " bytes overruns its length field " +
                     std::to_string(length));
    whole.insert(whole.end(), buffer_.begin(), buffer_.begin() + static_cast<ptrdiff_t>(*r));
  }
  auto c = decode_container(whole.data(), whole.size());
  if (!c) return c.error();
  if (c->type != kData && c->type != kResponse)
    return corrupt("container type " + std::to_string(c->type) + " on the bulk-in pipe");
  if (c->transaction_id != tid)
    return corrupt("container for transaction " + std::to_string(c->transaction_id) + " while " + std::to_string(tid) +
                   " is pending");
  return c;
}

Result<Reply> PtpSession::transact_once(uint16_t op, const std::vector<uint32_t>& params,
                                        const std::vector<uint8_t>* data_out) {
  uint32_t tid = 0;  // outside a session (GetDeviceInfo, OpenSession) the transaction id is 0
  if (open_) {
    tid = next_tid_++;
    if (next_tid_ == 0xFFFFFFFF) next_tid_ = 1;  // 0 and 0xFFFFFFFF are reserved
  }
  last_tid_ = tid;
  const auto command = encode_container(Container{kCommand, op, tid, params, {}});
  VDRIG_TRY(transport_.send(command.data(), command.size(), options_.timeout_ms));
  if (data_out) {
    const auto bytes = encode_container(Container{kData, op, tid, {}, *data_out});
    VDRIG_TRY(transport_.send(bytes.data(), bytes.size(), options_.timeout_ms));
  }
  auto c = receive_container(tid);
  if (!c) return c.error();
  Reply reply;
  if (c->type == kData) {
    if (c->code != op)
      return corrupt("data phase for " + operation_name(c->code) + " while " + operation_name(op) + " is pending");
    reply.data = std::move(c->payload);
    c = receive_container(tid);
    if (!c) return c.error();
    if (c->type != kResponse) return corrupt("a second data phase for " + operation_name(op));
  }
  reply.code = c->code;
  reply.params = std::move(c->params);
  return reply;
}

Result<Reply> PtpSession::transact(uint16_t op, std::vector<uint32_t> params, const std::vector<uint8_t>* data_out) {
  VDRIG_CHECK(params.size() <= kMaxParams, "PTP operations take at most 5 parameters");
  int backoff_ms = options_.busy_backoff_ms;
  for (int attempt = 0;; ++attempt) {
    auto reply = transact_once(op, params, data_out);
    if (!reply || reply->code != kDeviceBusy || attempt >= options_.busy_retries) return reply;
    // Busy: still writing the last photo to the card, or focusing. Nothing happened; ask again later.
    log::get("rig")->debug("PTP {}: DeviceBusy, retry {} in {} ms", operation_name(op), attempt + 1, backoff_ms);
    std::this_thread::sleep_for(std::chrono::milliseconds(backoff_ms));
    backoff_ms = std::min(2 * backoff_ms, options_.busy_backoff_max_ms);
  }
}

Result<Reply> PtpSession::run(uint16_t op, std::vector<uint32_t> params, const std::vector<uint8_t>* data_out) {
  auto reply = transact(op, std::move(params), data_out);
  if (!reply || reply->code == kOk) return reply;
  std::string msg = "PTP " + operation_name(op) + " answered " + response_name(reply->code);
  if (reply->code == kDeviceBusy) msg += " after " + std::to_string(options_.busy_retries) + " retries";
  const bool unsupported = reply->code == kOperationNotSupported || reply->code == kDevicePropNotSupported;
  return make_error(unsupported ? ErrorCode::kUnsupported : ErrorCode::kDevice, msg);
}

Result<DeviceInfo> PtpSession::get_device_info() {
  auto r = run(kGetDeviceInfo, {});
  if (!r) return r.error();
  return DeviceInfo::decode(r->data);
}

Status PtpSession::open() {
  if (open_) return Status::ok();
  constexpr uint32_t kSessionId = 1;
  auto r = transact(kOpenSession, {kSessionId});
  if (!r) return r.error();
  if (r->code == kSessionAlreadyOpen) {
    // A previous run died without CloseSession and the camera kept that session: close it and start afresh, so
    // the transaction ids start again at 1.
    log::get("rig")->info("PTP: camera reports a session still open; closing it");
    open_ = true;
    next_tid_ = 1;
    (void)transact(kCloseSession, {});
    open_ = false;
    r = transact(kOpenSession, {kSessionId});
    if (!r) return r.error();
    if (r->code == kSessionAlreadyOpen) r->code = kOk;  // it will not let go: use it as it is
  }
  if (r->code != kOk) return make_error(ErrorCode::kDevice, "PTP OpenSession answered " + response_name(r->code));
  open_ = true;
  next_tid_ = 1;
  return Status::ok();
}

Status PtpSession::close() {
  if (!open_) return Status::ok();
  auto r = run(kCloseSession, {});
  open_ = false;
  return r.status();
}

Result<PropDesc> PtpSession::get_prop_desc(uint16_t prop) {
  auto r = run(kGetDevicePropDesc, {prop});
  if (!r) return r.error();
  auto d = PropDesc::decode(r->data);
  if (d && d->code != prop)
    return corrupt("GetDevicePropDesc for " + hex_code(prop) + " describes " + hex_code(d->code));
  return d;
}

Status PtpSession::set_prop_value(uint16_t prop, uint16_t data_type, int64_t value) {
  Writer w;
  w.value(data_type, value);
  return run(kSetDevicePropValue, {prop}, &w.bytes).status();
}

Result<ObjectInfo> PtpSession::get_object_info(uint32_t handle) {
  auto r = run(kGetObjectInfo, {handle});
  if (!r) return r.error();
  return ObjectInfo::decode(r->data);
}

Result<std::vector<uint8_t>> PtpSession::get_object(uint32_t handle) {
  auto r = run(kGetObject, {handle});
  if (!r) return r.error();
  return std::move(r->data);
}

Status PtpSession::delete_object(uint32_t handle) { return run(kDeleteObject, {handle, 0}).status(); }

Result<std::vector<uint32_t>> PtpSession::capture(int timeout_ms, int complete_grace_ms) {
  // Events left from before (a DevicePropChanged after our SetDevicePropValue, a previous capture's leftovers)
  // must not be taken for this capture's.
  for (int i = 0; i < 64; ++i) {
    auto stale = transport_.receive_event(0);
    if (!stale) {
      if (stale.error().code == ErrorCode::kTimeout) break;
      return stale.error();
    }
  }
  auto r = run(kInitiateCapture, {0, 0});  // storage 0, format 0: wherever and however the camera is set up to
  if (!r) return r.error();
  const uint32_t capture_tid = last_tid_;
  const auto start = Clock::now();
  auto deadline = start + std::chrono::milliseconds(timeout_ms);
  std::vector<uint32_t> handles;
  bool complete = false;
  while (!(complete && !handles.empty())) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) break;
    auto e = transport_.receive_event(static_cast<int>(std::min<int64_t>(left, 200)));
    if (!e) {
      if (e.error().code == ErrorCode::kTimeout) continue;
      return e.error();
    }
    auto c = decode_container(e->data(), e->size());
    if (!c) return c.error();
    if (c->type != kEvent) return corrupt("container type " + std::to_string(c->type) + " on the event pipe");
    if (c->code == kObjectAdded && !c->params.empty()) {
      if (handles.empty())  // the first object is in: the rest (RAW+JPEG) and CaptureComplete come soon or never
        deadline = std::min(deadline, Clock::now() + std::chrono::milliseconds(complete_grace_ms));
      handles.push_back(c->params[0]);
    } else if (c->code == kCaptureComplete) {
      complete = true;
      if (!c->params.empty() && c->params[0] != capture_tid)
        log::get("rig")->debug("PTP CaptureComplete names transaction {}, InitiateCapture was {}", c->params[0],
                               capture_tid);
    } else if (c->code == kStoreFullEvent) {
      return make_error(ErrorCode::kDevice, "PTP: the camera's card is full (StoreFull event)");
    } else {
      log::get("rig")->debug("PTP event {} while capturing", event_name(c->code));
    }
  }
  if (handles.empty())
    return make_error(ErrorCode::kTimeout, "PTP: no ObjectAdded event within " + std::to_string(timeout_ms) +
                                               " ms of InitiateCapture" +
                                               (complete ? " (CaptureComplete came without an object)" : ""));
  return handles;
}

}  // namespace vdrig::rig::ptp
