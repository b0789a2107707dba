// Directories of RGB-D frames: TUM RGB-D, Redwood / Open3D and joinMap (slambook) layouts.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "capture/frame_source.h"
#include "capture/trajectory.h"
#include "capture/tum_index.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_io.h"

namespace lp {
namespace fs = std::filesystem;

void FrameSource::Seek(std::int64_t frame) {
  if (frame < 0) throw InputError(Describe() + ": cannot seek to frame " + std::to_string(frame));
  if (const auto n = FrameCount(); n && frame >= *n)
    throw InputError(Describe() + ": cannot seek to frame " + std::to_string(frame) + " (it has " +
                     std::to_string(*n) + ")");
  Rewind();
  RgbdFrame f;
  for (std::int64_t k = 0; k < frame; ++k)
    if (Next(&f, 5.0) != SourceStatus::kFrame)
      throw InputError(Describe() + ": seek to frame " + std::to_string(frame) + " ran past the end");
}

const char* ToString(SourceStatus s) {
  switch (s) {
    case SourceStatus::kFrame: return "frame";
    case SourceStatus::kEnd: return "end of stream";
    case SourceStatus::kTimeout: return "timeout";
    case SourceStatus::kDeviceLost: return "device lost";
  }
  return "?";
}

namespace {

struct Entry {
  fs::path color, depth;
  double color_time = 0, depth_time = 0;
  std::optional<Eigen::Matrix4d> pose;
};

/// Non-comment, non-empty lines of a text, split on whitespace.
std::vector<std::vector<std::string>> ParseTable(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::vector<std::string> cols;
    for (std::string c; ls >> c;) cols.push_back(c);
    rows.push_back(cols);
  }
  return rows;
}

double ParseNumber(const std::string& s, const std::string& name, std::size_t line) {
  try {
    std::size_t used = 0;
    const double v = std::stod(s, &used);
    if (used == s.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  throw InputError(name, "line " + std::to_string(line) + ": '" + s.substr(0, 64) + "' is not a number");
}

std::optional<Camera> IntrinsicsJson(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  return ParseDirectoryIntrinsics(ReadTextFile(path), path.string());
}

}  // namespace

Camera ParseDirectoryIntrinsics(const std::string& text, const std::string& name) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(name, std::string("malformed JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError(name, "intrinsics must be a JSON object");
  Camera k;
  auto num = [&](const nlohmann::json& v) {
    if (!v.is_number()) throw InputError(name, "intrinsics must be numbers");
    return v.get<double>();
  };
  if (j.contains("intrinsic_matrix")) {  // Open3D: 3x3 column-major, plus width/height
    const auto& m = j["intrinsic_matrix"];
    if (!m.is_array() || m.size() != 9) throw InputError(name, "\"intrinsic_matrix\" must have 9 numbers");
    k.fx = num(m[0]);
    k.fy = num(m[4]);
    k.cx = num(m[6]);
    k.cy = num(m[7]);
  } else {
    for (const char* key : {"fx", "fy", "cx", "cy"})
      if (!j.contains(key)) throw InputError(name, std::string("missing \"") + key + "\"");
    k.fx = num(j["fx"]);
    k.fy = num(j["fy"]);
    k.cx = num(j["cx"]);
    k.cy = num(j["cy"]);
  }
  auto side = [&](const char* key) {  // no cast of a huge or negative double to int
    const double v = num(j[key]);
    if (!(v >= 1 && v <= 65536)) throw InputError(name, std::string("\"") + key + "\" must be 1 to 65536");
    return static_cast<int>(v);
  };
  if (j.contains("width")) k.width = side("width");
  if (j.contains("height")) k.height = side("height");
  if (!(k.fx > 0) || !(k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy) || !std::isfinite(k.cx) ||
      !std::isfinite(k.cy))
    throw InputError(name, "focal lengths must be positive and finite, the centre finite");
  return k;
}

namespace {

Camera PrimeSenseDefault() { return {640, 480, 525.0, 525.0, 319.5, 239.5}; }

void RequireFile(const fs::path& p, const fs::path& index) {
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) throw InputError(index.string(), "names a missing file: " + p.string());
}

std::vector<Entry> LoadTum(const fs::path& dir) {
  const fs::path assoc = dir / "associations.txt";
  std::error_code ec;
  std::vector<TumFrame> frames;
  if (fs::exists(assoc, ec)) {
    frames = ParseTumAssociations(ReadTextFile(assoc), assoc.string());
  } else {
    const fs::path rgb = dir / "rgb.txt", depth = dir / "depth.txt";
    frames = PairTumLists(ParseTumList(ReadTextFile(rgb), rgb.string()),
                          ParseTumList(ReadTextFile(depth), depth.string()));
  }
  std::vector<Entry> out;
  for (const TumFrame& f : frames) {
    Entry e;
    e.color_time = f.color_time;
    e.color = dir / f.color;
    e.depth_time = f.depth_time;
    e.depth = dir / f.depth;
    out.push_back(e);
  }
  return out;
}

std::vector<fs::path> SortedFiles(const fs::path& dir) {
  std::vector<fs::path> v;
  for (const auto& f : fs::directory_iterator(dir))
    if (f.is_regular_file()) v.push_back(f.path());
  std::sort(v.begin(), v.end(), [](const fs::path& a, const fs::path& b) {
    // Numeric names sort by number (1.png, 2.png, 10.png), others by name.
    const std::string sa = a.stem().string(), sb = b.stem().string();
    const bool na = !sa.empty() && std::all_of(sa.begin(), sa.end(), ::isdigit);
    const bool nb = !sb.empty() && std::all_of(sb.begin(), sb.end(), ::isdigit);
    if (na && nb && sa.size() != sb.size()) return sa.size() < sb.size();
    return sa < sb;
  });
  return v;
}

class DirectorySource : public FrameSource {
 public:
  DirectorySource(const fs::path& dir, const DirectorySourceOptions& o) : dir_(dir), options_(o) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) throw InputError(dir.string(), "frame directory not found");
    fs::path index;
    if (fs::exists(dir / "rgb.txt", ec) || fs::exists(dir / "associations.txt", ec)) {
      layout_ = "TUM RGB-D";
      index = fs::exists(dir / "associations.txt", ec) ? dir / "associations.txt" : dir / "depth.txt";
      entries_ = LoadTum(dir);
      depth_scale_ = 1000.0 / 5000.0;
      intrinsics_ = PrimeSenseDefault();
    } else if (fs::is_directory(dir / "color", ec) && fs::is_directory(dir / "depth", ec)) {
      const auto colors = SortedFiles(dir / "color"), depths = SortedFiles(dir / "depth");
      if (colors.size() != depths.size())
        throw InputError(dir.string(), std::to_string(colors.size()) + " colour but " + std::to_string(depths.size()) +
                                           " depth images");
      for (std::size_t i = 0; i < colors.size(); ++i) entries_.push_back({colors[i], depths[i], i / 30.0, i / 30.0, {}});
      intrinsics_ = PrimeSenseDefault();
      std::vector<Eigen::Matrix4d> poses;
      if (fs::exists(dir / "pose.txt", ec)) {
        layout_ = "joinMap";
        index = dir / "pose.txt";
        poses = ReadPoseTxt(index);
        // slambook's joinMap camera (its joinMap.cpp): fx 518, fy 519, cx 325.5, cy 253.5.
        intrinsics_ = {640, 480, 518.0, 519.0, 325.5, 253.5};
      } else {
        layout_ = "Redwood";
        index = dir / "color";
        if (fs::exists(dir / "trajectory.log", ec)) poses = ReadTrajectoryLog(dir / "trajectory.log");
        for (const fs::path& cam : {dir / "camera_primesense.json", dir.parent_path() / "camera_primesense.json",
                                    dir / "camera.json", dir.parent_path() / "camera.json"})
          if (auto k = IntrinsicsJson(cam)) {
            intrinsics_ = *k;
            break;
          }
      }
      if (!poses.empty()) {
        if (poses.size() != entries_.size())
          throw InputError(index.string(), std::to_string(poses.size()) + " poses for " +
                                               std::to_string(entries_.size()) + " frames");
        for (std::size_t i = 0; i < poses.size(); ++i) entries_[i].pose = poses[i];
      }
    } else {
      throw InputError(dir.string(),
                       "unknown frame directory layout (expected TUM rgb.txt/depth.txt, or color/ and depth/)");
    }
    if (auto k = IntrinsicsJson(dir / "intrinsics.json")) intrinsics_ = *k;
    if (entries_.empty()) throw InputError(dir.string(), "no frames");
    for (const Entry& e : entries_) {
      RequireFile(e.color, index);
      RequireFile(e.depth, index);
    }
  }

  std::string Describe() const override {
    return layout_ + " directory " + dir_.string() + ", " + std::to_string(entries_.size()) + " frames";
  }
  std::optional<std::int64_t> FrameCount() const override { return static_cast<std::int64_t>(entries_.size()); }

  SourceStatus Next(RgbdFrame* frame, double) override {
    if (next_ >= entries_.size()) {
      if (!options_.loop) return SourceStatus::kEnd;
      next_ = 0;
    }
    const Entry& e = entries_[next_];
    RgbdFrame f;
    f.index = produced_++;
    f.color = ReadRgb8(e.color);
    f.depth = ReadDepth16(e.depth, depth_scale_);
    if (f.color.width != f.depth.width || f.color.height != f.depth.height)
      throw InputError(e.depth.string(), "depth is " + std::to_string(f.depth.width) + "x" +
                                             std::to_string(f.depth.height) + " but colour is " +
                                             std::to_string(f.color.width) + "x" + std::to_string(f.color.height));
    Camera k = intrinsics_;
    if (k.width == 0 || k.width != f.color.width) {  // scale the default to the image size
      const double s = k.width > 0 ? static_cast<double>(f.color.width) / k.width : 1.0;
      k = {f.color.width, f.color.height, k.fx * s, k.fy * s, (k.cx + 0.5) * s - 0.5, (k.cy + 0.5) * s - 0.5};
    }
    f.depth_intrinsics = f.color_intrinsics = k;
    f.registered = true;  // these datasets store depth registered to colour
    f.color_timestamp = e.color_time;
    f.depth_timestamp = e.depth_time;
    f.world_from_camera = e.pose;
    *frame = std::move(f);
    ++next_;
    return SourceStatus::kFrame;
  }

  void Rewind() override { next_ = 0; }

 private:
  fs::path dir_;
  DirectorySourceOptions options_;
  std::string layout_;
  std::vector<Entry> entries_;
  double depth_scale_ = 1.0;  // file units to millimetres
  Camera intrinsics_;
  std::size_t next_ = 0;
  std::int64_t produced_ = 0;
};

}  // namespace

