// The emulated Horus board (tests/emulated_horus_board.h). The ioctl handler runs on umockdev's own thread
// (the preload library forwards each ioctl on the device node to it over a socket); state is under a mutex.
// URB life cycle as the Linux kernel's usbfs does it (drivers/usb/core/devio.c): SUBMITURB queues, the URB
// completes (status, actual_length), REAPURBNDELAY hands completed URBs back (EAGAIN when none), DISCARDURB
// cancels one that has not completed (it is then reaped with -ENOENT).

#include "emulated_horus_board.h"

#include <errno.h>
#include <linux/capability.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <umockdev.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <mutex>
#include <stdexcept>

namespace s2m::test {
namespace {

void Put16(std::vector<std::uint8_t>& v, unsigned x) {
  v.push_back(static_cast<std::uint8_t>(x & 0xff));
  v.push_back(static_cast<std::uint8_t>((x >> 8) & 0xff));
}

// Device and configuration descriptors (USB 2.0 chapter 9, CDC PSTN 1.2 section 5.3) of an Uno R3's 16U2.
std::vector<std::uint8_t> Descriptors(const EmulatedHorusBoard::Options& o) {
  std::vector<std::uint8_t> d = {18, 1};
  Put16(d, 0x0200);                           // bcdUSB
  d.insert(d.end(), {0x02, 0x00, 0x00, 64});  // class CDC, subclass, protocol, bMaxPacketSize0
  Put16(d, o.vendor_id);
  Put16(d, o.product_id);
  Put16(d, 0x0001);                 // bcdDevice
  d.insert(d.end(), {1, 2, 3, 1});  // iManufacturer, iProduct, iSerialNumber, bNumConfigurations
  const std::vector<std::uint8_t> body = {
      9, 4,    0,    0,    1,    0x02, 0x02, 0x01, 0,  // interface 0: CDC comm, ACM, AT commands
      5, 0x24, 0x00, 0x10, 0x01,                       // CDC header
      4, 0x24, 0x02, 0x06,                             // ACM
      5, 0x24, 0x06, 0,    1,                          // union: master 0, slave 1
      5, 0x24, 0x01, 0x00, 1,                          // call management
      7, 5,    0x82, 0x03, 8,    0,    0xff,           // EP 2 IN interrupt
      9, 4,    1,    0,    2,    0x0A, 0,    0,    0,  // interface 1: CDC data
      7, 5,    0x04, 0x02, 64,   0,    0,              // EP 4 OUT bulk
      7, 5,    0x83, 0x02, 64,   0,    0,              // EP 3 IN bulk
  };
  d.insert(d.end(), {9, 2});
  Put16(d, static_cast<unsigned>(9 + body.size()));
  d.insert(d.end(), {2, 1, 0, 0xC0, 50});  // 2 interfaces, configuration 1, self powered, 100 mA
  d.insert(d.end(), body.begin(), body.end());
  return d;
}

std::string HexOf(const std::vector<std::uint8_t>& v) {
  std::string s;
  char buf[4];
  for (const std::uint8_t b : v) {
    std::snprintf(buf, sizeof(buf), "%02x", b);
    s += buf;
  }
  return s;
}

struct Urb {
  UMockdevIoctlData* data = nullptr;  // our reference; data->data is a usbdevfs_urb with a resolved buffer
  usbdevfs_urb* urb() const { return reinterpret_cast<usbdevfs_urb*>(data->data); }
};

std::string Strip(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c != ' ' && c != '\r' && c != '\n' && c != '\t') out += c;
  }
  return out;
}

}  // namespace

struct EmulatedHorusBoard::Impl {
  Options options;
  UMockdevTestbed* testbed = nullptr;
  UMockdevIoctlBase* handler = nullptr;
  std::string syspath, devnode, root, interface_syspath;
  std::string kernel_driver;  // bound to the interfaces while busy

  mutable std::mutex mutex;
  // Faults.
  std::vector<std::uint8_t> stalled;  // endpoints halted until CLEAR_HALT
  bool silent = false, vanished = false, busy = false;
  int vanish_after = -1;
  // USB state.
  std::deque<Urb> pending_in, completed, discarded;
  std::string input, output;
  // Firmware state.
  std::vector<std::string> log;
  double angle = 0, feed_rate = 0, acceleration = 0;
  bool lasers[2] = {false, false}, motor = false;
  int clear_halts = 0, resets = 0, commands = 0;
  std::uint32_t baud = 0;
  int data_bits = 0;
  std::uint16_t line_state = 0;

