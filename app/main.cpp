// citylod executable: the command line over citylod::tiler (app/cli.cpp).
#include "cli.hpp"

int main(int argc, char** argv) {
  return citylod::app::run_cli(argc, argv);
}
