#pragma once
// USB through libusb (issue 6): a context with its own event-handling thread, enumeration by vendor/product
// id and by interface class, hotplug notifications, and a device handle with bulk and control transfers under
// a retry policy. libusb's headers stay in usb_transport.cpp; errors come out as DeviceError
// (devices/horus_interfaces.h) with the action a user can take (docs/devices.md, "USB setup").

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "devices/horus_interfaces.h"

namespace s2m {

// USB class codes (usb.org "Defined Class Codes").
inline constexpr std::uint8_t kUsbClassCdcComm = 0x02;  // CDC communications (control) interface
inline constexpr std::uint8_t kUsbClassCdcData = 0x0A;  // CDC data interface (the bulk endpoints)

// What enumeration knows of a device without opening it, plus its strings when they were readable.
struct UsbDeviceInfo {
  int bus = 0, address = 0;
  std::uint16_t vendor_id = 0, product_id = 0;
  std::uint8_t device_class = 0;
  bool has_cdc_acm = false;  // a CDC comm (0x02) and a CDC data (0x0A) interface in the active configuration
  std::vector<std::uint8_t> interface_classes;       // of the active configuration, in interface order
  std::string manufacturer, product, serial_number;  // empty when unreadable (no permission, no string)
  std::string supported_as;                          // which supported device this is; empty: not one
  bool accessible = true;  // false: enumeration could not open it (usually no permission: the udev rule)
  std::string open_error;  // why, with the action to take, when not accessible
  // "2341:0043 'Arduino Uno' (bus 1, address 5)" (the product string when known): how messages name the
  // device.
  std::string Name() const;
};

// A supported device class: which ids we recognise and what we call them (`scan2model devices`).
struct SupportedUsbId {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;  // 0: any product of the vendor
  const char* name = "";
  bool cdc_acm = true;  // false: a vendor serial converter (CH340, FTDI) that needs its kernel driver
};
// Arduino-class boards (Arduino, Arduino.org, bq ZUM), CH340 and FTDI converters the Horus firmware ships on.
const std::vector<SupportedUsbId>& SupportedUsbIds();

// The udev rule that gives the logged-in user access to vendor:product (docs/devices.md).
std::string UdevRuleFor(std::uint16_t vendor_id, std::uint16_t product_id);

// A libusb error code (LIBUSB_ERROR_*) as a DeviceError naming the device and what was being done, with the
// action to take: ACCESS -> kPermission with the udev rule, BUSY -> kBusy, NO_DEVICE -> kDisconnected,
// TIMEOUT -> kTimeout, PIPE -> kStall, NOT_FOUND -> kNotFound, others kOther. Public for the tests.
DeviceError UsbError(int libusb_error, const UsbDeviceInfo& device, const std::string& what);

class UsbContext;

// An opened device. Transfers retry timeouts and stalls (a stall first clears the endpoint's halt); what is
// left after the retries throws DeviceError naming the device and `what`.
class UsbDevice {
 public:
  struct Options {
    int timeout_ms = 1000;  // per attempt of a transfer
    int retries = 2;        // further attempts after a timeout or stall (so 3 attempts in all)
    int backoff_ms = 10;    // wait before the first retry; doubled before each further one
  };
  struct Stats {
    int transfers = 0;       // completed transfers
    int retries = 0;         // attempts repeated after a timeout or a stall
    int stalls_cleared = 0;  // LIBUSB_ERROR_PIPE answered by libusb_clear_halt
    int timeouts = 0;        // attempts that timed out
  };

  ~UsbDevice();
  UsbDevice(const UsbDevice&) = delete;
  UsbDevice& operator=(const UsbDevice&) = delete;

  const UsbDeviceInfo& Info() const;
  const Options& GetOptions() const;
  Stats GetStats() const;

  // Claims an interface, detaching a kernel driver (cdc_acm) first when the platform allows; kBusy says which
  // driver or program holds it and how to free it.
  void ClaimInterface(int interface_number);
  // Bulk OUT: all of `data`, or throws.
  void BulkWrite(std::uint8_t endpoint, const std::vector<std::uint8_t>& data, const std::string& what);
  // Bulk IN: at most `capacity` bytes (a short packet ends the read), or throws (kTimeout when nothing came
  // in any attempt). `timeout_ms` < 0: the options' timeout.
  std::vector<std::uint8_t> BulkRead(std::uint8_t endpoint, std::size_t capacity, const std::string& what,
                                     int timeout_ms = -1);
  // Bulk IN, one attempt: what is there within `timeout_ms` (empty when nothing came); other errors throw.
  std::vector<std::uint8_t> BulkReadAvailable(std::uint8_t endpoint, std::size_t capacity, int timeout_ms,
                                              const std::string& what);
  // Control transfer; for IN requests (bit 7 of request_type) `data` is resized to what came back.
  void Control(std::uint8_t request_type, std::uint8_t request, std::uint16_t value, std::uint16_t index,
               std::vector<std::uint8_t>& data, const std::string& what);

  // The bulk endpoints and interfaces of the CDC-ACM function (zeros when the device has none).
  struct CdcAcmEndpoints {
    int comm_interface = -1, data_interface = -1;
    std::uint8_t bulk_in = 0, bulk_out = 0;
  };
  CdcAcmEndpoints FindCdcAcm() const;

 private:
  friend class UsbContext;
  struct Impl;
  explicit UsbDevice(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// A libusb context with its own event-handling thread (hotplug callbacks run on it); destroying it stops and
// joins the thread. Devices opened from it keep it alive.
class UsbContext {
 public:
  struct Options {
    int event_poll_ms = 100;  // the event thread wakes at least this often to notice shutdown
  };
  using HotplugCallback = std::function<void(const UsbDeviceInfo& device, bool arrived)>;

  UsbContext();
  explicit UsbContext(const Options& options);
  ~UsbContext();
  UsbContext(const UsbContext&) = delete;
  UsbContext& operator=(const UsbContext&) = delete;

  // Every device on the buses. Strings are read (by opening the device) only for supported and CDC-ACM
  // devices.
  std::vector<UsbDeviceInfo> Enumerate() const;
  // Devices with this vendor id and product id (product_id 0: any product of the vendor).
  std::vector<UsbDeviceInfo> FindByVidPid(std::uint16_t vendor_id, std::uint16_t product_id) const;
  // Devices with an interface (or device class) of this class, e.g. kUsbClassCdcData.
  std::vector<UsbDeviceInfo> FindByInterfaceClass(std::uint8_t interface_class) const;

  // Hotplug notifications through libusb_hotplug_register_callback, when libusb has the capability (Linux
  // with udev or netlink). Returns an id for RemoveHotplugCallback, or -1 when hotplug is not supported.
  bool HotplugSupported() const;
  int AddHotplugCallback(HotplugCallback callback);
  void RemoveHotplugCallback(int id);

  // Opens the device enumerated as `device` (same bus and address); throws DeviceError (kNotFound when it is
  // gone, kPermission with the udev rule, ...).
  std::unique_ptr<UsbDevice> Open(const UsbDeviceInfo& device, const UsbDevice::Options& options = {});

  struct Impl;

 private:
  std::shared_ptr<Impl> impl_;
};

// Connected devices we support (Arduino-class boards, CH340, FTDI), with their strings when readable.
std::vector<UsbDeviceInfo> ListSupportedDevices();
std::vector<UsbDeviceInfo> ListSupportedDevices(const UsbContext& context);

}  // namespace s2m
