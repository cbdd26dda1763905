// rilo: the tool for people (simulate, replay, evaluate, listen, probe).
// Subcommands arrive with their issues: demo, listen, ...
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>

#include "accuracy_command.h"
#include "demo.h"
#include "rilo_version.h"
#include "eval_command.h"
#include "import_command.h"
#include "listen.h"
#include "probe_command.h"
#include "range_errors_command.h"
#include "record_command.h"
#include "replay_command.h"
#include "report_command.h"
#include "sim_command.h"
#include "tool_log.h"
#include "unsigned_option.h"
#include "view_command.h"

int main(int argc, char** argv) {
  CLI::App app{"rilo: Ranging-Inertial LOcalization tools"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "rilo " RILO_VERSION_TEXT);

  rilo::tool::DemoOptions demo;
  CLI::App* demo_cmd = app.add_subcommand("demo", "Simulate an office walk and solve it in batch with each range noise model");
  demo_cmd->add_option("--seed", demo.seed, "Simulation seed")->capture_default_str()->check(rilo::cli::notNegative());
  demo_cmd->add_option("--seconds", demo.seconds, "Duration of the walk (s)")->capture_default_str()->check(CLI::Range(2.0, 3600.0));
  demo_cmd->add_option("--range-hz", demo.range_hz, "Total ranging rate (Hz)")->capture_default_str()->check(CLI::Range(0.5, 200.0));
  demo_cmd->add_option("--nlos", demo.nlos_fraction, "Fraction of time an anchor is NLOS")->capture_default_str()->check(CLI::Range(0.0, 0.9));
  demo_cmd->add_option("--noise", demo.noise_models, "Range noise models to compare")->capture_default_str();

  rilo::tool::addSimCommand(app);
  rilo::tool::addReplayCommand(app);
  rilo::tool::addReportCommand(app);
  rilo::tool::addAccuracyCommand(app);
  rilo::tool::addEvalCommand(app);
  rilo::tool::addRangeErrorsCommand(app);
  rilo::tool::addImportUtilCommand(app);
  rilo::tool::addListenCommand(app);
  rilo::tool::addProbeCommand(app);
  rilo::tool::addRecordCommand(app);
  rilo::tool::addViewCommand(app);

  // Messages go through spdlog as rilod's do, named after the subcommand
  // ("rilo replay: warning: ..."), chosen once the command line is parsed and
  // before any subcommand runs.
  rilo::tool::setUpToolLogging("");
  app.parse_complete_callback([&app] {
    for (const CLI::App* sub : app.get_subcommands()) rilo::tool::setUpToolLogging(sub->get_name());
  });
  CLI11_PARSE(app, argc, argv);
  try {
    if (*demo_cmd) return rilo::tool::runDemo(demo);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
