// Each terravt subcommand lives in its own cmd_*.cpp and registers itself with a static
// CommandRegistrar (tools/ is one executable, so every registrar runs before main).
#pragma once
#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace tvt::cli {

// Exit codes: 0 ok, 1 runtime failure (message on stderr), 2 bad usage or bad input.
using RunFn = std::function<int()>;
// Adds the subcommand's options to `app` and returns what runs when it was chosen.
using SetupFn = std::function<RunFn(CLI::App& app)>;

struct CommandInfo {
  std::string name;
  std::string description;
  SetupFn setup;
  int order;  // position in --help
};

std::vector<CommandInfo>& command_registry();

struct CommandRegistrar {
  CommandRegistrar(std::string name, std::string description, int order, SetupFn setup) {
    command_registry().push_back({std::move(name), std::move(description), std::move(setup), order});
  }
};

}  // namespace tvt::cli
