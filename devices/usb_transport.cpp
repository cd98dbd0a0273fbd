// libusb transport (issue 6). libusb-1.0 API: https://libusb.sourceforge.io/api-1.0/ ; the synchronous
// transfer functions cooperate with the context's event thread through libusb's event lock ("Multi-threaded
// applications and asynchronous I/O" in the libusb documentation), so they are used from any thread here.

#include "devices/usb_transport.h"

#include <libusb.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <system_error>
#include <thread>

namespace s2m {
namespace {

std::string Hex4(std::uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof(buf), "%04x", static_cast<unsigned>(v));
  return buf;
}

const SupportedUsbId* Lookup(std::uint16_t vid, std::uint16_t pid) {
  for (const SupportedUsbId& id : SupportedUsbIds()) {
    if (id.vendor_id == vid && (id.product_id == 0 || id.product_id == pid)) return &id;
  }
  return nullptr;
}

// Strings through control transfers (GET_DESCRIPTOR, USB 2.0 section 9.6.7); empty when unreadable.
std::string ReadString(libusb_device_handle* handle, std::uint8_t index) {
  if (index == 0) return "";
  unsigned char buf[256];
  const int n = libusb_get_string_descriptor_ascii(handle, index, buf, sizeof(buf));
  if (n <= 0) return "";
  return std::string(reinterpret_cast<const char*>(buf), static_cast<std::size_t>(n));
}

// Descriptor-level facts (no I/O: safe inside a hotplug callback).
UsbDeviceInfo DescribeDevice(libusb_device* dev) {
  UsbDeviceInfo info;
  info.bus = libusb_get_bus_number(dev);
  info.address = libusb_get_device_address(dev);
  libusb_device_descriptor desc{};
  if (libusb_get_device_descriptor(dev, &desc) != 0) return info;
  info.vendor_id = desc.idVendor;
  info.product_id = desc.idProduct;
  info.device_class = desc.bDeviceClass;
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(dev, &config) != 0 || config == nullptr) {
    if (libusb_get_config_descriptor(dev, 0, &config) != 0) config = nullptr;
  }
  bool comm = false, data = false;
  if (config != nullptr) {
    for (int i = 0; i < config->bNumInterfaces; ++i) {
      if (config->interface[i].num_altsetting < 1) continue;
      const std::uint8_t cls = config->interface[i].altsetting[0].bInterfaceClass;
      info.interface_classes.push_back(cls);
      comm = comm || cls == kUsbClassCdcComm;
      data = data || cls == kUsbClassCdcData;
    }
    libusb_free_config_descriptor(config);
  }
  info.has_cdc_acm = comm && data;
  if (const SupportedUsbId* id = Lookup(info.vendor_id, info.product_id)) info.supported_as = id->name;
  return info;
}

// The interface's sysfs name, <bus>-<port>[.<port>...]:<config>.<interface> ("1-2:1.0"); empty when unknown.
std::string InterfaceSysfsName(libusb_device_handle* handle, int interface_number) {
  libusb_device* dev = libusb_get_device(handle);
  std::uint8_t ports[8];
  const int n = libusb_get_port_numbers(dev, ports, sizeof(ports));
  if (n <= 0) return "";
  std::string name = std::to_string(libusb_get_bus_number(dev)) + "-";
  for (int i = 0; i < n; ++i) name += (i ? "." : "") + std::to_string(ports[i]);
  int config = 1;
  if (libusb_get_configuration(handle, &config) != 0 || config <= 0) config = 1;
  return name + ":" + std::to_string(config) + "." + std::to_string(interface_number);
}

// The kernel driver bound to an interface, from sysfs (/sys/bus/usb/devices/<interface>/driver); empty when
// unknown.
std::string KernelDriverName(const std::string& interface_name) {
  if (interface_name.empty()) return "";
  std::error_code ec;
  const std::filesystem::path target =
      std::filesystem::read_symlink("/sys/bus/usb/devices/" + interface_name + "/driver", ec);
  return ec ? "" : target.filename().string();
}

}  // namespace

std::string UsbDeviceInfo::Name() const {
  std::string s = Hex4(vendor_id) + ":" + Hex4(product_id);
  if (!product.empty()) s += " '" + product + "'";
  return s + " (bus " + std::to_string(bus) + ", address " + std::to_string(address) + ")";
}

