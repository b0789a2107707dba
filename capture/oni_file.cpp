// `.oni` recordings: the structure check (ValidateOniFile), the playback check in a
// separate process (lightprobe-oni-check) and the file source (OpenOniFile).
#include "capture/openni.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <thread>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

extern char** environ;  // for posix_spawn

#include "capture/openni_runtime.h"
#include "common/atomic_file.h"
#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;
using namespace openni_detail;

namespace {

std::uint32_t U32(const unsigned char* p) { return p[0] | p[1] << 8 | p[2] << 16 | std::uint32_t(p[3]) << 24; }

/// The helper that plays a file in its own process: LIGHTPROBE_ONI_CHECK if set, else the
/// one the build put in the OpenNI2 runtime folder.
std::string OniCheckHelper() {
  if (const char* env = std::getenv("LIGHTPROBE_ONI_CHECK")) return env;
#ifdef LIGHTPROBE_OPENNI2_RUNTIME
  return std::string(LIGHTPROBE_OPENNI2_RUNTIME) + "/lightprobe-oni-check";
#else
  return {};
#endif
}

/// Plays `path` through once in a child process (the helper reads every frame with
/// isolate off). A crash, a hang past the time limit or an error there is an InputError
/// here; this process never hands OpenNI2 a file that broke it.
void PlayInChild(const std::string& path, int frame_records) {
  const std::string helper = OniCheckHelper();
  std::error_code ec;
  if (helper.empty() || !fs::exists(helper, ec)) {
    static std::once_flag warned;
    std::call_once(warned, [&] {
      std::fprintf(stderr, "warning: %s not found; .oni playback is not isolated in a separate process\n",
                   helper.empty() ? "lightprobe-oni-check" : helper.c_str());
    });
    return;
  }
  int pipe_fd[2];  // close-on-exec: no other child inherits the write end and holds it open
  if (pipe2(pipe_fd, O_CLOEXEC) != 0) throw InputError(path, "cannot create a pipe for the playback check");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, pipe_fd[1], 2);
  posix_spawn_file_actions_addclose(&actions, pipe_fd[0]);
  std::string arg0 = helper, arg1 = path;
  char* argv[] = {arg0.data(), arg1.data(), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, helper.c_str(), &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fd[1]);
  if (rc != 0) {
    close(pipe_fd[0]);
    throw InputError(path, "cannot start the playback check " + helper + ": " + std::strerror(rc));
  }
  // Generous: the helper decodes ~1000 VGA frames/s; a hang is what this limit catches.
  const double limit = 30.0 + 0.05 * frame_records;
  const auto t0 = std::chrono::steady_clock::now();
  std::string err;
  int status = 0;
  bool done = false, killed = false;
  while (!done) {
    pollfd p{pipe_fd[0], POLLIN, 0};
    if (poll(&p, 1, 50) > 0) {
      char buf[512];
      const ssize_t n = read(pipe_fd[0], buf, sizeof buf);
      if (n > 0 && err.size() < 4096) err.append(buf, static_cast<std::size_t>(n));
      if (n <= 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));  // closed: do not spin
    }
    done = waitpid(pid, &status, WNOHANG) == pid;
    if (!done && std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      done = killed = true;
    }
  }
  fcntl(pipe_fd[0], F_SETFL, O_NONBLOCK);  // what is left, without waiting for anyone
  for (char buf[512];;) {  // what the child wrote just before it exited
    const ssize_t n = read(pipe_fd[0], buf, sizeof buf);
    if (n <= 0 || err.size() >= 4096) break;
    err.append(buf, static_cast<std::size_t>(n));
  }
  close(pipe_fd[0]);
  if (killed)
    throw InputError(path, "corrupt .oni file: OpenNI2 playback hung (checked in a separate process, stopped after " +
                               std::to_string(static_cast<int>(limit)) + " s)");
  if (WIFSIGNALED(status))
    throw InputError(path, "corrupt .oni file: OpenNI2 crashed playing it (signal " +
                               std::to_string(WTERMSIG(status)) + ", in a separate process)");
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
    // The helper's last line is the reason (it names the file).
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    const auto nl = err.rfind('\n');
    const std::string last = nl == std::string::npos ? err : err.substr(nl + 1);
    throw InputError(last.empty() ? path + ": the playback check failed" : last);
  }
}