  static gboolean OnIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<Impl*>(self)->Handle(client);
  }

  // The firmware: a line in, its reply out (Horus/Grbl: "ok" after each command).
  void RunLine(const std::string& raw) {
    const std::string line = Strip(raw);
    if (line.empty()) return;
    log.push_back(raw.substr(0, raw.find_last_not_of("\r\n") + 1));
    ++commands;
    auto number_after = [&](char key, double& out) {
      const std::size_t k = line.find(key, 1);
      if (k == std::string::npos) return false;
      out = std::atof(line.c_str() + k + 1);
      return true;
    };
    if (line.rfind("G1", 0) == 0) {
      double v = 0;
      if (number_after('F', v)) feed_rate = v;
      if (number_after('X', v)) angle = v;
      output += "ok\r\n";
    } else if (line.rfind("$120=", 0) == 0) {
      acceleration = std::atof(line.c_str() + 5);
      output += "ok\r\n";
    } else if (line == "M17" || line == "M18") {
      motor = line == "M17";
      output += "ok\r\n";
    } else if (line.rfind("M71T", 0) == 0 || line.rfind("M70T", 0) == 0) {
      const int n = std::atoi(line.c_str() + 4);
      if (n < 1 || n > 2) {
        output += "error:laser\r\n";
      } else {
        lasers[n - 1] = line[2] == '1';
        output += "ok\r\n";
      }
    } else if (line.rfind("M50T", 0) == 0) {
      const int on = (lasers[0] ? 1 : 0) + (lasers[1] ? 1 : 0);
      output += std::to_string(options.light_base + options.light_per_laser * on) + "\r\nok\r\n";
    } else {
      output += "error:Unsupported command\r\n";
    }
  }

  void Receive(const std::uint8_t* data, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      const char c = static_cast<char>(data[i]);
      if (c == 0x18) {  // Ctrl-X: soft reset (Grbl keeps the position; lasers off, motor released)
        input.clear();
        output.clear();
        log.push_back("^X");
        ++resets;
        lasers[0] = lasers[1] = false;
        motor = false;
        feed_rate = acceleration = 0;
        output += "\r\n" + options.banner + "\r\n";
        continue;
      }
      input += c;
      if (c == '\n') {
        RunLine(input);
        input.clear();
      }
    }
  }

  // Hands queued output to waiting bulk IN URBs.
  void Feed() {
    if (silent) return;
    while (!output.empty() && !pending_in.empty()) {
      Urb u = pending_in.front();
      pending_in.pop_front();
      usbdevfs_urb* urb = u.urb();
      const std::size_t n =
          std::min<std::size_t>(output.size(), static_cast<std::size_t>(urb->buffer_length));
      std::memcpy(urb->buffer, output.data(), n);
      output.erase(0, n);
      urb->actual_length = static_cast<int>(n);
      urb->status = 0;
      completed.push_back(u);
    }
  }

  void Complete(Urb u, int status, int actual) {
    u.urb()->status = status;
    u.urb()->actual_length = actual;
    completed.push_back(u);
  }

  void ControlRequest(Urb u) {
    usbdevfs_urb* urb = u.urb();
    auto* buf = static_cast<std::uint8_t*>(urb->buffer);
    const std::uint8_t type = buf[0], request = buf[1];
    const unsigned value = buf[2] | (buf[3] << 8), length = buf[6] | (buf[7] << 8);
    std::uint8_t* payload = buf + 8;
    if (type == 0x80 && request == 6 && (value >> 8) == 3) {  // GET_DESCRIPTOR string
      std::vector<std::uint8_t> d;
      const unsigned index = value & 0xff;
      if (index == 0) {
        d = {4, 3, 0x09, 0x04};  // English (US)
      } else {
        const std::string& s = index == 1   ? options.manufacturer
                               : index == 2 ? options.product
                                            : options.serial_number;
        d = {static_cast<std::uint8_t>(2 + 2 * s.size()), 3};
        for (const char c : s) d.insert(d.end(), {static_cast<std::uint8_t>(c), 0});
      }
      const std::size_t n = std::min<std::size_t>(d.size(), length);
      std::memcpy(payload, d.data(), n);
      Complete(u, 0, static_cast<int>(n));
    } else if (type == 0x21 && request == 0x20 && length >= 7) {  // SET_LINE_CODING
      baud = static_cast<std::uint32_t>(payload[0] | (payload[1] << 8) | (payload[2] << 16)) |
             (static_cast<std::uint32_t>(payload[3]) << 24);
      data_bits = payload[6];
      Complete(u, 0, static_cast<int>(length));
    } else if (type == 0x21 && request == 0x22) {  // SET_CONTROL_LINE_STATE
      line_state = static_cast<std::uint16_t>(value);
      Complete(u, 0, 0);
    } else {
      Complete(u, -EPIPE, 0);  // unsupported request: protocol stall, as devices do
    }
  }

  bool Stalled(std::uint8_t ep) const {
    return std::find(stalled.begin(), stalled.end(), ep) != stalled.end();
  }

  gboolean Handle(UMockdevIoctlClient* client) {
    std::lock_guard<std::mutex> lock(mutex);
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    if (vanished && request != USBDEVFS_REAPURBNDELAY && request != USBDEVFS_REAPURB) {
      umockdev_ioctl_client_complete(client, -1, ENODEV);
      return TRUE;
    }
    switch (request) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), nullptr);
        const guint32 caps = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                             USBDEVFS_CAP_REAP_AFTER_DISCONNECT | USBDEVFS_CAP_ZERO_PACKET;
        std::memcpy(d->data, &caps, sizeof(caps));
        g_object_unref(d);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_DISCONNECT_CLAIM:
        umockdev_ioctl_client_complete(client, busy ? -1 : 0, busy ? EBUSY : 0);
        return TRUE;
      case USBDEVFS_GETDRIVER: {
        if (kernel_driver.empty()) {
          umockdev_ioctl_client_complete(client, -1, ENODATA);  // no kernel driver bound
          return TRUE;
        }
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_getdriver), nullptr);
        auto* g = reinterpret_cast<usbdevfs_getdriver*>(d->data);
        std::snprintf(g->driver, sizeof(g->driver), "%s", kernel_driver.c_str());
        g_object_unref(d);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLEAR_HALT: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(unsigned int), nullptr);
        unsigned int ep = 0;
        std::memcpy(&ep, d->data, sizeof(ep));
        g_object_unref(d);
        stalled.erase(std::remove(stalled.begin(), stalled.end(), static_cast<std::uint8_t>(ep)),
                      stalled.end());
        ++clear_halts;
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_IOCTL:  // re-attaching the kernel driver after release
      case USBDEVFS_RESET:
      case USBDEVFS_RESETEP:
      case USBDEVFS_SETINTERFACE:
      case USBDEVFS_SETCONFIGURATION:
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      case USBDEVFS_SUBMITURB: {
        Urb u;
        u.data = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
        usbdevfs_urb* urb = u.urb();
        // The board goes when the host sends the command after the n-th (the n-th got its reply).
        if (urb->type == USBDEVFS_URB_TYPE_BULK && !(urb->endpoint & 0x80) && vanish_after >= 0 &&
            commands >= vanish_after) {
          VanishLocked();
          g_object_unref(u.data);
          umockdev_ioctl_client_complete(client, -1, ENODEV);
          return TRUE;
        }
        if (urb->buffer_length > 0) {
          g_object_unref(umockdev_ioctl_data_resolve(u.data, offsetof(usbdevfs_urb, buffer),
                                                     static_cast<gsize>(urb->buffer_length), nullptr));
        }
        umockdev_ioctl_client_complete(client, 0, 0);
        if (urb->type == USBDEVFS_URB_TYPE_CONTROL) {
          ControlRequest(u);
        } else if (Stalled(urb->endpoint)) {
          Complete(u, -EPIPE, 0);
        } else if (urb->endpoint & 0x80) {
          pending_in.push_back(u);
          Feed();
        } else {
          Receive(static_cast<const std::uint8_t*>(urb->buffer),
                  static_cast<std::size_t>(urb->buffer_length));
          Complete(u, 0, urb->buffer_length);
          Feed();
        }
        return TRUE;
      }
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY: {
        std::deque<Urb>& from = !discarded.empty() ? discarded : completed;
        if (from.empty()) {
          umockdev_ioctl_client_complete(client, -1, vanished ? ENODEV : EAGAIN);
          return TRUE;
        }
        Urb u = from.front();
        from.pop_front();
        if (&from == &discarded) u.urb()->status = -ENOENT;
        UMockdevIoctlData* ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), nullptr);
        umockdev_ioctl_data_set_ptr(ptr, 0, u.data);
        g_object_unref(ptr);
        g_object_unref(u.data);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_DISCARDURB: {
        gulong addr = 0;
        std::memcpy(&addr, arg->data, sizeof(addr));
        const auto it = std::find_if(pending_in.begin(), pending_in.end(),
                                     [&](const Urb& u) { return u.data->client_addr == addr; });
        if (it == pending_in.end()) {
          umockdev_ioctl_client_complete(client, -1, EINVAL);
        } else {
          discarded.push_back(*it);
          pending_in.erase(it);
          umockdev_ioctl_client_complete(client, 0, 0);
        }
        return TRUE;
      }
      default:
        return FALSE;
    }
  }

  void VanishLocked() {
    vanished = true;
    // Outstanding URBs end as the kernel ends them on disconnect.
    for (Urb& u : pending_in) Complete(u, -ENODEV, 0);
    pending_in.clear();
  }
};