const std::vector<SupportedUsbId>& SupportedUsbIds() {
  static const std::vector<SupportedUsbId> ids = {
      {0x2341, 0, "Arduino board (CDC-ACM)", true},      // Arduino SA: Uno, Mega, Leonardo...
      {0x2A03, 0, "Arduino.org board (CDC-ACM)", true},  // Arduino srl
      {0x1A86, 0x7523, "CH340 serial converter (Arduino clone)", false},
      {0x0403, 0x6001, "FTDI FT232R serial converter", false},
      {0x0403, 0x6015, "FTDI FT231X serial converter (bq ZUM BT-328)", false},
  };
  return ids;
}

std::string UdevRuleFor(std::uint16_t vendor_id, std::uint16_t product_id) {
  return "SUBSYSTEM==\"usb\", ATTRS{idVendor}==\"" + Hex4(vendor_id) + "\", ATTRS{idProduct}==\"" +
         Hex4(product_id) + "\", MODE=\"0660\", TAG+=\"uaccess\"";
}

DeviceError UsbError(int code, const UsbDeviceInfo& device, const std::string& what) {
  const std::string head = device.Name() + ": " + what + ": ";
  switch (code) {
    case LIBUSB_ERROR_ACCESS:
      return DeviceError(
          DeviceError::Kind::kPermission,
          head +
              "no permission to open the USB device. Give your user access with a udev rule: put "
              "the line\n  " +
              UdevRuleFor(device.vendor_id, device.product_id) +
              "\ninto /etc/udev/rules.d/60-scan2model.rules, run\n  sudo udevadm control --reload "
              "&& sudo udevadm trigger\nand re-plug the device (docs/devices.md, USB setup)");
    case LIBUSB_ERROR_BUSY:
      return DeviceError(DeviceError::Kind::kBusy,
                         head +
                             "the device is busy: another program or a kernel driver has claimed it. Close "
                             "programs using it (serial terminals, Horus, ModemManager) and try again");
    case LIBUSB_ERROR_NO_DEVICE:
      return DeviceError(DeviceError::Kind::kDisconnected,
                         head +
                             "the device was disconnected. Check the USB cable and the board's power, then "
                             "re-plug it; what was acquired before this point is kept");
    case LIBUSB_ERROR_TIMEOUT:
      return DeviceError(
          DeviceError::Kind::kTimeout,
          head +
              "no answer in time. Check that the board runs the Horus firmware and is powered; "
              "unplug and re-plug it if it stays silent");
    case LIBUSB_ERROR_PIPE:
      return DeviceError(DeviceError::Kind::kStall,
                         head +
                             "the endpoint stalled and kept stalling after clearing the halt. Re-plug the "
                             "device");
    case LIBUSB_ERROR_NOT_FOUND:
      return DeviceError(DeviceError::Kind::kNotFound, head + "not found (" + libusb_strerror(code) + ")");
    default:
      return DeviceError(DeviceError::Kind::kOther,
                         head + libusb_error_name(code) + " (" + libusb_strerror(code) + ")");
  }
}

// ------------------------------------------------------------------------------------------ context

struct UsbContext::Impl {
  libusb_context* ctx = nullptr;
  Options options;
  std::thread events;
  std::atomic<bool> stop{false};
  std::mutex hotplug_mutex;
  std::map<int, HotplugCallback> callbacks;
  int next_id = 1;
  bool hotplug_registered = false;
  libusb_hotplug_callback_handle hotplug_handle{};

  static int LIBUSB_CALL OnHotplug(libusb_context*, libusb_device* dev, libusb_hotplug_event event,
                                   void* user) {
    Impl* self = static_cast<Impl*>(user);
    const UsbDeviceInfo info = DescribeDevice(dev);
    std::vector<HotplugCallback> copy;
    {
      std::lock_guard<std::mutex> lock(self->hotplug_mutex);
      for (const auto& [id, cb] : self->callbacks) copy.push_back(cb);
    }
    for (const HotplugCallback& cb : copy) cb(info, event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED);
    return 0;  // stay registered
  }

  ~Impl() {
    if (ctx == nullptr) return;  // libusb_init failed
    if (hotplug_registered) libusb_hotplug_deregister_callback(ctx, hotplug_handle);
    stop = true;
    libusb_interrupt_event_handler(ctx);
    if (events.joinable()) events.join();
    libusb_exit(ctx);
  }
};

UsbContext::UsbContext() : UsbContext(Options{}) {}

