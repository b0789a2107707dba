// `lightprobe bench`: placeholder replaced below.
#include "app/commands.h"

namespace lp::app {
Run AddBench(CLI::App& app) {
  app.add_subcommand("bench", "benchmark the solvers");
  return [] {};
}
}  // namespace lp::app
