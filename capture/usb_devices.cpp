#include "capture/usb_devices.h"

#include <libusb.h>

#include <cstdio>

namespace lp {

namespace {

const char* ModelOf(int vendor, int product) {
  if (vendor == 0x1d27) return "PrimeSense-based (Asus Xtion Pro / Pro Live, Carmine)";
  if (vendor == 0x045e && product == 0x02ae) return "Microsoft Kinect (v1) camera";
  return nullptr;
}

}  // namespace

UsbScan ScanUsbCameras() {
  UsbScan scan;
  libusb_context* ctx = nullptr;
  if (const int rc = libusb_init(&ctx); rc != 0) {
    scan.usb_error = std::string("libusb_init failed: ") + libusb_strerror(static_cast<libusb_error>(rc));
    return scan;
  }
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  if (n < 0) {
    scan.usb_error = std::string("cannot list USB devices: ") + libusb_strerror(static_cast<libusb_error>(n));
    libusb_exit(ctx);
    return scan;
  }
  scan.usb_available = true;
  scan.devices_seen = static_cast<int>(n);
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0) continue;
    const char* model = ModelOf(d.idVendor, d.idProduct);
    if (!model) continue;
    UsbCamera cam;
    cam.vendor_id = d.idVendor;
    cam.product_id = d.idProduct;
    cam.model = model;
    cam.bus = libusb_get_bus_number(list[i]);
    std::uint8_t ports[8];
    const int depth = libusb_get_port_numbers(list[i], ports, 8);
    cam.port_path = std::to_string(cam.bus) + "-";
    for (int k = 0; k < depth; ++k) cam.port_path += (k ? "." : "") + std::to_string(ports[k]);
    libusb_device_handle* h = nullptr;
    const int rc = libusb_open(list[i], &h);
    cam.accessible = rc == 0;
    if (h) libusb_close(h);
    if (rc != 0) cam.access_error = libusb_strerror(static_cast<libusb_error>(rc));
    scan.cameras.push_back(cam);
  }
  libusb_free_device_list(list, 1);
  libusb_exit(ctx);
  return scan;
}

std::string UdevRuleText() {
  return "# /etc/udev/rules.d/55-lightprobe-depth-cameras.rules, then: sudo udevadm control --reload && replug\n"
         "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"1d27\", MODE=\"0666\", TAG+=\"uaccess\"\n"
         "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"045e\", ATTR{idProduct}==\"02ae\", MODE=\"0666\", TAG+=\"uaccess\"\n";
}

std::string ExplainNoDevice(const UsbScan& scan) {
  if (!scan.usb_available) return "no USB access on this machine (" + scan.usb_error + "), so no camera can be seen";
  if (scan.cameras.empty())
    return "no depth camera on USB (" + std::to_string(scan.devices_seen) +
           " USB devices, none PrimeSense 1d27 or Kinect 045e:02ae): plug the camera in";
  for (const UsbCamera& c : scan.cameras)
    if (!c.accessible)
      return "a " + c.model + " is on USB at " + c.port_path + " but this user may not open it (" + c.access_error +
             "): install the udev rule printed by `lightprobe devices`";
  return "a camera is on USB and accessible, but OpenNI2 did not open it: its driver (PS1080) is missing or failed "
         "(check /usr/lib/x86_64-linux-gnu/OpenNI2/Drivers)";
}

}  // namespace lp