UsbContext::UsbContext(const Options& options) : impl_(std::make_shared<Impl>()) {
  impl_->options = options;
  const int r = libusb_init(&impl_->ctx);
  if (r != 0) {
    impl_->ctx = nullptr;
    throw DeviceError(DeviceError::Kind::kOther,
                      std::string("libusb could not start (") + libusb_strerror(r) +
                          "): is /dev/bus/usb present? In a container, pass the USB bus through");
  }
  Impl* impl = impl_.get();
  impl->events = std::thread([impl] {
    while (!impl->stop) {
      timeval tv{impl->options.event_poll_ms / 1000, (impl->options.event_poll_ms % 1000) * 1000};
      int completed = 0;
      libusb_handle_events_timeout_completed(impl->ctx, &tv, &completed);
    }
  });
}

UsbContext::~UsbContext() = default;

std::vector<UsbDeviceInfo> UsbContext::Enumerate() const {
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(impl_->ctx, &list);
  if (n < 0) throw UsbError(static_cast<int>(n), UsbDeviceInfo{}, "listing USB devices");
  std::vector<UsbDeviceInfo> out;
  for (ssize_t i = 0; i < n; ++i) {
    UsbDeviceInfo info = DescribeDevice(list[i]);
    // Strings need the device opened: only for the devices we might drive (opening others is not our
    // business).
    if (!info.supported_as.empty() || info.has_cdc_acm) {
      libusb_device_handle* handle = nullptr;
      const int r = libusb_open(list[i], &handle);
      if (r != 0) {
        info.accessible = false;
        info.open_error = UsbError(r, info, "reading its strings").what();
      } else {
        libusb_device_descriptor desc{};
        libusb_get_device_descriptor(list[i], &desc);
        info.manufacturer = ReadString(handle, desc.iManufacturer);
        info.product = ReadString(handle, desc.iProduct);
        info.serial_number = ReadString(handle, desc.iSerialNumber);
        libusb_close(handle);
      }
    }
    out.push_back(std::move(info));
  }
  libusb_free_device_list(list, 1);
  return out;
}

std::vector<UsbDeviceInfo> UsbContext::FindByVidPid(std::uint16_t vendor_id, std::uint16_t product_id) const {
  std::vector<UsbDeviceInfo> out;
  for (UsbDeviceInfo& d : Enumerate()) {
    if (d.vendor_id == vendor_id && (product_id == 0 || d.product_id == product_id))
      out.push_back(std::move(d));
  }
  return out;
}

std::vector<UsbDeviceInfo> UsbContext::FindByInterfaceClass(std::uint8_t interface_class) const {
  std::vector<UsbDeviceInfo> out;
  for (UsbDeviceInfo& d : Enumerate()) {
    const bool has = d.device_class == interface_class ||
                     std::find(d.interface_classes.begin(), d.interface_classes.end(), interface_class) !=
                         d.interface_classes.end();
    if (has) out.push_back(std::move(d));
  }
  return out;
}

bool UsbContext::HotplugSupported() const {
  return libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0;
}

int UsbContext::AddHotplugCallback(HotplugCallback callback) {
  if (!HotplugSupported()) return -1;
  std::lock_guard<std::mutex> lock(impl_->hotplug_mutex);
  if (!impl_->hotplug_registered) {
    const int r = libusb_hotplug_register_callback(
        impl_->ctx,
        static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED |
                                          LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
        LIBUSB_HOTPLUG_NO_FLAGS, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
        &Impl::OnHotplug, impl_.get(), &impl_->hotplug_handle);
    if (r != 0) return -1;
    impl_->hotplug_registered = true;
  }
  const int id = impl_->next_id++;
  impl_->callbacks[id] = std::move(callback);
  return id;
}

void UsbContext::RemoveHotplugCallback(int id) {
  std::lock_guard<std::mutex> lock(impl_->hotplug_mutex);
  impl_->callbacks.erase(id);
}

// ------------------------------------------------------------------------------------------ device

struct UsbDevice::Impl {
  std::shared_ptr<UsbContext::Impl> context;  // keeps libusb alive while the device is open
  libusb_device_handle* handle = nullptr;
  UsbDeviceInfo info;
  Options options;
  mutable std::mutex stats_mutex;
  Stats stats;
  std::vector<int> claimed;

  ~Impl() {
    for (const int iface : claimed) libusb_release_interface(handle, iface);
    libusb_close(handle);
  }