EmulatedHorusBoard::EmulatedHorusBoard() : EmulatedHorusBoard(Options{}) {}

EmulatedHorusBoard::EmulatedHorusBoard(const Options& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  char node[64];
  std::snprintf(node, sizeof(node), "/dev/bus/usb/%03d/%03d", options.bus, options.address);
  impl_->devnode = node;
  impl_->testbed = umockdev_testbed_new();
  gchar* root = umockdev_testbed_get_root_dir(impl_->testbed);
  impl_->root = root;
  g_free(root);
  impl_->handler = umockdev_ioctl_base_new();
  g_signal_connect(impl_->handler, "handle-ioctl", G_CALLBACK(&Impl::OnIoctl), impl_.get());
  if (options.plugged) Plug();
}

EmulatedHorusBoard::~EmulatedHorusBoard() {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    for (std::deque<Urb>* q : {&impl_->pending_in, &impl_->completed, &impl_->discarded}) {
      for (Urb& u : *q) g_object_unref(u.data);
      q->clear();
    }
  }
  g_object_unref(impl_->testbed);
  g_object_unref(impl_->handler);
}

bool EmulatedHorusBoard::InMockEnvironment() {
  // umockdev_in_mock_environment() of umockdev 0.17 answers false under umockdev-wrapper; the preload library
  // in LD_PRELOAD is what matters.
  const char* preload = std::getenv("LD_PRELOAD");
  return preload != nullptr && std::strstr(preload, "libumockdev-preload") != nullptr;
}

