// `lightprobe devices`: depth cameras on USB (libusb), whether this user may open them,
// and the udev rule to install when not.
#include <cstdio>

#include "app/commands.h"
#include "capture/usb_devices.h"

namespace lp::app {

Run AddDevices(CLI::App& app) {
  auto* cmd = app.add_subcommand("devices", "list depth cameras on USB (PrimeSense 1d27, Kinect 045e:02ae)");
  auto rule = std::make_shared<bool>(false);
  cmd->add_flag("--udev-rule", *rule, "print the udev rule that lets this user open the cameras");
  return [rule] {
    if (*rule) {
      std::fputs(UdevRuleText().c_str(), stdout);
      return;
    }
    const UsbScan scan = ScanUsbCameras();
    for (const UsbCamera& c : scan.cameras)
      std::printf("%04x:%04x  %-8s %s  %s\n", c.vendor_id, c.product_id, c.port_path.c_str(), c.model.c_str(),
                  c.accessible ? "accessible" : ("NOT accessible: " + c.access_error).c_str());
    if (scan.cameras.empty() || !scan.usb_available) std::printf("%s\n", ExplainNoDevice(scan).c_str());
    for (const UsbCamera& c : scan.cameras)
      if (!c.accessible) {
        std::printf("\nTo let this user open it, install this rule:\n%s", UdevRuleText().c_str());
        break;
      }
  };
}

}  // namespace lp::app