  // Runs `attempt` (returns a libusb code) under the retry policy: timeouts and stalls are retried with
  // backoff, a stall after clearing the endpoint's halt (USB 2.0 section 9.4.5: the host clears a halted
  // endpoint).
  template <class Attempt>
  void WithRetries(std::uint8_t endpoint, const std::string& what, int timeout_ms, Attempt attempt) {
    int backoff_ms = options.backoff_ms;
    int last = 0;
    for (int k = 0; k <= options.retries; ++k) {
      if (k > 0) {
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          ++stats.retries;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(backoff_ms));
        backoff_ms *= 2;
      }
      last = attempt();
      if (last == 0) {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++stats.transfers;
        return;
      }
      if (last == LIBUSB_ERROR_TIMEOUT) {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++stats.timeouts;
      } else if (last == LIBUSB_ERROR_PIPE) {
        const int r = libusb_clear_halt(handle, endpoint);
        if (r != 0 && r != LIBUSB_ERROR_NOT_FOUND) throw UsbError(r, info, what + " (clearing a stall)");
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++stats.stalls_cleared;
      } else {
        throw UsbError(last, info, what);
      }
    }
    throw UsbError(last, info,
                   what + " (" + std::to_string(options.retries + 1) + " attempts of " +
                       std::to_string(timeout_ms) + " ms)");
  }
};

UsbDevice::UsbDevice(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
UsbDevice::~UsbDevice() = default;

const UsbDeviceInfo& UsbDevice::Info() const {
  return impl_->info;
}
const UsbDevice::Options& UsbDevice::GetOptions() const {
  return impl_->options;
}
UsbDevice::Stats UsbDevice::GetStats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

void UsbDevice::ClaimInterface(int interface_number) {
  libusb_device_handle* h = impl_->handle;
  // Linux: libusb detaches cdc_acm (USBDEVFS_DISCONNECT_CLAIM) on claim and re-attaches it on release.
  const int detach = libusb_set_auto_detach_kernel_driver(h, 1);
  const int r = libusb_claim_interface(h, interface_number);
  if (r == 0) {
    impl_->claimed.push_back(interface_number);
    return;
  }
  const std::string what = "claiming interface " + std::to_string(interface_number);
  if (r != LIBUSB_ERROR_BUSY) throw UsbError(r, impl_->info, what);
  const std::string interface_name = InterfaceSysfsName(h, interface_number);
  const std::string driver = KernelDriverName(interface_name);
  const bool kernel = libusb_kernel_driver_active(h, interface_number) == 1 || !driver.empty();
  std::string holder;
  if (kernel) {
    holder =
        "the kernel driver " + (driver.empty() ? std::string("(probably cdc_acm)") : driver) + " holds it" +
        (detach != 0 ? " and libusb cannot detach kernel drivers on this platform"
                     : " and could not be detached") +
        ". Close programs using the serial port (see fuser -v /dev/ttyACM*), or unbind the driver: echo -n "
        "'" +
        (interface_name.empty() ? "<bus>-<port>:1." + std::to_string(interface_number) : interface_name) +
        "' | sudo tee /sys/bus/usb/drivers/" + (driver.empty() ? "cdc_acm" : driver) + "/unbind";
  } else {
    holder =
        "another program has claimed it (Horus, a second scan2model, ModemManager?). Close it and try again";
  }
  throw DeviceError(DeviceError::Kind::kBusy,
                    impl_->info.Name() + ": " + what + ": busy: " + holder + " (docs/devices.md, USB setup)");
}

void UsbDevice::BulkWrite(std::uint8_t endpoint, const std::vector<std::uint8_t>& data,
                          const std::string& what) {
  std::size_t offset = 0;
  impl_->WithRetries(endpoint, what, impl_->options.timeout_ms, [&] {
    while (offset < data.size()) {
      int sent = 0;
      const int r =
          libusb_bulk_transfer(impl_->handle, endpoint, const_cast<std::uint8_t*>(data.data()) + offset,
                               static_cast<int>(data.size() - offset), &sent, impl_->options.timeout_ms);
      offset += static_cast<std::size_t>(std::max(sent, 0));  // a timed-out transfer may have sent a part
      if (r != 0) return r;
    }
    return 0;
  });
}

std::vector<std::uint8_t> UsbDevice::BulkRead(std::uint8_t endpoint, std::size_t capacity,
                                              const std::string& what, int timeout_ms) {
  std::vector<std::uint8_t> buf(capacity);
  int got = 0;
  const unsigned timeout = static_cast<unsigned>(timeout_ms < 0 ? impl_->options.timeout_ms : timeout_ms);
  impl_->WithRetries(endpoint, what, static_cast<int>(timeout), [&] {
    got = 0;
    const int r =
        libusb_bulk_transfer(impl_->handle, endpoint, buf.data(), static_cast<int>(capacity), &got, timeout);
    if (r == LIBUSB_ERROR_TIMEOUT && got > 0) return 0;  // data came, then the line went quiet
    return r;
  });
  buf.resize(static_cast<std::size_t>(got));
  return buf;
}

std::vector<std::uint8_t> UsbDevice::BulkReadAvailable(std::uint8_t endpoint, std::size_t capacity,
                                                       int timeout_ms, const std::string& what) {
  std::vector<std::uint8_t> buf(capacity);
  int got = 0;
  const int r = libusb_bulk_transfer(impl_->handle, endpoint, buf.data(), static_cast<int>(capacity), &got,
                                     static_cast<unsigned>(timeout_ms));
  if (r != 0 && r != LIBUSB_ERROR_TIMEOUT) throw UsbError(r, impl_->info, what);
  buf.resize(static_cast<std::size_t>(std::max(got, 0)));
  return buf;
}

void UsbDevice::Control(std::uint8_t request_type, std::uint8_t request, std::uint16_t value,
                        std::uint16_t index, std::vector<std::uint8_t>& data, const std::string& what) {
  int got = 0;
  impl_->WithRetries(0, what, impl_->options.timeout_ms, [&] {
    const int r = libusb_control_transfer(impl_->handle, request_type, request, value, index, data.data(),
                                          static_cast<std::uint16_t>(data.size()),
                                          static_cast<unsigned>(impl_->options.timeout_ms));
    if (r < 0) return r;
    got = r;
    return 0;
  });
  if (request_type & LIBUSB_ENDPOINT_IN) data.resize(static_cast<std::size_t>(got));
}

UsbDevice::CdcAcmEndpoints UsbDevice::FindCdcAcm() const {
  CdcAcmEndpoints out;
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(libusb_get_device(impl_->handle), &config) != 0 ||
      config == nullptr) {
    return out;
  }
  for (int i = 0; i < config->bNumInterfaces; ++i) {
    if (config->interface[i].num_altsetting < 1) continue;
    const libusb_interface_descriptor& alt = config->interface[i].altsetting[0];
    if (alt.bInterfaceClass == kUsbClassCdcComm && out.comm_interface < 0)
      out.comm_interface = alt.bInterfaceNumber;
    if (alt.bInterfaceClass != kUsbClassCdcData || out.data_interface >= 0) continue;
    for (int e = 0; e < alt.bNumEndpoints; ++e) {
      const libusb_endpoint_descriptor& ep = alt.endpoint[e];
      if ((ep.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) != LIBUSB_TRANSFER_TYPE_BULK) continue;
      if (ep.bEndpointAddress & LIBUSB_ENDPOINT_IN) {
        out.bulk_in = ep.bEndpointAddress;
      } else {
        out.bulk_out = ep.bEndpointAddress;
      }
    }
    out.data_interface = alt.bInterfaceNumber;
  }
  libusb_free_config_descriptor(config);
  return out;
}

