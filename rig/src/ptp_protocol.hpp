// PTP (ISO 15740, "Picture Transfer Protocol") as a USB Still Image class camera speaks it, without any USB code:
// containers, datasets (DeviceInfo, ObjectInfo, DevicePropDesc) and a session (transaction ids, the
// command / data / response phases, DeviceBusy retries, events) over an abstract PtpTransport. The libusb transport
// is in usb_ptp_camera.cpp; tests drive the session with an in-process fake camera. docs/rig-ptp.md has the details.
//
// Wire format (all little endian): a container is
//   u32 length (whole container, header included) | u16 type (1 command, 2 data, 3 response, 4 event) |
//   u16 code (operation, response or event) | u32 transaction id | payload
// where the payload of command/response/event containers is 0..5 u32 parameters (events at most 3) and that of a
// data container the dataset bytes. Dataset strings are u8 count of UCS-2 units (terminating NUL included, 0 for
// the empty string) then the units; arrays are u32 count then the elements.
//
// Every malformed input (short buffer, length field that disagrees with the bytes, wrong type or transaction id,
// dataset running past its end) is a kCorrupt error, never a crash or an out-of-bounds read.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::rig::ptp {

// Container types.
enum ContainerType : uint16_t { kCommand = 1, kData = 2, kResponse = 3, kEvent = 4 };

// Operation codes (ISO 15740 section 10.4).
enum Operation : uint16_t {
  kGetDeviceInfo = 0x1001,
  kOpenSession = 0x1002,
  kCloseSession = 0x1003,
  kGetObjectInfo = 0x1008,
  kGetObject = 0x1009,
  kDeleteObject = 0x100B,
  kInitiateCapture = 0x100E,
  kGetDevicePropDesc = 0x1014,
  kGetDevicePropValue = 0x1015,
  kSetDevicePropValue = 0x1016,
};

// Response codes (section 11).
enum Response : uint16_t {
  kOk = 0x2001,
  kGeneralError = 0x2002,
  kSessionNotOpen = 0x2003,
  kInvalidTransactionId = 0x2004,
  kOperationNotSupported = 0x2005,
  kParameterNotSupported = 0x2006,
  kIncompleteTransfer = 0x2007,
  kInvalidStorageId = 0x2008,
  kInvalidObjectHandle = 0x2009,
  kDevicePropNotSupported = 0x200A,
  kStoreFull = 0x200C,
  kAccessDenied = 0x200F,
  kStoreNotAvailable = 0x2013,
  kDeviceBusy = 0x2019,
  kInvalidDevicePropValue = 0x201C,
  kInvalidParameter = 0x201D,
  kSessionAlreadyOpen = 0x201E,
  kTransactionCancelled = 0x201F,
};

// Event codes (section 12).
enum Event : uint16_t {
  kObjectAdded = 0x4002,
  kDevicePropChanged = 0x4006,
  kStoreFullEvent = 0x400A,
  kCaptureComplete = 0x400D,
};

// Device property codes (section 13) and data types (section 5.3).
enum Property : uint16_t {
  kExposureTime = 0x500D,   // UINT32, units of 0.1 ms
  kExposureIndex = 0x500F,  // UINT16, ISO speed
};
enum DataType : uint16_t {
  kInt8 = 0x0001,
  kUint8 = 0x0002,
  kInt16 = 0x0003,
  kUint16 = 0x0004,
  kInt32 = 0x0005,
  kUint32 = 0x0006,
  kInt64 = 0x0007,
  kUint64 = 0x0008,
};

// Object formats a still camera produces that decode_image reads.
enum ObjectFormat : uint16_t {
  kFormatExifJpeg = 0x3801,
  kFormatTiff = 0x380D,
  kFormatPng = 0x380B,
  kFormatJfif = 0x3808
};

constexpr size_t kHeaderBytes = 12;
constexpr int kMaxParams = 5;

/// "DeviceBusy (0x2019)", "GetObject (0x1009)", "ObjectAdded (0x4002)"; unknown codes as "0x....".
std::string response_name(uint16_t code);
std::string operation_name(uint16_t code);
std::string event_name(uint16_t code);

