// terravt: command-line front end. Every subcommand is in its own cmd_*.cpp.
#include <algorithm>
#include <cstdio>
#include <vector>

#include "tools/commands.h"

namespace tvt::cli {
std::vector<CommandInfo>& command_registry() {
  static std::vector<CommandInfo> registry;
  return registry;
}
}  // namespace tvt::cli

int main(int argc, char** argv) {
  CLI::App root{"terravt: virtual-texture terrain texturing (compose, bake, stream, compare)"};
  root.require_subcommand(1);
  root.set_version_flag("--version", "terravt 0.1.0");
  auto registry = tvt::cli::command_registry();
  std::sort(registry.begin(), registry.end(), [](const auto& a, const auto& b) { return a.order < b.order; });
  std::vector<std::pair<CLI::App*, tvt::cli::RunFn>> commands;
  for (const auto& info : registry) {
    CLI::App* sub = root.add_subcommand(info.name, info.description);
    commands.emplace_back(sub, info.setup(*sub));
  }
  try {
    root.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = root.exit(e);
    return code == 0 ? 0 : 2;
  }
  for (const auto& [app, run] : commands)
    if (app->parsed()) return run();
  return 2;
}
