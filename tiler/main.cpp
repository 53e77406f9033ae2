// citylod executable: a thin shell over citylod::tiler's CLI dispatcher.
#include "citylod/tiler/cli.hpp"

int main(int argc, char** argv) { return citylod::tiler::run_cli(argc, argv); }