void EmulatedHorusBoard::Plug() {
  const Options& o = impl_->options;
  // The ioctl handler first, so that libusb can open the device as soon as the "add" event arrives.
  umockdev_testbed_attach_ioctl(impl_->testbed, impl_->devnode.c_str(), impl_->handler, nullptr);
  const std::string name = std::to_string(o.bus) + "-2";
  impl_->syspath = "/sys/devices/pci0000:00/0000:00:14.0/usb" + std::to_string(o.bus) + "/" + name;
  char ids[32];
  std::snprintf(ids, sizeof(ids), "%04x/%x/1", o.vendor_id, o.product_id);
  char busnum[8], devnum[8], vid[8], pid[8];
  std::snprintf(busnum, sizeof(busnum), "%03d", o.bus);
  std::snprintf(devnum, sizeof(devnum), "%03d", o.address);
  std::snprintf(vid, sizeof(vid), "%04x", o.vendor_id);
  std::snprintf(pid, sizeof(pid), "%04x", o.product_id);
  const std::string record =
      "P: " + impl_->syspath.substr(4) + "\nN: " + impl_->devnode.substr(5) +
      "\nE: SUBSYSTEM=usb\nE: DRIVER=usb\nE: DEVTYPE=usb_device\nE: BUSNUM=" + busnum +
      "\nE: DEVNUM=" + devnum + "\nE: DEVNAME=" + impl_->devnode + "\nE: PRODUCT=" + ids +
      "\nA: busnum=" + std::to_string(o.bus) + "\\n\nA: devnum=" + std::to_string(o.address) +
      "\\n\nA: bConfigurationValue=1\\n\nA: speed=12\\n\n" + "A: idVendor=" + vid +
      "\\n\nA: idProduct=" + pid + "\\n\nA: manufacturer=" + o.manufacturer + "\\n\nA: product=" + o.product +
      "\\n\nA: serial=" + o.serial_number + "\\n\nH: descriptors=" + HexOf(Descriptors(o)) + "\n";
  GError* error = nullptr;
  if (!umockdev_testbed_add_from_string(impl_->testbed, record.c_str(), &error)) {
    const std::string msg = error ? error->message : "unknown error";
    if (error) g_error_free(error);
    throw std::runtime_error("umockdev could not add the emulated board: " + msg);
  }
  // Interface 0 (CDC comm) as its own sysfs device, where the kernel driver's link lives.
  gchar* iface = umockdev_testbed_add_device(
      impl_->testbed, "usb", (name + ":1.0").c_str(), impl_->syspath.c_str(), "bInterfaceNumber", "00",
      "bInterfaceClass", "02", nullptr, "DEVTYPE", "usb_interface", nullptr);
  impl_->interface_syspath = iface != nullptr ? iface : "";
  g_free(iface);
}

