// lightprobe-oni-check FILE: plays an .oni file through OpenNI2 from the first frame to the
// last, in its own process. OpenOniFile runs it before it opens a file itself, so a file
// that crashes or hangs OpenNI2's decoders costs this process, not the application.
// Exit 0: the file plays; 1: an error (one line on stderr); killed by a signal: a crash.
#include <cstdio>
#include <exception>

#include "capture/openni.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s FILE.oni\n", argv[0]);
    return 2;
  }
  try {
    lp::OniPlaybackOptions o;
    o.isolate = false;
    auto source = lp::OpenOniFile(argv[1], o);
    lp::RgbdFrame frame;
    std::int64_t frames = 0;
    for (;;) {
      const lp::SourceStatus s = source->Next(&frame, 5.0);
      if (s == lp::SourceStatus::kEnd) break;
      if (s != lp::SourceStatus::kFrame) {
        std::fprintf(stderr, "%s: playback stalled after %lld frames (%s)\n", argv[1],
                     static_cast<long long>(frames), lp::ToString(s));
        return 1;
      }
      ++frames;
    }
    source.reset();  // closing is where some corrupt files crash
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