std::vector<Eigen::Matrix4d> ParseTrajectoryLog(const std::string& text, const std::string& name) {
  const auto rows = ParseTable(text);
  std::vector<Eigen::Matrix4d> poses;
  if (rows.size() % 5 != 0) throw InputError(name, "expected a 3-number header and 4 rows of 4 numbers per frame");
  for (std::size_t i = 0; i < rows.size(); i += 5) {
    if (rows[i].size() != 3) throw InputError(name, "expected a 3-number header and 4 rows of 4 numbers per frame");
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r) {
      if (rows[i + 1 + r].size() != 4) throw InputError(name, "a pose row must have 4 numbers");
      for (int c = 0; c < 4; ++c) m(r, c) = ParseNumber(rows[i + 1 + r][c], name, i + 2 + r);
    }
    poses.push_back(m);
  }
  return poses;
}

std::vector<Eigen::Matrix4d> ReadTrajectoryLog(const fs::path& path) {
  return ParseTrajectoryLog(ReadTextFile(path), path.string());
}

std::vector<Eigen::Matrix4d> ParsePoseTxt(const std::string& text, const std::string& name) {
  std::vector<Eigen::Matrix4d> poses;
  std::size_t line = 0;
  for (const auto& r : ParseTable(text)) {
    ++line;
    if (r.size() != 7) throw InputError(name, "line " + std::to_string(line) + ": expected 7 numbers");
    double v[7];
    for (int k = 0; k < 7; ++k) v[k] = ParseNumber(r[k], name, line);
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (!(q.norm() >= 1e-9) || !std::isfinite(q.norm()))
      throw InputError(name, "line " + std::to_string(line) + ": zero or overflowing quaternion");
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.block<3, 3>(0, 0) = q.normalized().toRotationMatrix();
    m.block<3, 1>(0, 3) = Eigen::Vector3d(v[0], v[1], v[2]);
    poses.push_back(m);
  }
  return poses;
}

