#pragma once
/// Atomic output: results are written to a temporary sibling and renamed into
/// place, so a crash never leaves a half-written file that looks complete.
#include <filesystem>
#include <functional>
#include <string>

namespace lp {

/// Calls `write(tmp_path)` to produce the file, then renames tmp_path to `path`.
/// The temporary keeps the extension of `path` (writers that pick a format by
/// extension still work). Throws InputError if writing or renaming fails; the
/// old `path`, if any, is untouched in that case.
void WriteAtomically(const std::filesystem::path& path,
                     const std::function<void(const std::filesystem::path& tmp)>& write);

/// Puts the complete directory `complete` in place of `dir` (created or replaced) in one
/// step: where `dir` exists the two are exchanged atomically (Linux renameat2
/// RENAME_EXCHANGE: a reader sees the old directory or the new one, never neither nor a
/// mix) and the old one is removed. Both must be on one file system. Throws InputError
/// when it cannot; `dir` is then as it was.
void ReplaceDirectory(const std::filesystem::path& dir, const std::filesystem::path& complete);

/// Why a write into `dir` failed, from the OS: "no space left on device" when `saved_errno`
/// is ENOSPC or the file system has no space left, else the errno's message (lower case);
/// empty when the OS said nothing. Save errno right after the failing write.
std::string WriteFailure(const std::filesystem::path& dir, int saved_errno);

/// Writes `text` to `path` atomically.
void WriteTextAtomically(const std::filesystem::path& path, const std::string& text);

/// Reads a whole file; throws InputError naming the file if it cannot be read.
std::string ReadTextFile(const std::filesystem::path& path);

}  // namespace lp
