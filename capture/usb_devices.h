#pragma once
/// Depth cameras on USB, found with libusb (no OpenNI2 involved): what `lightprobe
/// devices` lists, and what explains an OpenNI2 "no device" error.
#include <string>
#include <vector>

namespace lp {

struct UsbCamera {
  int vendor_id = 0, product_id = 0;
  int bus = 0;
  std::string port_path;  ///< "1-2.3" style
  std::string model;      ///< "PrimeSense-based (Asus Xtion / Carmine)" or "Microsoft Kinect (v1)"
  bool accessible = false;  ///< this user may open it
  std::string access_error; ///< libusb's reason when not accessible
};

struct UsbScan {
  bool usb_available = false;  ///< libusb initialized and could list devices
  std::string usb_error;       ///< why not, when not
  int devices_seen = 0;        ///< USB devices of any kind
  std::vector<UsbCamera> cameras;
};

/// Lists PrimeSense (vendor 1d27) and Kinect v1 (045e:02ae) cameras. Never throws: a
/// machine without USB access gives usb_available = false and the reason.
UsbScan ScanUsbCameras();

/// The udev rule that lets non-root users open PrimeSense and Kinect cameras.
std::string UdevRuleText();

/// One line explaining why OpenNI2 found no device, from a USB scan: no camera on USB,
/// a camera present but not accessible (with the udev rule's file name), or a camera
/// present and accessible (then the OpenNI2 driver is missing or failed).
std::string ExplainNoDevice(const UsbScan& scan);

}  // namespace lp
