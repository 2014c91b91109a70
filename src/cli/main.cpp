// subslip command line: placeholder until the scene runner lands.
#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
  CLI::App app{"subslip: subloading-overstress friction on contacts and crystal slip systems"};
  app.require_subcommand(1);
  CLI11_PARSE(app, argc, argv);
  return 0;
}
