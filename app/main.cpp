// lightprobe: an RGB-D camera as a light meter. Entry point: subcommands and the
// one place where errors become one clear line and an exit code.
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "app/commands.h"
#include "common/error.h"

/// The estimator builds and drops matrices of tens of MB several times a round (each solve's
/// problem with the lamps' columns); glibc hands blocks over 128 kB back to the kernel and
/// maps them again, and the page faults took ~10 % of an estimate (synth near-light: 5.89 ->
/// 5.41 s, the fastest of four, the same estimate to the last digit). Keep freed memory for reuse.
static void KeepFreedMemory() {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  mallopt(M_TOP_PAD, 64 << 20);
}

/// The estimator's working set is hundreds of MB, touched afresh each round; this kernel
/// (transparent huge pages on madvise only) faults it in 4 kB pages, about 175,000 faults
/// of ~12 us each on the demo's estimate (2.4 s of system time). glibc's malloc asks for huge
/// pages with the tunable glibc.malloc.hugetlb=1, read once when the process starts: so the
/// process starts itself again once with it set (the same arguments; 5,700 faults, the same
/// estimate to the last digit; docs/benchmarks.md, session 59). A GLIBC_TUNABLES that names
/// the tunable already (glibc.malloc.hugetlb=0 turns it off) is left as it is.
static void UseHugePages(char** argv) {
#if defined(__linux__) && defined(__GLIBC__)
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (tunables && std::strstr(tunables, "glibc.malloc.hugetlb")) return;
  const std::string value =
      tunables && *tunables ? std::string(tunables) + ":glibc.malloc.hugetlb=1" : "glibc.malloc.hugetlb=1";
  if (setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);  // (returns only where it failed: go on as we are)
#else
  (void)argv;
#endif
}

int main(int argc, char** argv) {
  UseHugePages(argv);
  KeepFreedMemory();
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (!args.empty() && args[0] == "--headless") {
    try {
      return lp::app::RunHeadless(args);
    } catch (const lp::InputError& e) {
      std::fprintf(stderr, "lightprobe: error: %s\n", e.what());
      return 2;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "lightprobe: internal error: %s\n", e.what());
      return 4;
    }
  }
  CLI::App app{"lightprobe: estimate a scene's illumination from RGB-D captures"};
  app.name("lightprobe");
  app.require_subcommand(1);
  app.set_version_flag("--version", "lightprobe 0.1.0");
  std::map<std::string, lp::app::Run> runs;
  for (auto add : {&lp::app::AddEstimate, &lp::app::AddRender, &lp::app::AddSynth, &lp::app::AddBench,
                   &lp::app::AddBenchReport, &lp::app::AddDevices,
                   &lp::app::AddRecord, &lp::app::AddReplay, &lp::app::AddReconstruct, &lp::app::AddCalibrate,
                   &lp::app::AddView, &lp::app::AddExport, &lp::app::AddEvaluate}) {
    const std::size_t before = app.get_subcommands([](CLI::App*) { return true; }).size();
    lp::app::Run r = add(app);
    const auto subs = app.get_subcommands([](CLI::App*) { return true; });
    if (subs.size() == before + 1) runs[subs.back()->get_name()] = r;
  }
  try {
    // No arguments: the window (an attached camera, else the bundled demo recording).
    std::vector<std::string> reversed = args.empty() ? std::vector<std::string>{"view"} : args;
    std::reverse(reversed.begin(), reversed.end());  // CLI11 takes them reversed
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    // Bad usage is bad input: one line and exit 2, like every other.
    std::fprintf(stderr, "lightprobe: error: %s (see --help)\n", e.what());
    return 2;
  } catch (const lp::InputError& e) {  // an option's value refused as it is read (estimate_options.h)
    std::fprintf(stderr, "lightprobe: error: %s\n", e.what());
    return 2;
  }
  try {
    for (CLI::App* sub : app.get_subcommands()) runs.at(sub->get_name())();
  } catch (const lp::InputError& e) {
    std::fprintf(stderr, "lightprobe: error: %s\n", e.what());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "lightprobe: error: out of memory (try fewer --rings, --spp or a smaller image)\n");
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lightprobe: internal error: %s\n", e.what());
    return 4;
  }
  return 0;
}
