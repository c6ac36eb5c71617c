#include "gateway/app/cli.h"

int main(int argc, char** argv) {
  return fleetgw::app::run_cli(argc, argv);
}