void EmulatedHorusBoard::StallOnce(std::uint8_t endpoint) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->stalled.push_back(endpoint);
}

void EmulatedHorusBoard::SetUnresponsive(bool silent) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->silent = silent;
  if (!silent) impl_->Feed();
}

void EmulatedHorusBoard::VanishAfterCommands(int n) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->vanish_after = n;
}

void EmulatedHorusBoard::Vanish() {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->VanishLocked();
  }
  // A udev "remove" event (libusb's hotplug monitor), then the sysfs entry goes.
  umockdev_testbed_uevent(impl_->testbed, impl_->syspath.c_str(), "remove");
  umockdev_testbed_remove_device(impl_->testbed, impl_->syspath.c_str());
}

void EmulatedHorusBoard::DenyAccess(bool deny) {
  const std::string path = impl_->root + impl_->devnode;
  if (::chmod(path.c_str(), deny ? 0000 : 0666) != 0) {
    throw std::runtime_error("cannot chmod the emulated device node " + path + ": " + std::strerror(errno));
  }
}

void EmulatedHorusBoard::SetBusy(bool busy, const std::string& kernel_driver) {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->busy = busy;
    impl_->kernel_driver = busy ? kernel_driver : "";
  }
  if (busy && !kernel_driver.empty()) {
    // The interface's sysfs entry names its driver, as /sys/bus/usb/devices/1-2:1.0/driver does.
    umockdev_testbed_set_attribute_link(impl_->testbed, impl_->interface_syspath.c_str(), "driver",
                                        ("../../../../../../bus/usb/drivers/" + kernel_driver).c_str());
  }
}

std::vector<std::string> EmulatedHorusBoard::CommandLog() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->log;
}
double EmulatedHorusBoard::Angle() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->angle;
}
bool EmulatedHorusBoard::Laser(int index) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->lasers[index];
}
bool EmulatedHorusBoard::MotorEnabled() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->motor;
}
double EmulatedHorusBoard::FeedRate() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->feed_rate;
}
double EmulatedHorusBoard::Acceleration() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->acceleration;
}
int EmulatedHorusBoard::ClearHalts() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->clear_halts;
}
int EmulatedHorusBoard::Resets() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->resets;
}
std::uint32_t EmulatedHorusBoard::BaudRate() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->baud;
}
int EmulatedHorusBoard::DataBits() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->data_bits;
}
std::uint16_t EmulatedHorusBoard::ControlLineState() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->line_state;
}
std::string EmulatedHorusBoard::DeviceNode() const {
  return impl_->devnode;
}
std::string EmulatedHorusBoard::SysfsPath() const {
  return impl_->syspath;
}

// ------------------------------------------------------------------------------------------ capabilities

ScopedNoDacOverride::ScopedNoDacOverride() {
  if (::geteuid() != 0) {
    ok_ = true;  // file modes already apply
    return;
  }
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2]{};
  if (::syscall(SYS_capget, &header, data) != 0) return;
  saved_[0] = data[0].effective;
  saved_[1] = data[1].effective;
  data[0].effective &= ~((1u << CAP_DAC_OVERRIDE) | (1u << CAP_DAC_READ_SEARCH));
  if (::syscall(SYS_capset, &header, data) != 0) return;
  ok_ = changed_ = true;
}

ScopedNoDacOverride::~ScopedNoDacOverride() {
  if (!changed_) return;
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2]{};
  if (::syscall(SYS_capget, &header, data) != 0) return;
  data[0].effective = saved_[0];
  data[1].effective = saved_[1];
  ::syscall(SYS_capset, &header, data);
}

}  // namespace s2m::test