struct Container {
  uint16_t type = 0;
  uint16_t code = 0;
  uint32_t transaction_id = 0;
  std::vector<uint32_t> params;  // command, response, event
  std::vector<uint8_t> payload;  // data
};

/// Serialises a container (params for command/response/event, payload for data).
std::vector<uint8_t> encode_container(const Container& c);
/// Parses exactly `n` bytes as one container: the length field must equal `n`, parameter containers must carry a
/// whole number of u32 parameters (at most 5). kCorrupt otherwise.
Result<Container> decode_container(const uint8_t* data, size_t n);

/// Little-endian dataset writer (also used by the test's fake camera).
class Writer {
 public:
  Writer& u8(uint8_t v);
  Writer& u16(uint16_t v);
  Writer& u32(uint32_t v);
  Writer& u64(uint64_t v);
  /// A value of the given PTP integer data type.
  Writer& value(uint16_t data_type, int64_t v);
  Writer& string(const std::string& s);  // ASCII/Latin-1 to UCS-2
  Writer& array16(const std::vector<uint16_t>& v);
  std::vector<uint8_t> bytes;
};

/// Bounds-checked little-endian dataset reader: a read past the end sets failed() and returns 0 / "".
class Reader {
 public:
  Reader(const uint8_t* data, size_t n) : p_(data), n_(n) {}
  uint8_t u8();
  uint16_t u16();
  uint32_t u32();
  uint64_t u64();
  /// A value of the given integer data type, sign-extended; an unknown type fails.
  int64_t value(uint16_t data_type);
  std::string string();  // UCS-2 to UTF-8
  std::vector<uint16_t> array16();
  bool failed() const { return failed_; }
  size_t remaining() const { return failed_ ? 0 : n_ - pos_; }

 private:
  bool take(size_t k);
  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  bool failed_ = false;
};

/// DeviceInfo dataset (section 5.5.1).
struct DeviceInfo {
  uint16_t standard_version = 100;
  uint32_t vendor_extension_id = 0;
  uint16_t vendor_extension_version = 0;
  std::string vendor_extension_desc;
  uint16_t functional_mode = 0;
  std::vector<uint16_t> operations, events, properties, capture_formats, image_formats;
  std::string manufacturer, model, device_version, serial_number;

  bool supports_operation(uint16_t op) const;
  bool supports_property(uint16_t prop) const;
  std::vector<uint8_t> encode() const;
  static Result<DeviceInfo> decode(const std::vector<uint8_t>& bytes);
};

/// ObjectInfo dataset (section 5.5.2); only the fields we use are kept beyond the fixed part.
struct ObjectInfo {
  uint32_t storage_id = 0;
  uint16_t format = 0;
  uint32_t compressed_size = 0;
  uint32_t width = 0, height = 0, bit_depth = 0;
  uint32_t parent = 0;
  std::string filename;

  std::vector<uint8_t> encode() const;
  static Result<ObjectInfo> decode(const std::vector<uint8_t>& bytes);
};

/// DevicePropDesc dataset (section 5.5.3) for integer-typed properties (exposure time, ISO).
struct PropDesc {
  enum class Form : uint8_t { kNone = 0, kRange = 1, kEnumeration = 2 };
  uint16_t code = 0;
  uint16_t data_type = kUint32;
  bool writable = false;  // GetSet: 1 = get/set
  int64_t factory_default = 0, current = 0;
  Form form = Form::kNone;
  int64_t min = 0, max = 0, step = 0;  // kRange
  std::vector<int64_t> values;         // kEnumeration

  std::vector<uint8_t> encode() const;
  static Result<PropDesc> decode(const std::vector<uint8_t>& bytes);
  /// The allowed value nearest to `want` by ratio (photographic stops), both > 0; among enumerated values those
  /// <= 0 are skipped (0 is "auto" and 0xFFFFFFFF "bulb" on many cameras). nullopt when nothing is allowed.
  std::optional<int64_t> nearest(double want) const;
};

