// The "why is there no device" explanation for each case, and a scan that never throws.
#include <gtest/gtest.h>

#include "capture/usb_devices.h"

namespace lp {
namespace {

bool Has(const std::string& s, const char* part) { return s.find(part) != std::string::npos; }

TEST(UsbDevices, ExplainsEachReasonForNoDevice) {
  UsbScan none;
  none.usb_available = true;
  none.devices_seen = 3;
  EXPECT_TRUE(Has(ExplainNoDevice(none), "no depth camera on USB")) << ExplainNoDevice(none);

  UsbScan locked = none;
  UsbCamera cam;
  cam.vendor_id = 0x1d27;
  cam.product_id = 0x0601;
  cam.model = "PrimeSense-based";
  cam.port_path = "1-2";
  cam.accessible = false;
  cam.access_error = "Access denied (insufficient permissions)";
  locked.cameras.push_back(cam);
  const std::string why = ExplainNoDevice(locked);
  EXPECT_TRUE(Has(why, "may not open")) << why;
  EXPECT_TRUE(Has(why, "udev")) << why;

  UsbScan open = locked;
  open.cameras[0].accessible = true;
  EXPECT_TRUE(Has(ExplainNoDevice(open), "driver")) << ExplainNoDevice(open);

  UsbScan no_usb;
  no_usb.usb_error = "libusb_init failed";
  EXPECT_TRUE(Has(ExplainNoDevice(no_usb), "no USB access")) << ExplainNoDevice(no_usb);
}

TEST(UsbDevices, UdevRuleCoversBothVendors) {
  const std::string r = UdevRuleText();
  EXPECT_TRUE(Has(r, "ATTR{idVendor}==\"1d27\""));
  EXPECT_TRUE(Has(r, "ATTR{idProduct}==\"02ae\""));
}

TEST(UsbDevices, ScanNeverThrowsAndIsConsistent) {
  const UsbScan s = ScanUsbCameras();
  if (!s.usb_available) {
    EXPECT_FALSE(s.usb_error.empty());
  }
  EXPECT_LE(static_cast<int>(s.cameras.size()), s.devices_seen);
}

}  // namespace
}  // namespace lp
