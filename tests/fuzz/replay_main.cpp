// Runs a fuzz target's entry point over files (or every file in directories): the
// seed corpus and the crash inputs kept as regression tests, in the normal build. Prints
// the slowest input and its time (a measurement for scripts/fuzz.sh, not a check).
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  for (int i = 1; i < argc; ++i) {
    const fs::path p(argv[i]);
    if (fs::is_directory(p)) {
      for (const auto& e : fs::recursive_directory_iterator(p))
        if (e.is_regular_file() && e.path().filename() != ".gitkeep") files.push_back(e.path());
    } else if (fs::is_regular_file(p)) {
      files.push_back(p);
    } else {
      std::fprintf(stderr, "replay: %s: not found\n", argv[i]);
      return 2;
    }
  }
  double slowest = -1;
  fs::path slowest_file;
  std::size_t slowest_size = 0;
  for (const fs::path& f : files) {
    std::ifstream in(f, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto start = std::chrono::steady_clock::now();
    LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (s > slowest) {
      slowest = s;
      slowest_file = f;
      slowest_size = bytes.size();
    }
  }
  if (slowest >= 0)
    std::printf("slowest input: %.6f s, %zu bytes, %s\n", slowest, slowest_size, slowest_file.string().c_str());
  std::printf("%zu passed, 0 failed\n", files.size());
  return 0;
}