class OniFileSource : public FrameSource, private OpenNiStreams {
 public:
  OniFileSource(const std::string& path, const OniPlaybackOptions& o) : path_(path), options_(o) {
    OniRecordFacts facts;
    const int records = ValidateOniFile(path, &facts);
    if (facts.depth_registered) side_registered_ = true;  // a side file, when there is one, says last
    ReadSideFile();
    if (o.isolate) PlayInChild(path, records);
    InitOpenNi();
    Open();
  }
  ~OniFileSource() override {
    if (open_) CloseDevice();
  }

  std::string Describe() const override {
    return ".oni file " + path_ + ", " + std::to_string(count_) + " frames" +
           (intrinsics_note_.empty() ? "" : "; intrinsics " + intrinsics_note_);
  }
  std::optional<std::int64_t> FrameCount() const override { return count_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    // No end-of-file signal in OpenNI2's playback: stop on the recorded frame counts.
    if (depth_read_ >= depth_count_ || color_read_ >= color_count_) {
      if (!options_.loop) {
        // Past its last frame OpenNI2's player thread spins on a whole core: closed here,
        // reopened by Rewind or Seek.
        if (open_) CloseDevice(), open_ = false;
        return SourceStatus::kEnd;
      }
      Rewind();
    }
    openni::VideoFrameRef d, c;
    if (!ReadPair(&d, &c, static_cast<int>(timeout_seconds * 1000), &depth_read_, &color_read_, depth_count_,
                  color_count_))
      return SourceStatus::kTimeout;
    *out = ToFrame(d, c, produced_++);
    if (side_registered_) out->registered = *side_registered_;
    if (out->registered) out->device_extrinsics.reset();
    out->exposure = side_exposure_;
    out->gain = side_gain_;
    return SourceStatus::kFrame;
  }

  /// OpenNI2's seek crashes: rewind by reopening the file.
  void Rewind() override {
    if (open_) CloseDevice(), open_ = false;
    Open();
  }

  /// Reopens and skips to `frame` at manual speed (OpenNI2's own seek crashes), then plays
  /// on at the chosen speed.
  void Seek(std::int64_t frame) override {
    seeking_ = true;  // Open() (through Rewind) plays at manual speed meanwhile
    try {
      FrameSource::Seek(frame);
    } catch (...) {
      seeking_ = false;
      throw;
    }
    seeking_ = false;
    // Paused stays paused: real time would run the file's clock on until the caller pauses
    // again, and a frame or two later is where the reader would land.
    device_.getPlaybackControl()->setSpeed(options_.real_time && !paused_ ? 1.0f : -1.0f);
  }

  /// Real-time playback runs on OpenNI2's clock: manual speed holds it while paused.
  void SetPaused(bool paused) override {
    paused_ = paused;
    if (!options_.real_time) return;
    if (!open_) return;  // at its end: Rewind or Seek reopens it at the speed chosen
    if (openni::PlaybackControl* pc = device_.getPlaybackControl()) pc->setSpeed(paused ? -1.0f : 1.0f);
  }

