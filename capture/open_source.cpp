// OpenFrameSource: the one place that decides what kind of input a path is.
#include <filesystem>

#include "capture/frame_source.h"
#include "capture/openni.h"
#include "common/error.h"

namespace lp {

std::unique_ptr<FrameSource> OpenFrameSource(const std::string& path, bool real_time) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) return OpenDirectorySource(path);
  if (!fs::exists(path, ec)) throw InputError(path, "no such file or directory");
  if (fs::path(path).extension() != ".oni")
    throw InputError(path, "not a frame directory or an .oni recording");
  OniPlaybackOptions o;
  o.real_time = real_time;
  return OpenOniFile(path, o);
}

}  // namespace lp