std::unique_ptr<UsbDevice> UsbContext::Open(const UsbDeviceInfo& device, const UsbDevice::Options& options) {
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(impl_->ctx, &list);
  if (n < 0) throw UsbError(static_cast<int>(n), device, "listing USB devices");
  libusb_device* found = nullptr;
  for (ssize_t i = 0; i < n; ++i) {
    if (libusb_get_bus_number(list[i]) == device.bus &&
        libusb_get_device_address(list[i]) == device.address) {
      found = list[i];
    }
  }
  if (found == nullptr) {
    libusb_free_device_list(list, 1);
    throw DeviceError(DeviceError::Kind::kNotFound,
                      device.Name() + ": not connected any more (run `scan2model devices` to see what is)");
  }
  libusb_device_handle* handle = nullptr;
  const int r = libusb_open(found, &handle);
  libusb_free_device_list(list, 1);
  if (r != 0) throw UsbError(r, device, "opening");
  auto impl = std::make_unique<UsbDevice::Impl>();
  impl->context = impl_;
  impl->handle = handle;
  impl->info = device;
  impl->options = options;
  return std::unique_ptr<UsbDevice>(new UsbDevice(std::move(impl)));
}

std::vector<UsbDeviceInfo> ListSupportedDevices(const UsbContext& context) {
  std::vector<UsbDeviceInfo> out;
  for (UsbDeviceInfo& d : context.Enumerate()) {
    if (!d.supported_as.empty()) out.push_back(std::move(d));
  }
  return out;
}

std::vector<UsbDeviceInfo> ListSupportedDevices() {
  const UsbContext context;
  return ListSupportedDevices(context);
}

}  // namespace s2m
