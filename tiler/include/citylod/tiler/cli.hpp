// citylod's command-line interface: parses argv, dispatches to a subcommand,
// converts every exception into a one-line message on stderr and an exit code
// (0 ok, 1 runtime failure, 2 usage error).
#pragma once

namespace citylod::tiler {

int run_cli(int argc, char** argv);

}  // namespace citylod::tiler