std::vector<Eigen::Matrix4d> ReadPoseTxt(const fs::path& path) { return ParsePoseTxt(ReadTextFile(path), path.string()); }

std::vector<TumFrame> ParseTumAssociations(const std::string& text, const std::string& name) {
  std::vector<TumFrame> out;
  std::size_t line = 0;
  for (const auto& r : ParseTable(text)) {
    ++line;
    if (r.size() < 4) throw InputError(name, "line " + std::to_string(line) + ": expected 4 columns");
    out.push_back({ParseNumber(r[0], name, line), r[1], ParseNumber(r[2], name, line), r[3]});
  }
  return out;
}

std::vector<TumListEntry> ParseTumList(const std::string& text, const std::string& name) {
  std::vector<TumListEntry> v;
  std::size_t line = 0;
  for (const auto& r : ParseTable(text)) {
    ++line;
    if (r.size() < 2) throw InputError(name, "line " + std::to_string(line) + ": expected 'timestamp path'");
    v.push_back({ParseNumber(r[0], name, line), r[1]});
  }
  return v;
}

std::vector<TumFrame> PairTumLists(const std::vector<TumListEntry>& rgb, const std::vector<TumListEntry>& depth) {
  // The colour frames' distinct times, each with its first-listed frame: a binary search per
  // depth frame (n log n: a long list must not take n^2).
  std::vector<std::size_t> order(rgb.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return rgb[a].time < rgb[b].time; });
  std::vector<double> times;
  std::vector<std::size_t> first;
  for (std::size_t i : order)
    if (times.empty() || rgb[i].time != times.back()) {
      times.push_back(rgb[i].time);
      first.push_back(i);
    }
  std::vector<TumFrame> out;
  for (const TumListEntry& d : depth) {
    const std::size_t hi = std::lower_bound(times.begin(), times.end(), d.time) - times.begin();
    double best = kTumMaxTimeDifference;
    const TumListEntry* match = nullptr;
    for (std::size_t k : {hi - 1, hi}) {  // hi - 1 wraps to SIZE_MAX when hi is 0
      if (k >= times.size()) continue;
      const double diff = std::abs(times[k] - d.time);
      const TumListEntry& c = rgb[first[k]];
      // Nearest in time; on a tie the colour frame listed first.
      if (diff < best || (match && diff == best && first[k] < static_cast<std::size_t>(match - rgb.data()))) {
        best = diff;
        match = &c;
      }
    }
    if (match) out.push_back({match->time, match->path, d.time, d.path});
  }
  return out;
}

