#include "common/atomic_file.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include <fcntl.h>
#include <stdio.h>
#include <unistd.h>

#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;

void WriteAtomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& write) {
  static std::atomic<int> counter{0};
  fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path tmp = dir / (".tmp." + std::to_string(::getpid()) + "." +
                              std::to_string(counter++) + "." + path.filename().string());
  try {
    write(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  if (!fs::exists(tmp)) throw InputError(path.string(), "writer produced no file");
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(path.string(), "cannot rename into place: " + ec.message());
  }
}

void ReplaceDirectory(const fs::path& dir, const fs::path& complete) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) {
    fs::rename(complete, dir, ec);
    if (ec) throw InputError(dir.string(), "cannot move into place: " + ec.message());
    return;
  }
  if (::renameat2(AT_FDCWD, complete.c_str(), AT_FDCWD, dir.c_str(), RENAME_EXCHANGE) != 0) {
    const int saved = errno;
    throw InputError(dir.string(), std::string("cannot replace: ") + std::strerror(saved));
  }
  fs::remove_all(complete, ec);  // now the old one
}

std::string WriteFailure(const fs::path& dir, int saved_errno) {
  std::error_code ec;
  const fs::space_info space = fs::space(dir.empty() ? fs::path(".") : dir, ec);
  if (saved_errno == ENOSPC || (!ec && space.available == 0)) return "no space left on device";
  if (saved_errno == 0) return "";
  std::string m = std::strerror(saved_errno);
  std::transform(m.begin(), m.end(), m.begin(), [](unsigned char c) { return std::tolower(c); });
  return m;
}

void WriteTextAtomically(const fs::path& path, const std::string& text) {
  WriteAtomically(path, [&](const fs::path& tmp) {
    errno = 0;
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    out.flush();
    if (!out) {
      const std::string why = WriteFailure(tmp.parent_path(), errno);
      throw InputError(path.string(), why.empty() ? "cannot write" : "cannot write: " + why);
    }
  });
}

std::string ReadTextFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path.string(), "file not found");
  if (fs::is_directory(path, ec)) throw InputError(path.string(), "is a directory, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), "cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace lp
