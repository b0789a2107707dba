#pragma once
/// Camera trajectories as the RGB-D datasets store them (world_from_camera per frame).

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace lp {

/// Open3D / Redwood `trajectory.log`: per frame a line "i j n", then the 4x4
/// world_from_camera in 4 rows. Throws InputError naming the file and line when malformed.
std::vector<Eigen::Matrix4d> ReadTrajectoryLog(const std::filesystem::path& path);
/// The same from the file's text (`name` for errors).
std::vector<Eigen::Matrix4d> ParseTrajectoryLog(const std::string& text, const std::string& name);

/// The text of a `trajectory.log` for `poses` (frame k: "k k k+1", then the 4 rows).
std::string FormatTrajectoryLog(const std::vector<Eigen::Matrix4d>& poses);

/// A trajectory file by its name: `*.log` as trajectory.log, `*.txt` as pose.txt.
std::vector<Eigen::Matrix4d> ReadTrajectory(const std::filesystem::path& path);

/// RMS distance between the camera positions of two trajectories of equal length (the
/// absolute trajectory error when both are in one world frame), metres.
double PositionRmse(const std::vector<Eigen::Matrix4d>& estimated, const std::vector<Eigen::Matrix4d>& truth);

/// slambook's `pose.txt`: "tx ty tz qx qy qz qw" per line (world_from_camera).
std::vector<Eigen::Matrix4d> ReadPoseTxt(const std::filesystem::path& path);
/// The same from the file's text (`name` for errors).
std::vector<Eigen::Matrix4d> ParsePoseTxt(const std::string& text, const std::string& name);

}  // namespace lp