 private:
  void Open() {
    if (device_.open(path_.c_str()) != openni::STATUS_OK)
      throw InputError(path_, "OpenNI2 cannot open it: " + OpenNiError());
    open_ = true;
    openni::PlaybackControl* pc = device_.getPlaybackControl();
    if (!pc) throw InputError(path_, "not a recording");
    pc->setSpeed(options_.real_time && !seeking_ && !paused_ ? 1.0f : -1.0f);  // -1: manual, one frame per read, none lost
    pc->setRepeatEnabled(false);
    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
        color_.create(device_, openni::SENSOR_COLOR) != openni::STATUS_OK)
      throw InputError(path_, "the recording needs a depth and a colour stream");
    depth_count_ = pc->getNumberOfFrames(depth_);
    color_count_ = pc->getNumberOfFrames(color_);
    count_ = std::min(depth_count_, color_count_);
    if (count_ <= 0) throw InputError(path_, "the recording has no frames in one of its streams");
    if (depth_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_DEPTH_1_MM ||
        color_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_RGB888)
      throw InputError(path_, "unsupported pixel format (expected 1 mm depth and RGB888 colour)");
    depth_.start();
    color_.start();
    depth_read_ = color_read_ = 0;
    const openni::VideoMode cm = color_.getVideoMode(), dm = depth_.getVideoMode();
    std::string color_note, depth_note;
    ColorIntrinsics(cm.getResolutionX(), cm.getResolutionY(), &color_note);
    DepthIntrinsics(dm.getResolutionX(), dm.getResolutionY(), &depth_note);
    intrinsics_note_ = color_note == depth_note ? (color_note.empty() ? "" : "of both cameras " + color_note)
                       : "of the colour camera " + (color_note.empty() ? "from its field of view" : color_note) +
                             ", of the depth camera " + (depth_note.empty() ? "from its field of view" : depth_note);
  }

  void ReadSideFile() {
    const std::string side = OniSideFile(path_);
    std::error_code ec;
    if (!fs::exists(side, ec)) return;
    const OniSideInfo info = ParseOniSideFile(ReadTextFile(side), side);
    side_registered_ = info.registered;
    side_exposure_ = info.exposure;
    side_gain_ = info.gain;
  }

  std::string path_;
  OniPlaybackOptions options_;
  std::optional<bool> side_registered_;
  std::string intrinsics_note_;  ///< which source gave the intrinsics, when not the streams' own
  bool seeking_ = false;
  bool paused_ = false;  // SetPaused: a seek or a reopen keeps it
  bool open_ = false;    // the device is open (closed at the end: Next)
  double side_exposure_ = 0, side_gain_ = 0;
  int depth_count_ = 0, color_count_ = 0, depth_read_ = 0, color_read_ = 0;
  std::int64_t count_ = 0, produced_ = 0;
};

}  // namespace

OniSideInfo ParseOniSideFile(const std::string& text, const std::string& side) {
  OniSideInfo info;
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    if (!j.is_object() || j.value("format", "") != "lightprobe-oni-side") throw InputError(side, "not a lightprobe side file");
    if (j.value("version", 0) != 1) throw InputError(side, "unsupported side file version");
    info.registered = j.at("registered").get<bool>();
    // Comparable across recordings only when the camera held them (not automatic).
    if (!j.value("auto_exposure", true) && j.value("exposure", -1.0) > 0 && j.value("gain", -1.0) > 0) {
      info.exposure = j.at("exposure").get<double>();
      info.gain = j.at("gain").get<double>();
      if (!std::isfinite(info.exposure) || !std::isfinite(info.gain))
        throw InputError(side, "exposure and gain must be finite");
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(side, std::string("malformed side file: ") + e.what());
  }
  return info;
}

namespace {

/// An .oni file's format version (file header bytes 4-11: u8 major, u8 minor, u16
/// maintenance, u32 build), ordered as OpenNI2's player orders them (PlayerNode's
/// CompareVersions: the build's difference taken as a signed 32-bit number).
struct OniVersion {
  int major = 0, minor = 0, maintenance = 0;
  std::uint32_t build = 0;
  std::string Text() const {
    return std::to_string(major) + "." + std::to_string(minor) + "." + std::to_string(maintenance) + "." +
           std::to_string(build);
  }
};

int Compare(const OniVersion& a, const OniVersion& b) {
  if (a.major != b.major) return a.major - b.major;
  if (a.minor != b.minor) return a.minor - b.minor;
  if (a.maintenance != b.maintenance) return a.maintenance - b.maintenance;
  return static_cast<std::int32_t>(a.build - b.build);
}

/// An IntProperty record's fields (after its header): the property's name (u32 length
/// with its NUL, then the characters), the value's size (u32) and the value (u64), as
/// OpenNI2's DataRecords.cpp reads them. Only what OniRecordFacts keeps is looked at; a
/// record that does not parse is left to the player.
void ReadIntProperty(std::istream& in, std::uint32_t bytes, OniRecordFacts* facts) {
  std::string f(bytes, '\0');
  if (!in.read(f.data(), bytes)) return;
  const auto* p = reinterpret_cast<const unsigned char*>(f.data());
  if (bytes < 4) return;
  const std::uint32_t name_size = U32(p);
  if (name_size == 0 || name_size > bytes - 4 || bytes - 4 - name_size < 12) return;
  const std::string name(f.data() + 4, name_size - 1);
  const std::uint32_t value_size = U32(p + 4 + name_size);
  if (value_size != 8) return;
  const std::uint64_t value = U32(p + 8 + name_size) | std::uint64_t(U32(p + 12 + name_size)) << 32;
  if (name == "AlternativeViewPoint" && value != 0) facts->depth_registered = true;
}

}  // namespace