/// The bytes of a USB Still Image camera's pipes, as the session sees them. Implementations: libusb (the real
/// camera) and the tests' fake. Errors: kDisconnected when the device went away, kTimeout when nothing came.
class PtpTransport {
 public:
  virtual ~PtpTransport() = default;
  /// Writes one whole bulk-out transfer (the implementation adds the zero-length packet USB needs when `n` is a
  /// multiple of the endpoint's packet size).
  virtual Status send(const uint8_t* data, size_t n, int timeout_ms) = 0;
  /// Reads one bulk-in transfer of at most `max` bytes (`max` a multiple of the packet size): it ends with a short
  /// packet or when `max` bytes came. Returns the byte count (0 for a zero-length packet).
  virtual Result<size_t> receive(uint8_t* data, size_t max, int timeout_ms) = 0;
  /// One event container from the interrupt pipe; kTimeout when none came within `timeout_ms` (0: just poll).
  virtual Result<std::vector<uint8_t>> receive_event(int timeout_ms) = 0;
};

struct SessionOptions {
  int timeout_ms = 5000;              // per transfer
  size_t read_chunk_bytes = 1 << 18;  // per bulk-in read; a multiple of any USB packet size (512, 1024)
  int busy_retries = 20;              // DeviceBusy answers tolerated per operation
  int busy_backoff_ms = 20;           // first wait after DeviceBusy; doubles up to busy_backoff_max_ms
  int busy_backoff_max_ms = 500;
  size_t max_object_bytes = size_t(1) << 30;  // a length field beyond this is corrupt
};

/// The answer to one operation.
struct Reply {
  uint16_t code = 0;
  std::vector<uint32_t> params;
  std::vector<uint8_t> data;  // the device-to-host data phase, if any
};

/// A PTP session over one transport. Not thread safe. After a transport error or a corrupt container the
/// transport's stream may be out of step: the owner should drop the session and reopen the transport.
class PtpSession {
 public:
  explicit PtpSession(PtpTransport& transport, SessionOptions options = {});

  /// One transaction: command, optional host-to-device data (`data_out`), optional device-to-host data, response.
  /// Retries DeviceBusy with backoff. Any other non-OK response is returned in Reply::code (see `run`).
  Result<Reply> transact(uint16_t op, std::vector<uint32_t> params, const std::vector<uint8_t>* data_out = nullptr);
  /// transact() that turns every response but OK into an error naming the operation and the response code:
  /// kUnsupported for OperationNotSupported / DevicePropNotSupported, kDevice otherwise.
  Result<Reply> run(uint16_t op, std::vector<uint32_t> params, const std::vector<uint8_t>* data_out = nullptr);

  /// GetDeviceInfo (allowed outside a session).
  Result<DeviceInfo> get_device_info();
  /// OpenSession with id 1; a camera still holding a session from a crashed run answers SessionAlreadyOpen, which
  /// is closed and opened again.
  Status open();
  /// CloseSession (best effort; also done by the destructor's owner).
  Status close();
  bool is_open() const { return open_; }

  Result<PropDesc> get_prop_desc(uint16_t prop);
  Status set_prop_value(uint16_t prop, uint16_t data_type, int64_t value);
  Result<ObjectInfo> get_object_info(uint32_t handle);
  Result<std::vector<uint8_t>> get_object(uint32_t handle);
  Status delete_object(uint32_t handle);

  /// InitiateCapture (storage 0 and format 0: the camera's defaults), then the ObjectAdded handles. Waits up to
  /// `timeout_ms` for the first ObjectAdded, then for CaptureComplete at most `complete_grace_ms` more (some
  /// cameras never send it, others add a RAW and a JPEG before it).
  Result<std::vector<uint32_t>> capture(int timeout_ms, int complete_grace_ms);

  const SessionOptions& options() const { return options_; }
  uint32_t last_transaction_id() const { return last_tid_; }

 private:
  Result<Container> receive_container(uint32_t tid);
  Result<Reply> transact_once(uint16_t op, const std::vector<uint32_t>& params, const std::vector<uint8_t>* data_out);

  PtpTransport& transport_;
  SessionOptions options_;
  bool open_ = false;
  uint32_t next_tid_ = 0;
  uint32_t last_tid_ = 0;
  std::vector<uint8_t> buffer_;
};

}  // namespace vdrig::rig::ptp
