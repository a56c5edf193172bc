// terravt: command-line front end. Every subcommand is in its own cmd_*.cpp.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#include "streaming/file_io.h"
#include "terravt/version.h"
#include "tools/commands.h"

namespace tvt::cli {
std::vector<CommandInfo>& command_registry() {
  static std::vector<CommandInfo> registry;
  return registry;
}
}  // namespace tvt::cli

int main(int argc, char** argv) {
  // Tests make the executable meet a full disk at a chosen byte (the library reads no
  // environment variable; the CLI turns this one into fileio::inject_write_failure()).
  if (const char* text = std::getenv("TERRAVT_FAULT_WRITE_AFTER"); text && *text) {
    char* end = nullptr;
    const unsigned long long after = std::strtoull(text, &end, 10);
    if (end && *end == '\0') tvt::fileio::inject_write_failure(after, ENOSPC);
  }
  CLI::App root{"terravt: virtual-texture terrain texturing (compose, bake, stream, compare)"};
  root.require_subcommand(1);
  root.set_version_flag("--version", std::string("terravt ") + terravt::version_string());
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
  for (const auto& [app, run] : commands) {
    if (!app->parsed()) continue;
    // Running out of memory where terravt cannot size the request up front (a scene's images,
    // zstd's contexts) is an error with the command's name and a non-zero exit, never an abort.
    try {
      return run();
    } catch (const std::bad_alloc&) {
      std::fprintf(stderr, "terravt %s: out of memory\n", app->get_name().c_str());
      return 1;
    }
  }
  return 2;
}