int ValidateOniFile(const std::string& path, OniRecordFacts* facts) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path, "file not found");
  const std::uint64_t size = fs::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot read");
  return ValidateOniStream(in, size, path, facts);
}

int ValidateOniStream(std::istream& in, std::uint64_t size, const std::string& path, OniRecordFacts* facts) {
  // The layouts OpenNI2's file player reads (docs/formats.md, ".oni structure check"):
  // versions 1.0.0.4 up to 1.0.1.0; before 1.0.1.0 record headers are 24 bytes (a 32-bit
  // undo position), from it 28. A record's fields (header included) may not exceed the
  // player's record buffer, which it would overrun.
  constexpr std::size_t kFileHeader = 24;
  constexpr std::uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
  constexpr std::uint64_t kRecordMaxSize = 5760121;   // PlayerNode's RECORD_MAX_SIZE
  const OniVersion kOldest{1, 0, 0, 4}, kFirst64bit{1, 0, 1, 0};
  unsigned char h[28];
  if (size < kFileHeader || !in.read(reinterpret_cast<char*>(h), kFileHeader))
    throw InputError(path, "empty or truncated .oni file (no header)");
  if (std::memcmp(h, "NI10", 4) != 0) throw InputError(path, "not an .oni recording (bad magic)");
  const OniVersion version{h[4], h[5], h[6] | h[7] << 8, U32(h + 8)};
  if (Compare(version, kOldest) < 0 || Compare(version, kFirst64bit) > 0)
    throw InputError(path, "unsupported .oni file format version " + version.Text() +
                               " (OpenNI2 plays 1.0.0.4 to 1.0.1.0)");
  const std::uint32_t kRecordHeader = Compare(version, kFirst64bit) < 0 ? 24 : 28;
  std::uint64_t pos = kFileHeader;
  int records = 0, frames = 0;
  bool end = false;
  while (!end) {
    if (pos + kRecordHeader > size)
      throw InputError(path, "truncated .oni file: record " + std::to_string(records) + " runs past the end");
    in.seekg(static_cast<std::streamoff>(pos));
    if (!in.read(reinterpret_cast<char*>(h), kRecordHeader)) throw InputError(path, "cannot read record header");
    const std::uint32_t magic = U32(h), type = U32(h + 4), fields = U32(h + 8 + 4), payload = U32(h + 16);
    if (magic != kRecordMagic)
      throw InputError(path, "corrupt .oni file: bad record magic at byte " + std::to_string(pos));
    if (type < 0x02 || type > 0x0E || fields < kRecordHeader || fields > kRecordMaxSize)
      throw InputError(path, "corrupt .oni file: bad record header at byte " + std::to_string(pos));
    const std::uint64_t next = pos + fields + static_cast<std::uint64_t>(payload);
    if (next > size)
      throw InputError(path, "truncated .oni file: record at byte " + std::to_string(pos) + " runs past the end");
    if (facts && type == 0x03 && fields - kRecordHeader <= 4096) ReadIntProperty(in, fields - kRecordHeader, facts);
    frames += type == 0x0A;
    end = type == 0x0B;
    pos = next;
    ++records;
  }
  if (frames == 0) throw InputError(path, ".oni file has no frames");
  return frames;
}

std::unique_ptr<FrameSource> OpenOniFile(const std::string& path, const OniPlaybackOptions& options) {
  return std::make_unique<OnOpenNiThreadSource>(
      OnOpenNiThread([&]() -> std::unique_ptr<FrameSource> { return std::make_unique<OniFileSource>(path, options); }));
}

}  // namespace lp