double PositionRmse(const std::vector<Eigen::Matrix4d>& estimated, const std::vector<Eigen::Matrix4d>& truth) {
  if (estimated.empty() || estimated.size() != truth.size()) return std::nan("");
  double sum2 = 0;
  for (std::size_t i = 0; i < truth.size(); ++i)
    sum2 += (estimated[i].block<3, 1>(0, 3) - truth[i].block<3, 1>(0, 3)).squaredNorm();
  return std::sqrt(sum2 / truth.size());
}

std::string FormatTrajectoryLog(const std::vector<Eigen::Matrix4d>& poses) {
  std::string out;
  char row[160];
  for (std::size_t k = 0; k < poses.size(); ++k) {
    std::snprintf(row, sizeof row, "%zu %zu %zu\n", k, k, k + 1);
    out += row;
    for (int r = 0; r < 4; ++r) {
      const Eigen::Matrix4d& m = poses[k];
      std::snprintf(row, sizeof row, "%.17g %.17g %.17g %.17g\n", m(r, 0), m(r, 1), m(r, 2), m(r, 3));
      out += row;
    }
  }
  return out;
}

std::vector<Eigen::Matrix4d> ReadTrajectory(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path.string(), "trajectory file not found");
  if (path.extension() == ".log") return ReadTrajectoryLog(path);
  if (path.extension() == ".txt") return ReadPoseTxt(path);
  throw InputError(path.string(), "unknown trajectory format (expected trajectory.log or pose.txt)");
}

std::unique_ptr<FrameSource> OpenDirectorySource(const std::string& dir, const DirectorySourceOptions& options) {
  return std::make_unique<DirectorySource>(dir, options);
}

void WriteFrameDirectory(const std::string& dir_name, const std::vector<RgbdFrame>& frames) {
  const fs::path dir(dir_name);
  if (frames.empty()) throw InputError(dir_name, "no frames to write");
  const fs::path parent = dir.parent_path().empty() ? fs::path(".") : dir.parent_path();
  const fs::path tmp = parent / ("." + dir.filename().string() + ".partial");
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp / "color", ec);
  fs::create_directories(tmp / "depth", ec);
  if (ec) throw InputError(dir_name, "cannot create: " + ec.message());
  bool poses = true;
  std::vector<Eigen::Matrix4d> trajectory;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const RgbdFrame& f = frames[k];
    if (f.color.width != frames[0].color.width || f.depth.width != f.color.width || f.depth.height != f.color.height)
      throw InputError(dir_name, "frames must be registered and of one size");
    char file[32];
    std::snprintf(file, sizeof file, "%05zu.png", k);
    WriteRgb8Png(tmp / "color" / file, f.color);
    WriteDepth16Png(tmp / "depth" / file, f.depth);
    poses = poses && f.world_from_camera.has_value();
    if (poses) trajectory.push_back(*f.world_from_camera);
  }
  if (poses) WriteTextAtomically(tmp / "trajectory.log", FormatTrajectoryLog(trajectory));
  const Camera& k0 = frames[0].color_intrinsics;
  nlohmann::json j = {{"fx", k0.fx}, {"fy", k0.fy}, {"cx", k0.cx}, {"cy", k0.cy}, {"width", k0.width}, {"height", k0.height}};
  WriteTextAtomically(tmp / "intrinsics.json", j.dump(2) + "\n");
  fs::remove_all(dir, ec);
  fs::rename(tmp, dir, ec);
  if (ec) throw InputError(dir_name, "cannot move the frames into place: " + ec.message());
}

}  // namespace lp
